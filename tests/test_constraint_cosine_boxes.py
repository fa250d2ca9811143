"""Rounded flats on cosines without the ψ-search (sim_core.constraint.cosine_boxes): the hollow's
uncertified cells cut into boxes of wheel angle and rail phase, each with a certified shape of G.

Cases: the 80 mm, l²/16R-deep flat on the paper's cosine (a = 0.1 mm, λ = 5 cm) and on a steep
one with a < 0 (0.2 mm, 8 cm). Checked: the boxes tile the uncertified cells over a whole rail
period; on each box G'' changes sign at most as often as its shape allows (analytic G'' on a
dense ψ grid); the boxes' maximum equals a dense brute force over ψ (never below it); the table
near its kinks (where two local maxima of the hollow's rims tie), with the rail perturbed in its
last bits and the flat's end over a crest, against brute force and the ψ-search's table; and a
passage over the flat's impact against the same passage on the ψ-search's table.
(The hybrid's own tests, test_constraint_cosine_hybrid.py, run through the boxes too.)
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_core.constraint import tabulate_constraint
from sim_core.constraint.cosine_boxes import CAP, CUP, box_cover, box_max
from sim_core.constraint.cosine_cells import (
    CONCAVE,
    CONVEX,
    FALLING,
    RISING,
    UNCERTIFIED,
    uncertified_spans,
)
from sim_core.constraint.cosine_hybrid import contact_windows, tabulate_cosine_hybrid
from sim_core.constraint.nodes import HERMITE_TOL, resolution
from sim_core.constraint.wheel_pieces import cosine_cover
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.materials import Material, derive
from sim_core.passage import PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

R = 0.46
WHEEL = WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R))
PAPER = RailProfile.cosine(1e-4, 0.05)
STEEP = RailProfile.cosine(-2e-4, 0.08)
RAILS = {"paper": PAPER, "steep": STEEP}
ALLOWED = {CONCAVE: 0, CONVEX: 0, RISING: 1, FALLING: 1, CAP: 2, CUP: 2}


def _g(
    rail: RailProfile, x: float, phi: float, psi: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(G + R, G'' (analytic), p) of the haversine at wheel position x, wheel angle φ (|φ| small)."""
    hd, w = 0.5 * WHEEL.flat_depth, TWO_PI * R / WHEEL.flat_length
    t = w * (psi + phi)
    rho = R - hd * (1.0 + np.cos(t))
    r1, r2 = hd * w * np.sin(t), hd * w * w * np.cos(t)
    s, c = np.sin(psi), np.cos(psi)
    p = x + rho * s
    a, k = rail.amplitude, TWO_PI / rail.wavelength
    A = r1 * s + rho * c
    A1 = r2 * s + 2.0 * r1 * c - rho * s
    g = a * np.cos(k * p) + rho * c
    g2 = (
        -a * k * k * np.cos(k * p) * A * A
        - a * k * np.sin(k * p) * A1
        + (r2 - rho) * c
        - 2 * r1 * s
    )
    return g, g2, p


def _boxes(rail: RailProfile) -> tuple[NDArray[np.float64], float, float, float]:
    cells, psi_max = cosine_cover(WHEEL, rail)
    boxes = box_cover(WHEEL, rail, cells)
    assert boxes is not None
    ((u0, u1),) = uncertified_spans(cells)
    return boxes, psi_max, float(u0), float(u1)


@pytest.mark.parametrize("name", list(RAILS))
def test_boxes_tile_the_uncertified_cells(name: str) -> None:
    rail = RAILS[name]
    cells, _ = cosine_cover(WHEEL, rail)
    boxes, _, u0, u1 = _boxes(rail)
    assert np.any(cells[:, 6] == UNCERTIFIED)
    assert set(boxes[:, 4].astype(int).tolist()) <= set(ALLOWED)
    area = np.sum((boxes[:, 1] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 2]))
    assert abs(area - (u1 - u0) * TWO_PI) < 1e-12
    assert boxes[:, 0].min() == u0 and boxes[:, 1].max() == u1
    assert boxes[:, 2].min() == 0.0 and abs(boxes[:, 3].max() - TWO_PI) < 1e-15


