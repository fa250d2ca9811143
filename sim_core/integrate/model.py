"""The vector field of MODEL.md §4 and the quantities read off a step's dense output.

The state is (y_C, v_C, y_M, v_M); on a rigid foundation y_M ≡ v_M ≡ 0.
Within one step the *mode* (flight, elastic, plastic: ``sim_core.integrate.types``) is
fixed, so the right-hand side is smooth there.

Every function here takes the table and the parameters as the named tuples of
``sim_core.integrate.types`` and a look-up ``hint`` (the last table interval),
which it returns updated: consecutive look-ups are close, so the next one
starts from the last interval instead of a bisection over the whole table.

Worked example: ``sim_core.integrate.loop.integrate`` is the only caller; see
``sim_core.passage.simulate_passage`` for a passage end to end.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import linear_at, table_eval
from sim_core.contact_laws import HERTZ, contact_force, mode_force, mode_stiffness
from sim_core.integrate.dense import dense_state
from sim_core.integrate.types import ELASTIC, FLIGHT, PLASTIC, Params, Table, kernel


@numba.njit(cache=True, inline="always")
def before(x: float, left: bool) -> float:
    """x, or a position just before it (to read the left-hand slope at a kink)."""
    if left:
        return x - 1e-13 * max(1.0, abs(x))
    return x


@numba.njit(cache=True, inline="always")
def constraint_at(tab: Table, xv: float, hint: int) -> tuple[float, float, float, int]:
    """(y_C^k, slope, stiffness scale σ, index) at x."""
    v, d, i = table_eval(tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, xv, hint)
    s = 1.0
    if tab.scale.size > 0:
        s, _, _, _ = linear_at(tab.x, tab.scale, tab.period, xv, i, False)
    return v, d, s, i


@numba.njit(cache=True, inline="always")
def value_at_x(tab: Table, xv: float, hint: int) -> tuple[float, int]:
    """(y_C^k, index) at x: the hot path of the right-hand side."""
    v, _, i = table_eval(tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, xv, hint)
    return v, i


@numba.njit(cache=True, inline="always")
def slope_at(tab: Table, xv: float, hint: int) -> tuple[float, float, int]:
    """(y_C^k, slope, index) at x."""
    return table_eval(tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, xv, hint)


@numba.njit(cache=True, inline="always")
def force(delta: float, mode: int, par: Params, scale: float) -> float:
    """F of the mode's branch (0 in flight), the Hertz part scaled by σ = ``scale``."""
    if mode == FLIGHT:
        return 0.0
    return mode_force(delta, mode == PLASTIC, par.law, par.c * scale, par.f_y, par.d_y, par.theta)


@numba.njit(cache=True, inline="always")
def loading_force(delta: float, par: Params, scale: float) -> float:
    """F(δ) on the loading branch of the law (MODEL.md §3), Hertz part scaled by ``scale``.

    The peak and least force are reported on it: the elastic branch continues a
    hair (the yield hysteresis) above δ_Y before the switch is located.
    """
    return contact_force(delta, par.law, par.c * scale, par.f_y, par.d_y, par.theta)


@numba.njit(cache=True, inline="always")
def mode_of(delta: float, par: Params) -> int:
    """The mode a state with indentation δ starts in."""
    if delta <= 0.0:
        return FLIGHT
    if par.law != HERTZ and delta > par.d_y:
        return PLASTIC
    return ELASTIC


@numba.njit(cache=True, inline="always")
def rhs(
    t: float,
    yc: float,
    vc: float,
    ym: float,
    vm: float,
    mode: int,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, float, float, int]:
    """(a_C, a_M, δ, hint). In flight δ is not needed and returned as NaN."""
    f = 0.0
    delta = np.nan
    if mode != FLIGHT:
        if tab.scale.size > 0:
            ck, _, sc, hint = constraint_at(tab, par.speed * t, hint)
        else:
            ck, hint = value_at_x(tab, par.speed * t, hint)
            sc = 1.0
        delta = -yc + ck + ym
        f = force(delta, mode, par, sc)
    # times the inverse masses: in the stage loop the compiler hoists the divisions
    ac = (-par.load + f) * (1.0 / par.mass)
    am = 0.0
    if par.compliant:
        am = (-f - par.f_stiff * ym - par.f_damp * vm) * (1.0 / par.f_mass)
    return ac, am, delta, hint


