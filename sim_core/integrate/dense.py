"""Dense output of one step: the septic Hermite polynomial through both ends.

With s = (t - t_n)/h the position of each body is Σ c_k s^k, k = 0..7,
matching position, velocity, acceleration and jerk at both step ends: exact
for flight (a parabola), O(h⁸) in contact. DOP853 gives the accelerations
without extra stages; the jerks are F'(δ)·dδ/dt through the masses
(``model.jerks``). Row 0 of the coefficients is the wheel, row 1 the
foundation.

Worked example: a parabola y = t²/2 over a step of h = 2 is reproduced exactly,

    >>> import numpy as np
    >>> coef = np.zeros((2, 8))
    >>> fill_dense(coef, 2.0, np.zeros(4), np.array([0.0, 1.0, 0.0, 0.0]), 0.0, 0.0,
    ...            np.array([2.0, 2.0, 0.0, 0.0]), np.array([2.0, 1.0, 0.0, 0.0]), 0.0, 0.0)
    >>> [round(v, 12) for v in dense(0.5, 2.0, coef)]
    [0.5, 1.0, 0.0, 0.0]
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

# c_0..c_3 come from the start; c_4..c_7 = _SEPTIC_INV · (the end conditions' residuals).
_SEPTIC_INV = np.linalg.inv(
    np.array(
        [
            [1.0, 1.0, 1.0, 1.0],
            [4.0, 5.0, 6.0, 7.0],
            [12.0, 20.0, 30.0, 42.0],
            [24.0, 60.0, 120.0, 210.0],
        ]
    )
)


@numba.njit(cache=True, inline="always")
def _septic_fill(
    c: NDArray[np.float64],
    row: int,
    h: float,
    p0: float,
    v0: float,
    a0: float,
    j0: float,
    p1: float,
    v1: float,
    a1: float,
    j1: float,
) -> None:
    h2 = h * h
    h3 = h2 * h
    c0 = p0
    c1 = h * v0
    c2 = 0.5 * h2 * a0
    c3 = h3 * j0 / 6.0
    r0 = p1 - (c0 + c1 + c2 + c3)
    r1 = h * v1 - (c1 + 2.0 * c2 + 3.0 * c3)
    r2 = h2 * a1 - (2.0 * c2 + 6.0 * c3)
    r3 = h3 * j1 - 6.0 * c3
    c[row, 0] = c0
    c[row, 1] = c1
    c[row, 2] = c2
    c[row, 3] = c3
    for k in range(4):
        c[row, 4 + k] = (
            _SEPTIC_INV[k, 0] * r0
            + _SEPTIC_INV[k, 1] * r1
            + _SEPTIC_INV[k, 2] * r2
            + _SEPTIC_INV[k, 3] * r3
        )


@numba.njit(cache=True, inline="always")
def fill_dense(
    coef: NDArray[np.float64],
    h: float,
    y0: NDArray[np.float64],
    k0: NDArray[np.float64],
    j0c: float,
    j0m: float,
    y1: NDArray[np.float64],
    k1: NDArray[np.float64],
    j1c: float,
    j1m: float,
) -> None:
    """Coefficients of the step's dense output; k0/k1 are (v_C, a_C, v_M, a_M) at the ends.

    Inlined: ~30 floating-point operations a row, less than the cost of a call.
    """
    _septic_fill(coef, 0, h, y0[0], y0[1], k0[1], j0c, y1[0], y1[1], k1[1], j1c)
    _septic_fill(coef, 1, h, y0[2], y0[3], k0[3], j0m, y1[2], y1[3], k1[3], j1m)


@numba.njit(cache=True, inline="always")
def dense(s: float, h: float, coef: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """(y_C, v_C, y_M, v_M) at fraction s of the step (septic Hermite, O(h^8) in position)."""
    pc = coef[0, 7]
    dc = 7.0 * coef[0, 7]
    pm = coef[1, 7]
    dm = 7.0 * coef[1, 7]
    for k in range(6, 0, -1):
        pc = pc * s + coef[0, k]
        dc = dc * s + k * coef[0, k]
        pm = pm * s + coef[1, k]
        dm = dm * s + k * coef[1, k]
    pc = pc * s + coef[0, 0]
    pm = pm * s + coef[1, 0]
    return pc, dc / h, pm, dm / h


@numba.njit(cache=True, inline="always")
def dense_state(
    s: float, h: float, coef: NDArray[np.float64], compliant: bool
) -> tuple[float, float, float, float]:
    """``dense``, skipping the foundation's row on a rigid foundation (y_M = v_M = 0 there).

    On a rigid foundation that row is zeros, so the wheel's values are the same bits and
    the foundation's the same zeros (up to the sign of zero) at half the work: this is
    what every event scan and sample evaluates.
    """
    if compliant:
        return dense(s, h, coef)
    pc = coef[0, 7]
    dc = 7.0 * coef[0, 7]
    for k in range(6, 0, -1):
        pc = pc * s + coef[0, k]
        dc = dc * s + k * coef[0, k]
    pc = pc * s + coef[0, 0]
    return pc, dc / h, 0.0, 0.0


@numba.njit(cache=True, inline="always")
def end_acceleration(h: float, coef: NDArray[np.float64], row: int) -> tuple[float, float]:
    """The second derivatives (per s²) at both ends of row ``row``, divided by h² (accelerations)."""
    a0 = 2.0 * coef[row, 2] / (h * h)
    a1 = 0.0
    for k in range(2, 8):
        a1 += k * (k - 1) * coef[row, k]
    return a0, a1 / (h * h)