@pytest.mark.parametrize("name", list(RAILS))
def test_each_box_has_its_shape(name: str) -> None:
    """Analytic G'' on a dense ψ grid inside each box (wheel angle and rail phase): its sign
    changes at most as often as the box's shape allows, at random wheel positions."""
    rail = RAILS[name]
    boxes, psi_max, _, _ = _boxes(rail)
    k = TWO_PI / rail.wavelength
    rng = np.random.default_rng(11)
    seen = 0
    for u0, u1, q0, q1, shape in boxes[:, :5]:
        for _ in range(40):
            phi = rng.uniform(u0 - psi_max, u1 + psi_max)
            x = rng.uniform(-1.0, 1.0)
            psi = np.linspace(max(u0 - phi, -psi_max), min(u1 - phi, psi_max), 4001)
            if psi[-1] <= psi[0]:
                continue
            _, g2, p = _g(rail, x, phi, psi)
            q = np.mod(k * p, TWO_PI)
            inside = (q >= q0) & (q <= q1)
            # one run of ψ per rail period: split where the phase wraps
            runs = np.split(
                np.flatnonzero(inside), np.flatnonzero(np.diff(np.flatnonzero(inside)) > 1) + 1
            )
            for run in runs:
                sig = np.sign(g2[run])
                sig = sig[np.abs(g2[run]) > 1e-9]
                assert np.count_nonzero(np.diff(sig)) <= ALLOWED[int(shape)]
                seen += 1
    assert seen > 100


def _brute_span(rail: RailProfile, x: float, phi: float, lo: float, hi: float) -> float:
    """max of G over ψ in [lo, hi]: a dense grid, then golden section around its best (a lower
    bound of the true maximum, within ~1e-16 m of it)."""
    psi = np.linspace(lo, hi, 200001)
    g = _g(rail, x, phi, psi)[0]
    i = int(np.argmax(g))
    a, b = psi[max(i - 1, 0)], psi[min(i + 1, psi.size - 1)]
    best = float(g[i])
    for _ in range(80):
        m1, m2 = a + 0.381966 * (b - a), a + 0.618034 * (b - a)
        v1, v2 = (float(v) for v in _g(rail, x, phi, np.array([m1, m2]))[0])
        best = max(best, v1, v2)
        if v1 < v2:
            a = m1
        else:
            b = m2
    return best - R


@pytest.mark.parametrize("name", list(RAILS))
def test_box_max_is_the_brute_force_max(name: str) -> None:
    rail = RAILS[name]
    boxes, psi_max, u0, u1 = _boxes(rail)
    rng = np.random.default_rng(4)
    worst, n = 0.0, 0
    for phi in rng.uniform(u0 - psi_max, u1 + psi_max, 120):
        x = R * phi + rng.uniform(0.0, rail.wavelength)
        lo, hi = max(u0 - phi, -psi_max), min(u1 - phi, psi_max)
        if lo >= hi:
            continue
        # any turn: φ + 2π is the same wheel angle
        v, xd = box_max(boxes, R, rail.amplitude, rail.wavelength, psi_max, x, phi + TWO_PI)
        ref = _brute_span(rail, x, phi, lo, hi)
        assert v >= ref - 1e-16, "never below the true maximum"
        assert abs(v - ref) < 1e-14 and math.isfinite(xd)
        worst, n = max(worst, abs(v - ref)), n + 1
    assert n > 80


def _brute_table(rail: RailProfile, x: NDArray[np.float64], phase: float) -> NDArray[np.float64]:
    """y_C^k by a dense ψ grid over ±0.12 rad (the whole wheel within reach): within ~1e-13 m."""
    psi = np.linspace(-0.12, 0.12, 480001)
    out = np.empty(x.size)
    for i, xc in enumerate(x):
        phi = phase + xc / R
        rho = WHEEL.radius_at(psi + phi)
        out[i] = np.max(rail.height(xc + rho * np.sin(psi)) + rho * np.cos(psi)) - R
    return out


