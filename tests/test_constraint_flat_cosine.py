"""Ideal flats on cosine rails (the chord's crest windows, sim_core.constraint.flat_cosine, in
the piece sweep) against the general ψ-search and brute force.

The example site's gentle cosine (a = 2 µm, λ = 6 cm), the paper's (a = 0.1 mm, λ = 5 cm)
and a steeper one with a < 0 (a trough at x = 0), each at several phases, on windows where the
flat carries the wheel: values within 1e-12 m of the ψ-search's table at 99 % of 20 000
points (1e-11 m everywhere: the ψ-search misses a corner taking over by up to ~4e-12 m),
the fast table exact (brute force) where the two differ most,
node values within 1e-12 m of the exact solve, the same kinks (slope jumps > 1e-6) within
1e-9 m, and slopes equal to finite differences of the exact solve away from kinks.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_core.constraint import evaluate_exact, tabulate_constraint
from sim_core.constraint.flat_cosine import crest_contact, supports_flat_cosine
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import supports
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from tests.test_constraint_fast import strong_kinks

RAILS = {
    "site": (0.46, RailProfile.cosine(2e-6, 0.06)),
    "paper": (0.475, RailProfile.cosine(1e-4, 0.05)),
    "steep": (0.46, RailProfile.cosine(-2e-4, 0.08)),
}


def brute(
    wheel: WheelOutline, rail: RailProfile, x: NDArray[np.float64], phase: float
) -> NDArray[np.float64]:
    """max over a dense ψ grid plus the flat's corners (numpy): within ~1e-14 m."""
    Rn = wheel.nominal_radius
    t0 = wheel.flat_half_angle
    out = np.empty(x.size)
    for i, xc in enumerate(x):
        phi = phase + xc / Rn
        corners = np.array([-t0, t0]) - phi
        corners = (corners + np.pi) % (2 * np.pi) - np.pi
        psi = np.concatenate((np.linspace(-0.09, 0.09, 360001), corners[np.abs(corners) < 0.09]))
        rho = wheel.radius_at(psi + phi)
        out[i] = np.max(rail.height(xc + rho * np.sin(psi)) + rho * np.cos(psi)) - Rn
    return out


def check_window(
    fast: ConstraintTable,
    gen: ConstraintTable,
    wheel: WheelOutline,
    rail: RailProfile,
    window: tuple[float, float],
    phase: float,
    xs: NDArray[np.float64],
    reach: float,
) -> None:
    """On a window where a flat carries the wheel: node values within 1e-12 m of the exact
    solve, the contact within ``reach`` of the wheel centre somewhere (on the flat), the same
    strong kinks as the ψ-search within 1e-9 m, slopes at ``xs`` equal to finite differences
    of the exact solve away from kinks."""
    lo, hi = window
    inside = (fast.x > lo) & (fast.x < hi)
    yd, _ = evaluate_exact(wheel, rail, fast.x[inside][::5], phase=phase)
    assert np.abs(yd - fast.y[inside][::5]).max() < 1e-12
    assert np.any(np.abs(fast.contact_x[inside] - fast.x[inside]) < reach)
    kf, kg = strong_kinks(fast, lo + 1e-3, hi - 1e-3), strong_kinks(gen, lo + 1e-3, hi - 1e-3)
    assert kf.size == kg.size and kf.size >= 1 and np.abs(kf - kg).max() < 1e-9
    far = np.min(np.abs(xs[:, None] - fast.kinks[None, :]), axis=1) > 1e-5
    h = 1e-7
    yp, _ = evaluate_exact(wheel, rail, xs[far] + h, phase=phase)
    ym, _ = evaluate_exact(wheel, rail, xs[far] - h, phase=phase)
    assert np.abs((yp - ym) / (2 * h) - fast.slope(xs[far])).max() < 1e-6


@pytest.mark.parametrize("rail_name", list(RAILS))
@pytest.mark.parametrize("phase", [0.0, 0.013, -0.04, 2.9])
def test_ideal_flat_on_cosine_against_general(rail_name: str, phase: float) -> None:
    R, rail = RAILS[rail_name]
    wheel = WheelOutline.ideal_flat(R, 0.05)
    assert supports(wheel, rail)
    # the window where the flat is under the wheel: φ = phase + x/R within ±0.1 rad of 0 (mod 2π)
    turn = 2 * np.pi * R
    centre = (-phase * R) % turn
    centre -= turn if centre > 0.5 * turn else 0.0
    lo, hi = centre - 0.045, centre + 0.045
    fast = tabulate_constraint(wheel, rail, lo, hi, phase=phase)
    gen = tabulate_constraint(wheel, rail, lo, hi, phase=phase, method="general")
    xq = np.random.default_rng(11).uniform(lo, hi, 20000)
    diff = np.abs(fast.evaluate(xq) - gen.evaluate(xq))
    # the ψ-search misses a corner taking over by up to ~1e-11 m (the worst points: brute force)
    assert np.quantile(diff, 0.99) < 1e-12 and diff.max() < 1e-11
    worst = xq[np.argsort(diff)[-8:]]
    assert np.abs(brute(wheel, rail, worst, phase) - fast.evaluate(worst)).max() < 1e-12
    check_window(fast, gen, wheel, rail, (lo, hi), phase, xq[:200], 0.025)


def test_crest_windows_bound_the_dispatch() -> None:
    """The chord's contact matches the rail's slope on the crest's concave half; a rail curved
    more than 0.9/R, or a rounded flat, keeps the ψ-search."""
    u = crest_contact(1e-3, 1e-4, 0.05)
    assert -1e-4 * 2 * np.pi / 0.05 * np.sin(2 * np.pi * u / 0.05) == pytest.approx(-1e-3)
    assert np.isnan(crest_contact(0.02, 1e-4, 0.05))
    flat = WheelOutline.ideal_flat(0.46, 0.05)
    assert supports_flat_cosine(flat, RailProfile.cosine(1e-4, 0.05))
    assert not supports_flat_cosine(flat, RailProfile.cosine(3e-4, 0.04))
    assert not supports_flat_cosine(WheelOutline.rounded_flat(0.46, 0.08, 1e-3), RAILS["site"][1])
