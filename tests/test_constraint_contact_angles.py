"""The flat zones' contact-angle bounds (``contact_zones._bounds``) against their numpy form.

θ*(x) - φ0 = asin((x_D - x)/R) + x/R at each round-table node; ``lo[i]`` is the least
θ* - margin over the intervals from i on, ``hi[i]`` the largest θ* + margin over those up to
i. ``math.asin`` (libm) and numpy's arcsin may differ by an ulp, hence the tolerance.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.constraint.contact_zones import FLAT_ZONE_MARGIN, _bounds
from sim_core.constraint.nodes import NCOL, XD, X


def _numpy_bounds(rn: np.ndarray, R: float) -> tuple[np.ndarray, np.ndarray]:
    x = rn[:, X]
    th = np.arcsin(np.clip((rn[:, XD] - x) / R, -1.0, 1.0)) + x / R
    lo = np.minimum.accumulate((th[:-1] - FLAT_ZONE_MARGIN)[::-1])[::-1]
    hi = np.maximum.accumulate(th[1:] + FLAT_ZONE_MARGIN)
    return lo, hi


@pytest.mark.parametrize("n", [1, 2, 3, 500])
def test_bounds_are_the_running_extremes_of_the_contact_angle(n: int) -> None:
    rng = np.random.default_rng(n)
    R = 0.46
    rn = np.zeros((n, NCOL))
    rn[:, X] = np.sort(rng.uniform(0.0, 2.0, n))
    # the contact point wanders a few mm about the centre, sometimes back (θ* dips)
    rn[:, XD] = rn[:, X] + 3e-3 * np.sin(40.0 * rn[:, X]) + rng.normal(0.0, 1e-4, n)
    x = np.empty(n)
    lo = np.empty(n - 1)
    hi = np.empty(n - 1)
    _bounds(rn, R, FLAT_ZONE_MARGIN, x, lo, hi)
    want_lo, want_hi = _numpy_bounds(rn, R)
    assert np.array_equal(x, rn[:, X])
    ulp = 4 * np.spacing(np.max(np.abs(rn[:, X] / R)) + 1.0)
    assert np.allclose(lo, want_lo, rtol=0.0, atol=ulp)
    assert np.allclose(hi, want_hi, rtol=0.0, atol=ulp)
    assert np.all(np.diff(lo) >= 0) and np.all(np.diff(hi) >= 0)  # monotone: binary search


def test_asin_series_matches_libm_on_both_sides_of_its_range() -> None:
    import math

    from sim_core.constraint.contact_zones import ASIN_SERIES, _asin

    u = np.concatenate(
        [
            np.linspace(-ASIN_SERIES, ASIN_SERIES, 4001),
            np.nextafter(ASIN_SERIES, [0.0, 1.0]),
            -np.nextafter(ASIN_SERIES, [0.0, 1.0]),
            np.linspace(-1.0, 1.0, 401),
            [0.0, 5e-324, 1e-300],
        ]
    )
    got = np.array([_asin(float(v)) for v in u])
    want = np.array([math.asin(float(v)) for v in u])
    assert np.all(np.abs(got - want) <= np.spacing(np.abs(want)))  # within one ulp