@pytest.mark.parametrize("bits", [0, 1, 2, 3])
@pytest.mark.parametrize("name", list(RAILS))
def test_near_ties_with_the_rail_perturbed_in_its_last_bits(name: str, bits: int) -> None:
    """Around the kinks (the hollow's rims tie over the crests) and with the flat's end over a
    crest: the table (boxes in the window) against brute force and the ψ-search's table, the
    rail's amplitude and wavelength moved by a few units in their last place."""
    base = RAILS[name]
    eps = bits * 2.0**-52
    rail = RailProfile.cosine(base.amplitude * (1.0 + eps), base.wavelength * (1.0 - eps))
    crest = 0.0 if rail.amplitude > 0 else 0.5 * rail.wavelength
    # the flat's trailing end (wheel angle l/2R) over a crest when its middle is at the bottom
    phase = -(crest + 0.5 * WHEEL.flat_length) / R
    lo, hi = -0.5 * WHEEL.flat_length + crest - 0.03, crest + 0.5 * WHEEL.flat_length + 0.03
    assert contact_windows(WHEEL, rail, phase, lo, hi), "the stretch holds a window"
    fast = tabulate_constraint(WHEEL, rail, lo, hi, phase=phase)
    gen = tabulate_constraint(WHEEL, rail, lo, hi, phase=phase, method="general")
    xq = np.random.default_rng(bits).uniform(lo, hi, 20000)
    assert np.abs(fast.evaluate(xq) - gen.evaluate(xq)).max() < 1e-12
    kf = fast.kinks[(fast.kinks > lo) & (fast.kinks < hi)]
    kg = gen.kinks[(gen.kinks > lo) & (gen.kinks < hi)]
    assert kf.size == kg.size and np.abs(kf - kg).max(initial=0.0) < 1e-9
    # exact at the nodes: never below the true y_C^k (brute force's grid is a lower bound of it);
    # between them the cubic Hermite, within the table's tolerance as the ψ-search's table
    # (both measured up to ~1.05e-13 m off brute force there, HERMITE_TOL = 1e-13 m at midpoints)
    inner = fast.x[(fast.x > lo) & (fast.x < hi)]
    nodes = inner[:: max(1, inner.size // 60)]
    assert np.all(fast.evaluate(nodes) >= _brute_table(rail, nodes, phase) - 1e-16)
    pts = [xq[:20]]
    for xk in kf:
        pts.append(xk + np.array([-1e-6, -1e-9, 0.0, 1e-9, 1e-6]))
    x = np.concatenate(pts)
    ref = _brute_table(rail, x, phase)
    assert np.abs(fast.evaluate(x) - ref).max() < 2.0 * HERMITE_TOL
    assert np.abs(gen.evaluate(x) - ref).max() < 2.0 * HERMITE_TOL


def test_passage_against_the_search_table() -> None:
    """The flat's impact at 20 m/s on the paper's cosine (Hertz): the passage on the boxes' table
    has the peak force and the transitions of the passage on the ψ-search's table."""
    rail = PAPER
    phase = -0.6 / R  # the flat's middle at the bottom at x = 0.6 m
    d = derive(Material(2.14e11, 0.3, 6e8), radius=R, load=39240.0, mass=400.0)
    contact = ContactModel(ContactLaw.HERTZ, d.contact_coefficient)
    spec = PassageSpec(
        mass=400.0, load=39240.0, speed=20.0, duration=0.05, sample_rate=1e5, contact=contact
    )
    fast = tabulate_cosine_hybrid(WHEEL, rail, 0.0, 1.0, phase, None, resolution(WHEEL, rail))
    gen = tabulate_constraint(WHEEL, rail, 0.0, 1.0, phase=phase, method="general")
    assert contact_windows(WHEEL, rail, phase, 0.0, 1.0)
    a = simulate_passage(fast, spec)
    b = simulate_passage(gen, spec)
    assert a.transitions and len(a.transitions) == len(b.transitions)
    ta = np.array([t[0] for t in a.transitions])
    tb = np.array([t[0] for t in b.transitions])
    assert [t.kind for t in a.transitions] == [t.kind for t in b.transitions]
    assert np.abs(ta - tb).max() < 1e-9
    # the tables differ by ~1e-13 m: the integrator's path by its tolerance (measured 7.7e-8)
    assert abs(a.peak_force / b.peak_force - 1.0) < 1e-6
    assert a.peak_force > 2.0 * 39240.0, "the flat's impact"
