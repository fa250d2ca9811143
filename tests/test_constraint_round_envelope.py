"""The round wheel on a polyline rail by one pass over its segments (the envelope's stack,
sim_core.constraint.round_polyline) against the direct ψ-search solve.

Rails that stress the hand-overs: the stored rough rail (a kink at about every other
vertex), collinear and nearly collinear vertices (a hand-over in closed form that is a tie),
segments too short or too steep for the wheel to touch their interior (a concave vertex whose
two lines cross outside their tangent ranges), a step's vertical riser, and deep hollows the
wheel bridges. Values within 1e-12 m of the solve at 4000 points, node values within 1e-15 m,
and never below the rail under the wheel's centre.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.constraint import evaluate_exact, tabulate_constraint
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from tests.stored_rails import rough_rail

R = 0.46


def collinear() -> RailProfile:
    x = np.arange(0.0, 0.1, 5e-4)
    y = -7.853e-4 * x + 1e-6 * (x > 0.05) * (x - 0.05) ** 2 / 1e-3
    y[40:60] = -7.853e-4 * x[40:60] * (1.0 + 1e-15 * np.arange(20))  # last-bit kinks
    return RailProfile.sampled(x - 0.05, y)


def steep_short() -> RailProfile:
    x = np.arange(9) * 0.0039
    y = np.array([0.0, 0.0, 0.0, 0.0, -2e-4, -2e-4, 1e-4, 1e-4, -3e-5])
    return RailProfile.sampled(x - 0.015, y)


def hollows() -> RailProfile:
    x = np.arange(0.0, 0.2, 5e-4)
    y = -3e-4 * ((np.abs(x - 0.05) < 0.004) | (np.abs(x - 0.12) < 0.01)) + 2e-6 * np.sin(900 * x)
    return RailProfile.sampled(x - 0.1, y)


RAILS = {
    "rough (stored)": rough_rail,
    "collinear": collinear,
    "steep and short": steep_short,
    "hollows": hollows,
    "step": lambda: RailProfile.step(1e-4, 0.0),
}


@pytest.mark.parametrize("name", sorted(RAILS))
def test_round_envelope_against_the_solve(name: str) -> None:
    rail = RAILS[name]()
    wheel = WheelOutline.round(R)
    lo, hi = -0.05, 0.05
    t = tabulate_constraint(wheel, rail, lo, hi)
    xq = np.random.default_rng(5).uniform(lo, hi, 4000)
    exact, _ = evaluate_exact(wheel, rail, xq)
    assert np.abs(t.evaluate(xq) - exact).max() < 1e-12
    inside = (t.x > lo) & (t.x < hi)
    yn, _ = evaluate_exact(wheel, rail, t.x[inside])
    assert np.abs(yn - t.y[inside]).max() < 1e-15
    assert np.all(t.evaluate(xq) >= rail.height(xq) - 1e-15)
