"""Permanent deformation (MODEL.md §5) and the paper's Fig. 8, and multi-pass runs.

Fig. 8: Hertzian–perfectly plastic law, even rail, start from static equilibrium
pushed down at 0.3 m/s, V = 100 km/h: an undamped self-sustained oscillation that
presses periodic dents, about 0.41 / 0.17 / 0.07 mm deep for Y = 600 / 700 / 800 MPa.
"""

from __future__ import annotations

import dataclasses
import functools
import itertools
from collections import Counter
from collections.abc import Callable

import numpy as np
import pytest

from sim_core.constraint import flat_constraint
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.dents import dent_profile, dented_rail
from sim_core.multipass import constraint_for, simulate_passes
from sim_core.passage import InitialState, PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from tests import reference_solver as rs

M_WHEEL, LOAD = 400.0, 39240.0
SPEED = 100 / 3.6
ROUND = WheelOutline.round(0.475)
FIG8_DEPTHS_MM = {6e8: 0.41, 7e8: 0.17, 8e8: 0.07}


def report(record_property: Callable[[str, object], None], name: str, value: object) -> None:
    record_property(name, value)
    print(f"\n[measured] {name} = {value}")


def hpp(y: float) -> ContactModel:
    k = rs.paper_constants(yield_stress=y)
    return ContactModel(ContactLaw.HERTZ_PLASTIC, k.c, k.f_y, k.d_y)


def fig8_spec(y: float, duration: float = 0.2, rtol: float = 1e-9) -> PassageSpec:
    return PassageSpec(
        mass=M_WHEEL,
        load=LOAD,
        speed=SPEED,
        duration=duration,
        sample_rate=2e4,
        contact=hpp(y),
        initial=InitialState(v_c=-0.3),
        rtol=rtol,
    )


@functools.cache
def fig8(y: float) -> PassageOutput:
    return simulate_passage(flat_constraint(), fig8_spec(y))