@numba.njit(cache=True, inline="always")
def jerks_and_delta(
    t: float,
    y: NDArray[np.float64],
    am: float,
    mode: int,
    par: Params,
    tab: Table,
    hint: int,
    left: bool,
) -> tuple[float, float, float, float, int]:
    """(dä_C/dt, dä_M/dt, δ, dδ/dt, hint) in ``mode``: the jerks are F'(δ)·dδ/dt through the masses.

    ``left``: take the constraint's slope just before t (a step ending on a kink).
    δ and dδ/dt (0 in flight) come from the same look-up: at a step's end they are
    what ``records.step_extrema`` folds, so it need not look the end up again.

    (A curvature-dependent C(x) adds C'(x)·V·δ^(3/2), neglected here: it only
    touches the interpolation between step ends, not the steps.)

    Inlined (as is ``jerks``): a call would copy the ~65 words of ``Params`` and
    ``Table`` for a look-up and a square root (measured on the site passage:
    ~47 ns a step as a separate function).
    """
    dfdd = 0.0
    delta = 0.0
    rate = 0.0
    if mode != FLIGHT:
        ck, dck, hint = slope_at(tab, before(par.speed * t, left), hint)
        delta = -y[0] + ck + y[2]
        rate = -y[1] + par.speed * dck + y[3]
        dfdd = mode_stiffness(delta, mode == PLASTIC, par.law, par.c, par.f_y, par.d_y, par.theta)
    jc = dfdd * rate / par.mass
    jm = 0.0
    if par.compliant:
        jm = (-dfdd * rate - par.f_stiff * y[3] - par.f_damp * am) / par.f_mass
    return jc, jm, delta, rate, hint


@numba.njit(cache=True, inline="always")
def jerks(
    t: float,
    y: NDArray[np.float64],
    am: float,
    mode: int,
    par: Params,
    tab: Table,
    hint: int,
    left: bool,
) -> tuple[float, float, int]:
    """(dä_C/dt, dä_M/dt, hint) in ``mode``: ``jerks_and_delta`` without δ and its rate."""
    jc, jm, _, _, hint = jerks_and_delta(t, y, am, mode, par, tab, hint, left)
    return jc, jm, hint


@numba.njit(cache=True, inline="always")
def delta_rate(
    s: float, t: float, h: float, coef: NDArray[np.float64], par: Params, tab: Table, hint: int
) -> tuple[float, float, int]:
    """(δ, dδ/dt, hint) at fraction s of the step [t, t + h] with dense coefficients ``coef``."""
    yc, vc, ym, vm = dense_state(s, h, coef, par.compliant)
    ck, dck, hint = slope_at(tab, par.speed * (t + s * h), hint)
    return -yc + ck + ym, -vc + par.speed * dck + vm, hint


@kernel
def force_rate(
    s: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    left: bool,
    hint: int,
) -> tuple[float, float, int]:
    """(F, q, hint) at fraction s of an elastic step with a stiffness scale C(x)/C = σ(x).

    F = σ·C·δ^(3/2) and q = 1.5·σ·dδ/dt + V·σ'·δ, which has the sign of dF/dt
    (dF/dt = C·√δ·q for δ > 0). σ is linear between table nodes, so q jumps at
    nodes; a sign change of q across a node is a kink extremum of F there.
    ``left``: read slopes just before the position (a step ending on a kink).
    """
    yc, vc, ym, vm = dense_state(s, h, coef, par.compliant)
    v = par.speed
    xv = before(v * (t + s * h), left)
    ck, dck, hint = slope_at(tab, xv, hint)
    d = -yc + ck + ym
    r = -vc + v * dck + vm
    sc, dsc, _, _ = linear_at(tab.x, tab.scale, tab.period, xv, hint, False)
    return force(d, ELASTIC, par, sc), 1.5 * sc * r + v * dsc * d, hint


@kernel
def curvature_bound(tab: Table) -> float:
    """max |y_C^k''| of the Hermite table (1/m): y'' is linear on each piece, so at a piece's end.

    For y = 0.1·x² tabulated exactly (values and slopes) it is 0.2 on every piece.
    """
    out = 0.0
    for i in range(tab.x.size - 1):
        h = tab.x[i + 1] - tab.x[i]
        dy = (tab.y[i + 1] - tab.y[i]) / (h * h)
        m0 = tab.slope_right[i] / h
        m1 = tab.slope_left[i + 1] / h
        c0 = 6.0 * dy - 4.0 * m0 - 2.0 * m1
        c1 = -6.0 * dy + 2.0 * m0 + 4.0 * m1
        out = max(out, abs(c0), abs(c1))
    return out
