"""The one compiled look-up of sampled arrays: rail heights, wheel outlines, constraint tables.

``locate`` finds the interval of a strictly increasing array that holds a position, starting
from a hint (the last interval: consecutive look-ups of an integration or a sweep are
nearby, so most cost one or two comparisons; a far jump falls back to bisection).
``wrap`` wraps a position into one period of a periodic array, ``linear`` interpolates.

Worked example: samples at 0, 1, 2, 3 m; 2.5 m lies in interval 2, and a periodic array of
period 4 m over [0, 4) holds 9.5 m at 1.5 m (two periods of 4 m taken off):

    >>> import numpy as np
    >>> xs = np.array([0.0, 1.0, 2.0, 3.0])
    >>> locate(xs, 2.5, 0), wrap(9.5, 0.0, 4.0)
    (2, (1.5, 8.0))
    >>> linear(xs, 2.0 * xs, 2.5, 2)
    5.0
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["linear", "locate", "wrap"]


@numba.njit(cache=True, inline="always")
def wrap(xv: float, x0: float, period: float) -> tuple[float, float]:
    """(position inside [x0, x0 + period), shift taken off); no wrap if period <= 0."""
    if period <= 0.0:
        return xv, 0.0
    n = np.floor((xv - x0) * (1.0 / period))  # a division the look-up loops hoist
    shift = n * period
    return xv - shift, shift


@numba.njit(cache=True, inline="always")
def locate(x: NDArray[np.float64], xv: float, hint: int) -> int:
    """Index i with x[i] <= xv < x[i+1] (clamped to [0, n-2]); starts at ``hint``."""
    n = x.size
    i = hint
    if i < 0 or i > n - 2:
        i = 0
    if x[i] <= xv:
        if i + 1 < n - 1 and xv >= x[i + 1]:
            if i + 2 < n - 1 and xv >= x[i + 2]:
                return _bisect_index(x, xv, i + 2, n - 1)
            return i + 1
        return i
    return _bisect_index(x, xv, 0, i)


@numba.njit(cache=True, inline="always")
def _bisect_index(x: NDArray[np.float64], xv: float, lo: int, hi: int) -> int:
    """The largest i in [lo, hi) with x[i] <= xv, given x[lo] <= xv < x[hi] (or lo the answer)."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if x[mid] <= xv:
            lo = mid
        else:
            hi = mid
    return lo


@numba.njit(cache=True, inline="always")
def linear(x: NDArray[np.float64], v: NDArray[np.float64], xv: float, i: int) -> float:
    """v interpolated linearly at ``xv`` in interval i (x[i] <= xv <= x[i+1])."""
    w = (xv - x[i]) / (x[i + 1] - x[i])
    return v[i] + w * (v[i + 1] - v[i])
