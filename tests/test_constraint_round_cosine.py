"""The round wheel on a gentle cosine (sim_core.constraint.round_cosine) against the ψ-search.

The offset curve in closed form, one period: values within the Hermite tolerance (1e-13 m)
of the direct ψ-search solve everywhere (20 000 points over several periods), the same
function as the ψ-search's own table, slopes equal to the rail's slope at the contact point,
contact points on the rail's normal through the wheel centre, and the dispatch: steeper
cosines (the wheel bridging the trough) still take the ψ-search.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_core.constraint import evaluate_exact, tabulate_constraint
from sim_core.constraint.round_cosine import (
    CURVATURE_LIMIT,
    supports_round_cosine,
    tabulate_round_cosine,
)
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

CASES = {
    "Fig. 4 (0.1 mm / 5 cm, R 0.475)": (0.475, 1e-4, 0.05, 0.0),
    "negative amplitude, far start": (0.46, -3e-5, 0.04, 7.3),
    "near the limit (|a|k²R = 0.94)": (0.475, 0.94 / (0.475 * (TWO_PI / 0.05) ** 2), 0.05, -1.0),
    "long wave": (0.475, 1e-5, 0.5, 0.2),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_round_cosine_against_the_psi_search(case: str) -> None:
    R, a, lam, x0 = CASES[case]
    wheel, rail = WheelOutline.round(R), RailProfile.cosine(a, lam)
    assert supports_round_cosine(wheel, rail)
    t = tabulate_constraint(wheel, rail, x0, x0 + 3.0)
    assert t.period == lam and t.kinks.size == 0 and t.x[0] == x0
    xq = np.random.default_rng(3).uniform(x0 - 0.1, x0 + 3.1, 20000)
    exact, _ = evaluate_exact(wheel, rail, xq)
    assert np.abs(t.evaluate(xq) - exact).max() < 1.5e-13
    # the same function as the ψ-search's table (each within its tolerance of the exact)
    g = tabulate_constraint(wheel, rail, x0, x0 + 3.0, method="general")
    assert np.abs(t.evaluate(xq) - g.evaluate(xq)).max() < 3e-13
    # nodes: the wheel centre on the rail's normal at the contact point, R above it
    p = t.contact_x
    k = TWO_PI / lam
    s = -a * k * np.sin(k * p)
    assert np.allclose(t.slope_left, s, rtol=0, atol=1e-15)
    cx = t.x + 0.0
    cy = t.y + R  # the centre's height above the rail datum (round wheel on a flat rail: R)
    ry = a * np.cos(k * p)
    assert np.allclose(np.hypot(cx - p, cy - ry), R, rtol=0, atol=1e-12)
    assert np.allclose((cx - p) + s * (cy - ry), 0.0, rtol=0, atol=1e-12)
    # the contact point the ψ-search finds, at the nodes (its x_D is first order in the error
    # of its ψ, ~1e-9 m, where y_C^k is second order)
    _, xdn = evaluate_exact(wheel, rail, t.x[::7])
    assert np.abs(xdn - t.contact_x[::7]).max() < 1e-8


def test_round_cosine_is_periodic_and_reaches_the_crest() -> None:
    wheel, rail = WheelOutline.round(0.475), RailProfile.cosine(1e-4, 0.05)
    t = tabulate_round_cosine(wheel, rail, 0.013, 0.2)
    assert t.x[-1] - t.x[0] == pytest.approx(0.05, abs=1e-15)
    assert t.y[0] == t.y[-1] and t.slope_left[0] == t.slope_left[-1]
    xq = np.linspace(0.0, 0.05, 1001)
    assert np.abs(t.evaluate(xq) - t.evaluate(xq + 0.05 * 37)).max() < 1e-17
    # crest at x = 0 (mod λ): the wheel sits on it at +a; the trough's bottom at -a (to the
    # Hermite's tolerance: no node need sit there)
    assert float(t.evaluate(np.array([0.05 * 3]))[0]) == pytest.approx(1e-4, abs=1e-13)
    assert float(t.evaluate(np.array([0.025]))[0]) == pytest.approx(-1e-4, abs=1e-13)


def test_steeper_cosines_take_the_psi_search() -> None:
    R, lam = 0.475, 0.05
    k = TWO_PI / lam
    steep = RailProfile.cosine(1.05 * CURVATURE_LIMIT / (R * k * k), lam)
    wheel = WheelOutline.round(R)
    assert not supports_round_cosine(wheel, steep)
    assert not supports_round_cosine(
        WheelOutline.ideal_flat(R, 0.05), RailProfile.cosine(1e-5, lam)
    )
    with pytest.raises(ValueError, match="curvature"):
        tabulate_round_cosine(wheel, steep, 0.0, 1.0)
    # past 1/R the wheel bridges the trough: the ψ-search's table, a kink per period
    bridge = RailProfile.cosine(1.3 / (R * k * k), lam)
    t = tabulate_constraint(wheel, bridge, 0.0, 1.0)
    assert t.period == lam and t.kinks.size == 1
    assert math.isclose(float(t.y.max()), bridge.amplitude, rel_tol=1e-12)
