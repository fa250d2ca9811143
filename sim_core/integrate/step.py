"""The one compiled explicit Runge–Kutta step: a tableau (``tableau.Stages``) drives it.

DOP853 and DOPRI5 are the same compiled function with two values of its first argument, as
diffrax drives one step by its ``ButcherTableau``: the stages, the solution's weights, the
end point stored in row ``END`` (first same as last) and the error norm all come from the
tableau, and the state's components are looped over, two for the wheel and two more for
the foundation's mass when it moves (``Params.compliant``).

Worked example: ``loop.attempt_step`` takes DOP853 steps and ``loop._run`` DOPRI5 ones
between close breakpoints; ``tests/test_integrator.py`` holds both to an independent solver.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.integrate.model import rhs
from sim_core.integrate.tableau import DOP853, DOPRI5, END, Stages
from sim_core.integrate.types import Params, Table, Work, kernel

DOP853_STAGES = DOP853.compiled()
DOPRI5_STAGES = DOPRI5.compiled()


@numba.njit(cache=True, inline="always")
def _store_stage(
    w: Work, s: int, state: NDArray[np.float64], ac: float, am: float, d: float
) -> None:
    """Row s of K = f at a stage whose state is ``state`` (accelerations ac, am), and δ there."""
    w.K[s, 0] = state[1]
    w.K[s, 1] = ac
    w.K[s, 2] = state[3]
    w.K[s, 3] = am
    w.dstage[s] = d


@numba.njit(cache=True, inline="always")
def rk_step(
    tb: Stages,
    t: float,
    y: NDArray[np.float64],
    h: float,
    mode: int,
    w: Work,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """One step of ``tb`` from (t, y) with K[0] = f(t, y): fills K[1 … stages−1] and K[END],
    ``ynew``; returns (the error norm, hint).

    K rows hold (v_C, a_C, v_M, a_M); dstage[i] is δ at stage i (NaN in flight). Rows a
    tableau has no stage for are left as they were (its error weights never read them).
    """
    K = w.K
    tmp = w.tmp
    ynew = w.ynew
    nc = 4 if par.compliant else 2
    for s in range(1, tb.stages):
        for j in range(nc):
            acc = 0.0
            for q in range(s):
                acc += tb.a[s, q] * K[q, j]
            tmp[j] = y[j] + h * acc
        ac, am, d, hint = rhs(t + tb.c[s] * h, tmp[0], tmp[1], tmp[2], tmp[3], mode, par, tab, hint)
        _store_stage(w, s, tmp, ac, am, d)
    for j in range(4):
        if j < nc:
            acc = 0.0
            for q in range(tb.stages):
                acc += tb.b[q] * K[q, j]
            ynew[j] = y[j] + h * acc
        else:
            ynew[j] = y[j]
    ac, am, d, hint = rhs(t + h, ynew[0], ynew[1], ynew[2], ynew[3], mode, par, tab, hint)
    _store_stage(w, END, ynew, ac, am, d)
    err_hi = 0.0
    err_lo = 0.0
    for j in range(nc):
        atol = par.atol_y if j % 2 == 0 else par.atol_v
        sc = atol + par.rtol * max(abs(y[j]), abs(ynew[j]))
        e_hi = 0.0
        e_lo = 0.0
        for q in tb.error_rows:
            e_hi += tb.e_high[q] * K[q, j]
            e_lo += tb.e_low[q] * K[q, j]
        e_hi /= sc
        e_lo /= sc
        err_hi += e_hi * e_hi
        err_lo += e_lo * e_lo
    if err_hi == 0.0 and err_lo == 0.0:
        return 0.0, hint
    return abs(h) * err_hi / math.sqrt((err_hi + 0.01 * err_lo) * nc), hint


@kernel
def dop853_step(
    t: float,
    y: NDArray[np.float64],
    h: float,
    mode: int,
    w: Work,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """``rk_step`` driven by DOP853. The tableau is a global, so the compiler sees its
    coefficients as constants once ``rk_step`` is inlined: it unrolls the stages and drops
    the zero terms, as a step written out for DOP853 would (one function, two tableaus,
    no price for the generality)."""
    return rk_step(DOP853_STAGES, t, y, h, mode, w, par, tab, hint)


@kernel
def dopri5_step(
    t: float,
    y: NDArray[np.float64],
    h: float,
    mode: int,
    w: Work,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """``rk_step`` driven by DOPRI5 (as ``dop853_step``)."""
    return rk_step(DOPRI5_STAGES, t, y, h, mode, w, par, tab, hint)
