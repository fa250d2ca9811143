"""A passage over a rough sampled rail: curvature jumps as stops, the short step, convergence.

The issue's site (``benchmarks.constraint_bench.site_rail``: a rail sampled every
0.5 mm with 10 µm rms roughness, read from its file by :mod:`tests.stored_rails` so that
it is the same on every CPU) on 0.3 m, the paper's wheel with a 50 mm ideal
flat at 160 km/h whose flat strikes mid-window (loss and return of contact). The
table is C¹ at ~2000 nodes where the exact constraint passes from a rail segment's
offset line to the arc of the wheel pivoting on a vertex (G'' jumps by 1/R = 2.17 /m):
steps in contact stop on them (``integrator.stop_on_jump``), the short pair
(DOPRI5) takes the steps they cut, and the error now follows the tolerance.

Measured values are printed (``pytest -s``); nothing here is timed.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np
import pytest

from sim_core import paper
from sim_core.constraint import tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.integrate.loop import jump_allowance
from sim_core.integrate.types import Params
from sim_core.passage import PassageOutput, PassageSpec, simulate_passage
from sim_core.wheel import WheelOutline
from tests import reference_solver as rs
from tests.stored_rails import site_rail_0p3

LENGTH = 0.3
RADIUS = 0.46
SPEED = 160 / 3.6
FLAT_PHASE = -0.15 / RADIUS  # the flat's centre at x = 0.15 m


def report(record_property: Callable[[str, object], None], name: str, value: object) -> None:
    record_property(name, value)
    print(f"\n[measured] {name} = {value}")


@functools.cache
def rough_table() -> ConstraintTable:
    wheel = WheelOutline.ideal_flat(RADIUS, 0.05)
    return tabulate_constraint(wheel, site_rail_0p3(), 0.0, LENGTH, phase=FLAT_PHASE)


def spec(rtol: float) -> PassageSpec:
    return PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=SPEED,
        duration=LENGTH / SPEED,
        sample_rate=1e5,
        contact=paper.contact_model(ContactLaw.HERTZ),
        rtol=rtol,
    )


@functools.cache
def run(rtol: float) -> PassageOutput:
    return simulate_passage(rough_table(), spec(rtol))


def force_error(out: PassageOutput, ref: PassageOutput) -> float:
    return float(np.max(np.abs(out.force - ref.force))) / paper.LOAD


def transition_error(out: PassageOutput, ref: PassageOutput) -> float:
    assert [t.kind for t in out.transitions] == [t.kind for t in ref.transitions]
    return max(
        (abs(a.t - b.t) for a, b in zip(out.transitions, ref.transitions, strict=True)), default=0.0
    )


def test_the_window_is_the_site_regime() -> None:
    """The flat strikes (contact lost and regained) and the table has both kinds of breakpoint."""
    out = run(1e-9)
    assert [t.kind for t in out.transitions][:2] == ["loss", "contact"]
    assert out.peak_force > 3.0 * paper.LOAD
    table = rough_table()
    jumps, sizes = table.curvature_jumps_between(0.0, LENGTH, 1e-3)
    kinks = table.kinks_between(0.0, LENGTH)
    assert kinks.size > 100 and jumps.size > 1.5 * kinks.size
    assert np.allclose(np.median(sizes), 1.0 / RADIUS, rtol=0.01)


def _jumps_by_differences(table: ConstraintTable) -> tuple[np.ndarray, np.ndarray]:
    """(|ΔG''|, max |G''| of both sides) at every interior node from differences of the
    table's own slope (not its pieces)."""
    x = table.x[1:-1]
    eps = 1e-3 * np.min(np.diff(table.x))
    # G'' is linear on a piece: two one-sided differences of the slope extrapolate it to the node
    right = (
        4.0 * table.slope(x + eps) - table.slope(x + 2 * eps) - 3.0 * table.slope_right[1:-1]
    ) / (2.0 * eps)
    left = (
        3.0 * table.slope_left[1:-1] - 4.0 * table.slope(x - eps) + table.slope(x - 2 * eps)
    ) / (2.0 * eps)
    return np.abs(right - left), np.maximum(np.abs(right), np.abs(left))


