"""The length interval's crossing of the χ² bound, interpolated between walked points.

The walk around the best length takes steps of 6 %, 15 %, ... ; where the profile is
steep, the first step outside the bound lands at many times it. The crossing is
interpolated in sqrt(J - J_min), exact for a parabolic profile, so a coarse step does not
shrink the interval (it used to: interpolating J itself put the crossing at a fifth of
the parabola's distance, and intervals of well-fitted flats missed the truth by 1-5 %).
"""

from __future__ import annotations

import math

import pytest

from sim_core.diagnosis.estimate import _interval


@pytest.mark.parametrize("curvature", [1e3, 1e5, 1e7])
def test_parabolic_profile_crossed_where_the_parabola_crosses(curvature: float) -> None:
    best, j_min, j_max = 0.05, 1.0, 2.28
    points = [
        (best + dx, j_min * (1.0 + curvature * dx * dx))
        for dx in (-0.015, -0.003, 0.0, 0.003, 0.015)
    ]
    lo, hi = _interval(points, j_max, best)
    half = math.sqrt((j_max / j_min - 1.0) / curvature)
    # inside the walked points the crossing is the parabola's own; beyond them, the end
    expected_lo = max(best - half, best - 0.015)
    expected_hi = min(best + half, best + 0.015)
    assert lo == pytest.approx(expected_lo, rel=1e-12)
    assert hi == pytest.approx(expected_hi, rel=1e-12)


def test_overshooting_step_no_longer_shrinks_the_interval() -> None:
    # J = 1 at the best, 30 at +6 %: linear interpolation of J gives +0.26 %, the
    # parabola through both +1.26 %
    best = 0.030
    lo, hi = _interval([(best, 1.0), (best * 1.06, 30.0)], 2.28, best)
    assert lo == best
    assert hi / best - 1.0 == pytest.approx(0.06 * math.sqrt(1.28 / 29.0), rel=1e-12)
    assert hi / best - 1.0 > 0.0125


def test_profile_never_outside_the_bound_gives_the_walked_ends() -> None:
    pts = [(0.02, 1.5), (0.03, 1.0), (0.04, 1.2)]
    assert _interval(pts, 2.0, 0.03) == (0.02, 0.04)


def test_a_flat_minimum_keeps_the_best_inside() -> None:
    # the best point itself above j_min of a neighbour: the crossing still brackets it
    lo, hi = _interval([(0.02, 5.0), (0.03, 1.0), (0.031, 1.0), (0.04, 5.0)], 2.0, 0.03)
    assert lo < 0.03 < 0.031 < hi