def _dent_peaks(x: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position, depth) of the deepest point of each separate dent."""
    inside = d > 0
    starts = np.flatnonzero(inside & ~np.r_[False, inside[:-1]])
    ends = np.flatnonzero(inside & ~np.r_[inside[1:], False])
    idx = np.array([s + int(np.argmax(d[s : e + 1])) for s, e in zip(starts, ends, strict=True)])
    return x[idx], d[idx]


@pytest.mark.parametrize("y", list(FIG8_DEPTHS_MM))
def test_fig8_dent_depths(y: float, record_property: Callable[[str, object], None]) -> None:
    out = fig8(y)
    x, d = dent_profile(out, hpp(y))
    px, pd = _dent_peaks(x, d)
    report(
        record_property,
        f"Fig. 8 Y = {y / 1e6:.0f} MPa: dent depth (mm) / spacing (m) / dents",
        f"{pd.max() * 1e3:.4f} / {np.mean(np.diff(px)):.4f} / {pd.size}",
    )
    assert pd.max() * 1e3 == pytest.approx(FIG8_DEPTHS_MM[y], rel=0.05)
    # periodic: every dent equally deep, equally spaced
    assert pd.size >= 5
    assert np.allclose(pd, pd[0], rtol=1e-6)
    assert np.allclose(np.diff(px), np.diff(px)[0], rtol=1e-3)
    # the oscillation is periodic too (P < F_Y: self-sustained, no damping)
    loss = np.array([t.t for t in out.transitions if t.kind == "loss"])
    assert np.allclose(np.diff(loss), np.diff(loss)[0], rtol=1e-6)
    assert out.peak_force == pytest.approx(rs.paper_constants(yield_stress=y).f_y, rel=1e-12)


def test_fig8_dents_deeper_for_lower_yield_stress() -> None:
    depth = [dent_profile(fig8(y), hpp(y))[1].max() for y in sorted(FIG8_DEPTHS_MM)]
    assert depth[0] > depth[1] > depth[2] > 0


@pytest.mark.parametrize("y", list(FIG8_DEPTHS_MM))
def test_fig8_energy_conserved(y: float, record_property: Callable[[str, object], None]) -> None:
    """With only the loading branch acting, ∫F dδ is a potential: energy is conserved."""
    out = simulate_passage(flat_constraint(), fig8_spec(y, duration=0.5, rtol=1e-10))
    k = rs.paper_constants(yield_stress=y)
    u = np.array([rs.loading_potential(float(d), "hertz_plastic", k) for d in out.delta])
    e = 0.5 * M_WHEEL * out.v_c**2 + LOAD * out.y_c + u
    drift = float(np.max(np.abs(e - e[0]))) / (0.5 * M_WHEEL * 0.3**2)
    report(
        record_property, f"Fig. 8 Y = {y / 1e6:.0f} MPa: energy drift over 0.5 s", f"{drift:.1e}"
    )
    assert drift <= 1e-6


def test_dent_depth_is_indentation_beyond_recovery() -> None:
    """y_f = y_r - (δ_c - δ_Y): the deepest dent is the peak indentation less δ_Y."""
    y = 6e8
    out = fig8(y)
    _, d = dent_profile(out, hpp(y))
    d_y = rs.paper_constants(yield_stress=y).d_y
    assert d.max() == pytest.approx(out.max_indentation - d_y, rel=1e-6)


def test_elastic_passage_leaves_no_dent() -> None:
    k = rs.paper_constants()
    spec = dataclasses.replace(
        fig8_spec(8e8, duration=0.05), contact=ContactModel(ContactLaw.HERTZ, k.c)
    )
    out = simulate_passage(flat_constraint(), spec)
    x, d = dent_profile(out, spec.contact)
    assert x.size == 0 and d.size == 0


# ------------------------------------------------------------------------------------
# windows that end while a dent is being pressed
# ------------------------------------------------------------------------------------
def test_dent_still_pressed_at_window_end_is_dropped() -> None:
    y = 6e8
    full = fig8(y)
    tr = full.transitions
    yields = [t.t for t in tr if t.kind == "yield"]
    unyields = [t.t for t in tr if t.kind == "unyield"]
    # a window ending inside the second plastic phase keeps only the first dent
    t_end = 0.5 * (yields[1] + unyields[1])
    out = simulate_passage(flat_constraint(), fig8_spec(y, duration=t_end))
    assert [t.kind for t in out.transitions][-1] == "yield"
    x, d = dent_profile(out, hpp(y))
    assert d.max() > 0
    first_x, _ = dent_profile(
        simulate_passage(flat_constraint(), fig8_spec(y, duration=0.5 * (unyields[0] + yields[1]))),
        hpp(y),
    )
    assert x[d > 0].max() <= first_x.max() + 1e-12
    assert x[d > 0].max() < SPEED * yields[1]
    # a window ending inside the very first plastic phase leaves no dent at all
    out0 = simulate_passage(flat_constraint(), fig8_spec(y, duration=0.5 * unyields[0]))
    _, d0 = dent_profile(out0, hpp(y))
    assert not np.any(d0 > 0)


# ------------------------------------------------------------------------------------
# several wheels
# ------------------------------------------------------------------------------------
MULTI_DURATION = 0.02  # two plastic phases of Fig. 8 (Y = 600 MPa)


@functools.cache
def chained_rails() -> tuple[list[RailProfile], list[float]]:
    """The rail after each of 3 single passes, each pass run on the rail the previous left."""
    spec = fig8_spec(6e8, duration=MULTI_DURATION)
    rails = [RailProfile.flat()]
    dents = []
    for _ in range(3):
        one = simulate_passes(ROUND, rails[-1], spec, passes=1)
        assert one.rail_after is not None
        rails.append(one.rail_after)
        dents.append(one.summaries[0].max_dent)
    return rails, dents


def test_multipass_runs_and_chains_the_rail(record_property: Callable[[str, object], None]) -> None:
    spec = fig8_spec(6e8, duration=MULTI_DURATION)
    seen: list[int] = []
    multi = simulate_passes(
        ROUND, RailProfile.flat(), spec, passes=3, progress=lambda i, n, s: seen.append(i)
    )
    assert seen == [1, 2, 3]
    assert len(multi.summaries) == 3
    rails, dents = chained_rails()
    report(
        record_property,
        "multi-pass (Y = 600 MPa, 20 ms): deepest dent per pass (mm)",
        [round(d * 1e3, 4) for d in dents],
    )
    # the same three passes one at a time, each on the rail the last one left
    assert [s.max_dent for s in multi.summaries] == pytest.approx(dents, rel=1e-9, abs=1e-15)
    assert multi.rail_after is not None
    after, chained = multi.rail_after, rails[-1]
    assert after.kind == chained.kind == "sampled"
    np.testing.assert_allclose(after.x, chained.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(after.y, chained.y, rtol=0, atol=1e-15)
    # each rail is the one before with that pass's dents pressed in (only ever deeper)
    for before, nxt in itertools.pairwise(rails[1:]):
        xs = nxt.x
        assert np.all(nxt.height(xs) <= before.height(xs) + 1e-15)
    assert dents[0] == pytest.approx(FIG8_DEPTHS_MM[6e8] * 1e-3, rel=0.05)


def test_second_wheel_meets_the_first_wheels_dents() -> None:
    """The second wheel's table is built on the dented rail: it dips where the first pressed."""
    rails, _ = chained_rails()
    spec = fig8_spec(6e8, duration=MULTI_DURATION)
    first = simulate_passage(flat_constraint(), spec)
    dx, depth = dent_profile(first, spec.contact)
    rebuilt = dented_rail(RailProfile.flat(), dx, depth, -0.1, SPEED * MULTI_DURATION + 0.1)
    xs = np.linspace(0.0, SPEED * MULTI_DURATION, 2001)
    np.testing.assert_allclose(rebuilt.height(xs), rails[1].height(xs), atol=1e-15)
    table = constraint_for(ROUND, rails[1], 0.0, SPEED * MULTI_DURATION)
    assert table.evaluate(xs).min() < -0.9 * depth.max()


def test_no_chattering_on_a_dented_rail(record_property: Callable[[str, object], None]) -> None:
    """On rails dented by earlier wheels the next wheel rides near δ = δ_Y: it may cross
    δ_Y many times (each vertex of the dented profile), but the count is the same at
    every tolerance and every crossing makes progress."""
    rails, _ = chained_rails()
    spec = fig8_spec(6e8, duration=MULTI_DURATION)
    table = constraint_for(ROUND, rails[2], 0.0, SPEED * MULTI_DURATION)
    runs = [simulate_passage(table, dataclasses.replace(spec, rtol=r)) for r in (1e-9, 1e-11)]
    counts = [Counter(t.kind for t in o.transitions) for o in runs]
    report(record_property, "third wheel on the dented rail: transitions", dict(counts[0]))
    assert counts[0] == counts[1]
    assert [t.kind for t in runs[0].transitions] == [t.kind for t in runs[1].transitions]
    t = np.array([tr.t for tr in runs[0].transitions])
    assert t.size < 1000 and np.all(np.diff(t) > 1e-10)