def test_stop_list_holds_every_curvature_jump_above_the_threshold() -> None:
    """The passage's stop list: every non-kink node whose G'' jumps by more than the least
    jump a contact step could be hurt by (``jump_allowance``/hmax³) and by more than the
    interpolation's own (``table.JUMP_RELATIVE``), and no other."""
    table = rough_table()
    par_like = Params.build(
        law=0, c=1.0, f_y=0.0, d_y=0.0, theta=0.0, hyst=0.0, mass=paper.MASS, load=paper.LOAD,
        speed=SPEED, compliant=False, f_mass=1.0, f_stiff=0.0, f_damp=0.0, rtol=1e-9,
        atol_y=1e-9 * 5.1e-5, atol_v=1e-9 * 5.1e-5 * 1700.0, hmax_contact=3 * table.resolution / SPEED,
        c2max=3.0, track_dents=False, dent_dx=1e-4,
    )  # fmt: skip
    least = jump_allowance(par_like) / par_like.hmax_contact**3
    assert 1e-6 < least < 1e-3  # far below an arc's 2.17 /m, far above round-off
    listed, sizes = table.curvature_jumps_between(-1e-12, LENGTH, least)
    by_diff, curvature = _jumps_by_differences(table)
    kink = table.slope_left[1:-1] != table.slope_right[1:-1]
    inside = (table.x[1:-1] > -1e-12) & (table.x[1:-1] <= LENGTH)
    real = by_diff > 0.02 * curvature  # the table's JUMP_RELATIVE is 0.01: no node is near it
    sig = by_diff > least
    assert np.all((by_diff <= 1e-3 * curvature) | (by_diff >= 0.9 * curvature) | ~sig | kink)
    chosen = (by_diff > least) & ~kink & inside & real
    assert np.array_equal(listed, table.x[1:-1][chosen])
    assert np.allclose(sizes, by_diff[chosen], rtol=1e-4, atol=1e-6)
    assert np.all(np.isin(table.kinks, listed, invert=True))


@pytest.mark.parametrize("rtol", [1e-8, 1e-10])
def test_force_follows_the_tolerance(
    rtol: float, record_property: Callable[[str, object], None]
) -> None:
    """Against rtol 1e-12 on the same table: max |ΔF|/P within 100·rtol, transitions within
    0.01·rtol s (measured: 21·rtol and 6e-12 s at rtol 1e-8; before the curvature jumps were
    stops, 2.3e-3 and 3.4e-7 s at rtol 1e-8 on the 6 m site)."""
    out, ref = run(rtol), run(1e-12)
    df = force_error(out, ref)
    dt = transition_error(out, ref)
    report(
        record_property,
        f"rough rail rtol {rtol:g}: max|dF|/P / max|dt| (s) / steps / rejected",
        f"{df:.2e} / {dt:.1e} / {out.steps} / {out.rejected_steps}",
    )
    assert df <= 100.0 * rtol
    assert dt <= 0.01 * rtol
    assert abs(out.peak_force / ref.peak_force - 1.0) <= 100.0 * rtol


def test_breakpoints_cost_no_rejections_and_take_the_short_pair() -> None:
    """One step per breakpoint interval, nearly none rejected (those left are at the strike's
    singular steps), most at DOPRI5's 6 evaluations (DOP853: 12)."""
    out = run(1e-9)
    assert out.rejected_steps <= 0.02 * out.steps
    assert out.rhs_evaluations < 8.0 * out.steps


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_agrees_with_scipy_restarted_at_every_breakpoint(
    record_property: Callable[[str, object], None],
) -> None:
    """SciPy's DOP853 at rtol 1e-12, restarted at every kink and every curvature jump of the
    table, with terminal events per mode (``tests.reference_solver``), over 60 mm around the
    flat's strike."""
    table = rough_table()
    t0, t1 = 0.11 / SPEED, 0.17 / SPEED
    ours = simulate_passage(table, dataclasses.replace(spec(1e-10), t0=t0, duration=t1 - t0))
    k = rs.paper_constants()
    prob = rs.Problem(
        rs.table_constraint(table), paper.MASS, paper.LOAD, SPEED, "hertz", k, 0.0, 0.0
    )
    breaks = rs.table_breaks(table, t0, t1, SPEED)
    r = rs.solve(prob, prob.static_state(t0), t0, t1, sample_t=ours.t, breaks=breaks)
    assert [t.kind for t in ours.transitions] == r.kinds and len(r.kinds) >= 2
    dt = float(np.max(np.abs(np.array([t.t for t in ours.transitions]) - r.times())))
    df = float(np.max(np.abs(ours.force - r.force))) / paper.LOAD
    rel = ours.peak_force / r.peak_force - 1.0
    report(
        record_property,
        "rough rail vs SciPy: max|dt| (s) / max|dF|/P / peak rel",
        f"{dt:.1e} / {df:.1e} / {rel:.1e}",
    )
    assert dt <= 1e-9
    assert df <= 1e-5
    assert abs(rel) <= 1e-6
