"""Compiled adaptive DOP853 integrator with located contact events.

The state is (y_C, v_C, y_M, v_M); on a rigid foundation y_M ≡ v_M ≡ 0. The
right-hand side is smooth inside each *mode* — flight (F = 0), elastic contact
(Hertz), plastic contact (Johnson or the plateau F_Y) — and every switch
between modes is an *event* located to ~1e-13 s on the step's interpolant and
then reached by a fresh Runge–Kutta step that ends exactly on it, so no step
ever straddles a change of law (MODEL.md §4, §7):

- loss of contact: δ falls through 0 (elastic mode);
- return of contact: δ rises through 0 (flight);
- yield / unyield: δ crosses δ_Y (± a hysteresis of ~1e-14 m, MODEL.md §5).

Kinks of the constraint y_C^k (contact-point jumps) are known in advance
(``ConstraintTable.kinks``): steps in contact stop exactly on them.

How crossings are found without stepping over them:

- in contact the 12 stages of each step already evaluate δ; if any of them,
  or the step's end, comes near a threshold, the step's interpolant is scanned
  for a sign change;
- in flight on a rigid foundation the wheel centre is a parabola (steps grow
  to the end of the window, the error estimate being zero), so δ(t) is scanned
  by interval bisection with a rigorous bound on δ'' (P/m + V²·max|y_C^k''|,
  plus the foundation's acceleration): an interval is discarded only if its
  end values and the bound prove δ < 0 inside it.

Dense output is the septic Hermite polynomial through the positions,
velocities, accelerations and jerks at both step ends (exact for flight,
O(h⁸) in contact): DOP853 gives the accelerations without extra stages and
the jerks are F'(δ)·dδ/dt through the masses.

Extrema (peak and least δ and force in contact) are taken from that continuous
solution: at the step ends and where dδ/dt — or, with a curvature-dependent
C(x), the rate of C(x)·δ^(3/2) — changes sign inside a step.

Worked example: ``sim_core.passage.simulate_passage`` wraps this; see there.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core import dop853
from sim_core.constraint_table import locate, table_eval, table_value, wrap
from sim_core.contact_laws import HERTZ, JOHNSON, contact_force, mode_force

# Modes.
FLIGHT = 0
ELASTIC = 1
PLASTIC = 2

# Transition codes (sim_core.passage.TRANSITION_KINDS).
EV_LOSS = 0
EV_CONTACT = 1
EV_YIELD = 2
EV_UNYIELD = 3

# Layout of the float parameter vector.
P_LAW = 0
P_C = 1
P_FY = 2
P_DY = 3
P_THETA = 4
P_MASS = 5
P_LOAD = 6
P_FMASS = 7
P_FSTIFF = 8
P_FDAMP = 9
P_SPEED = 10
P_COMPLIANT = 11
P_HYST = 12
P_RTOL = 13
P_ATOL_Y = 14
P_ATOL_V = 15
P_HMAX_CONTACT = 16
P_C2MAX = 17
P_DENT_DX = 18
P_TRACK_DENTS = 19
N_PARAMS = 20

# Status codes.
OK = 0
STEP_TOO_SMALL = 1
TOO_MANY_STEPS = 2

# Sample columns.
S_T = 0
S_X = 1
S_YC = 2
S_VC = 3
S_YM = 4
S_VM = 5
S_YCK = 6
S_DELTA = 7
S_FORCE = 8
S_CONTACT = 9
N_COLS = 10

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
EVENT_OFFSET = 1e-15
"""How far (m) past a switching surface the state is put after an event."""

LOSS_AIM = 1.1
"""Aim a step this far past the linearly predicted loss of contact (δ is convex there)."""

IMPACT_FIRST_STEP = 0.004
"""First step after a landing, as a fraction of the Hertz impact duration."""

_A = dop853.A
_B = dop853.B
_C = dop853.C
_E3 = dop853.E3
_E5 = dop853.E5


@numba.njit(cache=True, inline="always")
def _constraint(
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tscale: NDArray[np.float64],
    period: float,
    xv: float,
    hint: int,
) -> tuple[float, float, float, int]:
    """(y_C^k, slope, stiffness scale, index) at x."""
    v, d, i = table_eval(tx, ty, tsl, tsr, period, xv, hint)
    s = 1.0
    if tscale.size > 0:
        xw, _ = wrap(xv, tx[0], period)
        if xw <= tx[0]:
            s = tscale[0]
        elif xw >= tx[tx.size - 1]:
            s = tscale[tx.size - 1]
        else:
            u = (xw - tx[i]) / (tx[i + 1] - tx[i])
            s = tscale[i] + u * (tscale[i + 1] - tscale[i])
    return v, d, s, i


@numba.njit(cache=True, inline="always")
def _force(delta: float, mode: int, par: NDArray[np.float64], scale: float) -> float:
    if mode == FLIGHT:
        return 0.0
    return mode_force(
        delta,
        mode == PLASTIC,
        int(par[P_LAW]),
        par[P_C] * scale,
        par[P_FY],
        par[P_DY],
        par[P_THETA],
    )


@numba.njit(cache=True, inline="always")
def _loading_force(delta: float, par: NDArray[np.float64], scale: float) -> float:
    """F(δ) on the loading branch of the law (MODEL.md §3), Hertz part scaled by ``scale``.

    The peak and least force are reported on it: the elastic branch continues a
    hair (the yield hysteresis) above δ_Y before the switch is located.
    """
    return contact_force(
        delta, int(par[P_LAW]), par[P_C] * scale, par[P_FY], par[P_DY], par[P_THETA]
    )


@numba.njit(cache=True, inline="always")
def _rhs(
    t: float,
    yc: float,
    vc: float,
    ym: float,
    vm: float,
    mode: int,
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tscale: NDArray[np.float64],
    period: float,
    hint: int,
) -> tuple[float, float, float, int]:
    """(a_C, a_M, δ, hint). In flight δ is not needed and returned as NaN."""
    f = 0.0
    delta = np.nan
    if mode != FLIGHT:
        if tscale.size > 0:
            ck, _, sc, hint = _constraint(tx, ty, tsl, tsr, tscale, period, par[P_SPEED] * t, hint)
        else:
            ck, hint = table_value(tx, ty, tsl, tsr, period, par[P_SPEED] * t, hint)
            sc = 1.0
        delta = -yc + ck + ym
        f = _force(delta, mode, par, sc)
    ac = (-par[P_LOAD] + f) / par[P_MASS]
    am = 0.0
    if par[P_COMPLIANT] > 0.0:
        am = (-f - par[P_FSTIFF] * ym - par[P_FDAMP] * vm) / par[P_FMASS]
    return ac, am, delta, hint


# Septic Hermite interpolation: with s = (t - t_n)/h the position is Σ c_k s^k, k = 0..7,
# matching position, velocity, acceleration and jerk at both ends. c_0..c_3 come from
# the start; c_4..c_7 = _SEPTIC_INV · (the end conditions' residuals).
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


@numba.njit(cache=True)
def _fill_dense(
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
    """Coefficients of the step's dense output; k0/k1 are (v_C, a_C, v_M, a_M) at the ends."""
    _septic_fill(coef, 0, h, y0[0], y0[1], k0[1], j0c, y1[0], y1[1], k1[1], j1c)
    _septic_fill(coef, 1, h, y0[2], y0[3], k0[3], j0m, y1[2], y1[3], k1[3], j1m)


@numba.njit(cache=True, inline="always")
def _dense(s: float, h: float, coef: NDArray[np.float64]) -> tuple[float, float, float, float]:
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
def _before(x: float, left: bool) -> float:
    """x, or a position just before it (to read the left-hand slope at a kink)."""
    if left:
        return x - 1e-13 * max(1.0, abs(x))
    return x


@numba.njit(cache=True)
def _jerks(
    t: float,
    y: NDArray[np.float64],
    am: float,
    mode: int,
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
    hint: int,
    left: bool,
) -> tuple[float, float, int]:
    """(dä_C/dt, dä_M/dt, hint) in ``mode``: F'(δ)·dδ/dt through the masses.

    ``left``: take the constraint's slope just before t (a step ending on a kink).

    (A curvature-dependent C(x) adds C'(x)·V·δ^(3/2), neglected here: it only
    touches the interpolation between step ends, not the steps.)
    """
    dfdd = 0.0
    rate = 0.0
    if mode != FLIGHT:
        ck, dck, hint = table_eval(tx, ty, tsl, tsr, period, _before(par[P_SPEED] * t, left), hint)
        delta = -y[0] + ck + y[2]
        rate = -y[1] + par[P_SPEED] * dck + y[3]
        if delta > 0.0:
            if mode == ELASTIC:
                dfdd = 1.5 * par[P_C] * math.sqrt(delta)
            elif int(par[P_LAW]) == JOHNSON:
                sj = 2.0 * delta / par[P_DY] - 1.0
                if sj < 1e-300:
                    sj = 1e-300
                th3 = 3.0 * par[P_THETA]
                dfdd = par[P_FY] * (2.0 / par[P_DY]) * (1.0 + math.log(sj) / th3 + 1.0 / th3)
    jc = dfdd * rate / par[P_MASS]
    jm = 0.0
    if par[P_COMPLIANT] > 0.0:
        jm = (-dfdd * rate - par[P_FSTIFF] * y[3] - par[P_FDAMP] * am) / par[P_FMASS]
    return jc, jm, hint


@numba.njit(cache=True)
def _gval(
    s: float,
    kind: int,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
) -> float:
    """Event function at fraction s: signed so that the event is g going from <= 0 to > 0.

    kind: 0 contact (g = δ), 1 loss (g = -δ), 2 yield (g = δ - δ_Y - hyst),
    3 unyield (g = δ_Y - hyst - δ).
    """
    yc, _, ym, _ = _dense(s, h, coef)
    ck, _, _ = table_eval(tx, ty, tsl, tsr, period, par[P_SPEED] * (t + s * h), 0)
    d = -yc + ck + ym
    if kind == 0:
        return d
    if kind == 1:
        return -d
    if kind == 2:
        return d - par[P_DY] - par[P_HYST]
    return par[P_DY] - par[P_HYST] - d


@numba.njit(cache=True)
def _delta_rate(
    s: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
) -> tuple[float, float]:
    """(δ, dδ/dt) at fraction s of the step."""
    yc, vc, ym, vm = _dense(s, h, coef)
    ck, dck, _ = table_eval(tx, ty, tsl, tsr, period, par[P_SPEED] * (t + s * h), 0)
    return -yc + ck + ym, -vc + par[P_SPEED] * dck + vm


@numba.njit(cache=True)
def _elastic_force_rate(
    s: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tscale: NDArray[np.float64],
    period: float,
    left: bool,
) -> tuple[float, float]:
    """(F, q) at fraction s of an elastic step with a stiffness scale C(x)/C = σ(x).

    F = σ·C·δ^(3/2) and q = 1.5·σ·dδ/dt + V·σ'·δ, which has the sign of dF/dt
    (dF/dt = C·√δ·q for δ > 0). σ is linear between table nodes, so q jumps at
    nodes; a sign change of q across a node is a kink extremum of F there.
    ``left``: read slopes just before the position (a step ending on a kink).
    """
    yc, vc, ym, vm = _dense(s, h, coef)
    v = par[P_SPEED]
    xv = _before(v * (t + s * h), left)
    ck, dck, i = table_eval(tx, ty, tsl, tsr, period, xv, 0)
    d = -yc + ck + ym
    r = -vc + v * dck + vm
    xw, _ = wrap(xv, tx[0], period)
    dsc = 0.0
    if xw <= tx[0]:
        sc = tscale[0]
    elif xw >= tx[tx.size - 1]:
        sc = tscale[tx.size - 1]
    else:
        dsc = (tscale[i + 1] - tscale[i]) / (tx[i + 1] - tx[i])
        sc = tscale[i] + (xw - tx[i]) * dsc
    return _force(d, ELASTIC, par, sc), 1.5 * sc * r + v * dsc * d


@numba.njit(cache=True)
def _root(
    sa: float,
    ga: float,
    sb: float,
    gb: float,
    kind: int,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
) -> float:
    """Illinois regula falsi for the first g > 0 in (sa, sb] with g(sa) <= 0 < g(sb)."""
    side = 0
    tol = 1e-14 / h if h > 0 else 1e-14
    for _ in range(200):
        if sb - sa <= tol:
            break
        sm = (sa * gb - sb * ga) / (gb - ga) if gb != ga else 0.5 * (sa + sb)
        if not (sa < sm < sb):
            sm = 0.5 * (sa + sb)
        gm = _gval(sm, kind, t, h, coef, par, tx, ty, tsl, tsr, period)
        if gm > 0.0:
            sb = sm
            gb = gm
            if side == -1:
                ga *= 0.5
            side = -1
        else:
            sa = sm
            ga = gm
            if side == 1:
                gb *= 0.5
            side = 1
    return sb


@numba.njit(cache=True)
def _first_crossing_scan(
    kind: int,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
    n_points: int,
) -> float:
    """Scan g at n_points+1 equal fractions (and the RK nodes); return the root or -1."""
    ga = _gval(0.0, kind, t, h, coef, par, tx, ty, tsl, tsr, period)
    if ga > 0.0:
        # Starting on the wrong side by round-off: treat the start as g = 0.
        ga = 0.0
    sa = 0.0
    for j in range(1, n_points + 1):
        sb = j / n_points
        gb = _gval(sb, kind, t, h, coef, par, tx, ty, tsl, tsr, period)
        if gb > 0.0:
            return _root(
                sa,
                ga,
                sb,
                gb,
                kind,
                t,
                h,
                coef,
                par,
                tx,
                ty,
                tsl,
                tsr,
                period,
            )
        sa = sb
        ga = gb
    return -1.0


@numba.njit(cache=True)
def _flight_scan(
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    period: float,
    kinks: NDArray[np.float64],
    stack_s: NDArray[np.float64],
    stack_g: NDArray[np.float64],
    s_start: float,
) -> float:
    """First return of contact in the step after fraction ``s_start``, or -1.

    On [sa, sb] with g = δ <= 0 at both ends and |δ''| <= D2, δ <= max(ga, gb) + D2·(Δt)²/8.
    Kinks of the constraint break the bound on δ'' and are inserted as split points.
    """
    v = par[P_SPEED]
    d2 = par[P_LOAD] / par[P_MASS] + v * v * par[P_C2MAX]
    if par[P_COMPLIANT] > 0.0:
        # the foundation's acceleration at the step's ends, from the dense coefficients
        a0m = 2.0 * coef[1, 2] / (h * h)
        a1m = 0.0
        for k in range(2, 8):
            a1m += k * (k - 1) * coef[1, k]
        a1m /= h * h
        d2 += 2.0 * max(abs(a0m), abs(a1m)) + 1e-12
    x0 = v * (t + s_start * h)
    x1 = v * (t + h)
    lo = 0
    hi = 0
    if kinks.size > 0:
        lo = np.searchsorted(kinks, x0, side="right")
        hi = np.searchsorted(kinks, x1, side="left")
    min_ds = 1e-13 / h
    cap = stack_s.size
    sa = s_start
    ga = _gval(sa, 0, t, h, coef, par, tx, ty, tsl, tsr, period)
    if ga > 0.0:
        ga = 0.0
    # segments between kinks, left to right; inside each, depth-first halving
    for j in range(lo, hi + 1):
        if j < hi:
            s_end = (kinks[j] / v - t) / h
            if not (sa < s_end < 1.0):
                continue
        else:
            s_end = 1.0
        n = 1
        stack_s[0] = s_end
        stack_g[0] = _gval(s_end, 0, t, h, coef, par, tx, ty, tsl, tsr, period)
        while n > 0:
            sb = stack_s[n - 1]
            gb = stack_g[n - 1]
            dt = (sb - sa) * h
            if gb > 0.0:
                # A crossing lies in [sa, sb] and none before sa. It is the only one if g
                # is monotone there: g'(sa) > |g''|max·Δt. Otherwise halve and look left first.
                _, rate_a = _delta_rate(sa, t, h, coef, par, tx, ty, tsl, tsr, period)
                if rate_a > d2 * dt or (sb - sa) < min_ds or n >= cap:
                    return _root(
                        sa,
                        ga,
                        sb,
                        gb,
                        0,
                        t,
                        h,
                        coef,
                        par,
                        tx,
                        ty,
                        tsl,
                        tsr,
                        period,
                    )
            else:
                bound = max(ga, gb) + d2 * dt * dt / 8.0
                if bound < 0.0 or (sb - sa) < min_ds or n >= cap:
                    # proven free of contact (or unresolvably small): move on
                    sa = sb
                    ga = gb
                    n -= 1
                    continue
            sm = 0.5 * (sa + sb)
            stack_s[n] = sm
            stack_g[n] = _gval(sm, 0, t, h, coef, par, tx, ty, tsl, tsr, period)
            n += 1
    return -1.0


@numba.njit(cache=True)
def _rk_step(
    t: float,
    y: NDArray[np.float64],
    h: float,
    mode: int,
    K: NDArray[np.float64],
    ynew: NDArray[np.float64],
    dstage: NDArray[np.float64],
    tmp: NDArray[np.float64],
    par: NDArray[np.float64],
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tscale: NDArray[np.float64],
    period: float,
    hint: int,
) -> tuple[float, int]:
    """One DOP853 step from (t, y) with K[0] = f(t, y); fills K[1..12], ynew; returns (error norm, hint).

    K rows hold (v_C, a_C, v_M, a_M); dstage[i] is δ at stage i (NaN in flight).
    """
    nc = 4 if par[P_COMPLIANT] > 0.0 else 2
    for s in range(1, 12):
        for j in range(nc):
            acc = 0.0
            for q in range(s):
                acc += _A[s, q] * K[q, j]
            tmp[j] = y[j] + h * acc
        ac, am, d, hint = _rhs(
            t + _C[s] * h,
            tmp[0],
            tmp[1],
            tmp[2],
            tmp[3],
            mode,
            par,
            tx,
            ty,
            tsl,
            tsr,
            tscale,
            period,
            hint,
        )
        K[s, 0] = tmp[1]
        K[s, 1] = ac
        K[s, 2] = tmp[3]
        K[s, 3] = am
        dstage[s] = d
    for j in range(nc):
        acc = 0.0
        for q in range(12):
            acc += _B[q] * K[q, j]
        ynew[j] = y[j] + h * acc
    for j in range(nc, 4):
        ynew[j] = y[j]
    ac, am, d, hint = _rhs(
        t + h, ynew[0], ynew[1], ynew[2], ynew[3], mode, par, tx, ty, tsl, tsr, tscale, period, hint
    )
    K[12, 0] = ynew[1]
    K[12, 1] = ac
    K[12, 2] = ynew[3]
    K[12, 3] = am
    dstage[12] = d
    # DOP853 error norm (as in Hairer's code and SciPy)
    err5 = 0.0
    err3 = 0.0
    for j in range(nc):
        atol = par[P_ATOL_Y] if j % 2 == 0 else par[P_ATOL_V]
        sc = atol + par[P_RTOL] * max(abs(y[j]), abs(ynew[j]))
        e5 = 0.0
        e3 = 0.0
        for q in range(13):
            e5 += _E5[q] * K[q, j]
            e3 += _E3[q] * K[q, j]
        e5 /= sc
        e3 /= sc
        err5 += e5 * e5
        err3 += e3 * e3
    if err5 == 0.0 and err3 == 0.0:
        return 0.0, hint
    denom = err5 + 0.01 * err3
    return abs(h) * err5 / math.sqrt(denom * nc), hint


@numba.njit(cache=True)
def _mode_of(delta: float, par: NDArray[np.float64]) -> int:
    if delta <= 0.0:
        return FLIGHT
    if int(par[P_LAW]) != HERTZ and delta > par[P_DY]:
        return PLASTIC
    return ELASTIC


@numba.njit(cache=True, nogil=True)
def integrate(
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tcx: NDArray[np.float64],
    tscale: NDArray[np.float64],
    period: float,
    kinks: NDArray[np.float64],
    par: NDArray[np.float64],
    t0: float,
    t1: float,
    y0: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    max_steps: int,
) -> tuple[
    int,
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int64],
    NDArray[np.float64],
]:
    """Integrate one passage from t0 to t1.

    Args:
        tx..tscale, period: the constraint table (sim_core.constraint_table).
        kinks: kink positions x (absolute, sorted) over the passage.
        par: parameters (layout P_*).
        y0: initial (y_C, v_C, y_M, v_M).
        sample_t: increasing output times in [t0, t1].
        max_steps: safety limit on accepted + rejected steps.

    Returns:
        (status, samples[n, N_COLS], transition times, transition codes,
         extrema [peak δ, least δ in contact, time out of contact, time reached, mode
         there, peak force, least force in contact] (the time and mode say where a
         failed integration stopped),
         dent records [m, 3] (t, x_D, δ) taken while plastic,
         stats [steps, rejected, rhs evaluations], final state)
    """
    v = par[P_SPEED]
    ns = sample_t.size
    samples = np.zeros((ns, N_COLS))
    cap_tr = 64
    tr_t = np.empty(cap_tr)
    tr_k = np.empty(cap_tr, dtype=np.int64)
    n_tr = 0
    cap_dent = 1024
    dents = np.empty((cap_dent, 3))
    n_dent = 0
    track_dents = par[P_TRACK_DENTS] > 0.0
    dent_dx = par[P_DENT_DX]
    K = np.zeros((13, 4))
    K1 = np.zeros((13, 4))
    dstage = np.zeros(13)
    stack_s = np.empty(128)
    stack_g = np.empty(128)
    y = y0.copy()
    y_prev = y0.copy()
    ynew = np.empty(4)
    tmp = np.zeros(4)
    status = OK
    hint = 0
    t = t0
    ck0, _, sc0, hint = _constraint(tx, ty, tsl, tsr, tscale, period, v * t, hint)
    delta0 = -y[0] + ck0 + y[2]
    mode = _mode_of(delta0, par)
    scaled = tscale.size > 0
    ac, am, _, hint = _rhs(
        t, y[0], y[1], y[2], y[3], mode, par, tx, ty, tsl, tsr, tscale, period, hint
    )
    K[0, 0] = y[1]
    K[0, 1] = ac
    K[0, 2] = y[3]
    K[0, 3] = am
    coef = np.zeros((2, 8))
    j0c, j0m, hint = _jerks(t, y, am, mode, par, tx, ty, tsl, tsr, period, hint, False)
    peak_delta = delta0
    min_delta = delta0 if mode != FLIGHT else 0.0
    peak_f = _loading_force(delta0, par, sc0) if mode != FLIGHT else 0.0
    min_f = peak_f
    t_flight = 0.0
    nsteps = 0
    nrej = 0
    nrhs = 1
    # first step guess: a fraction of the contact period
    h = 1e-6
    hmin_abs = 1e-15
    # samples at t0
    si = 0
    while si < ns and sample_t[si] <= t0:
        si += 1
    for q in range(si):
        samples[q, S_T] = sample_t[q]
        samples[q, S_X] = v * sample_t[q]
        samples[q, S_YC] = y[0]
        samples[q, S_VC] = y[1]
        samples[q, S_YM] = y[2]
        samples[q, S_VM] = y[3]
        samples[q, S_YCK] = ck0
        samples[q, S_DELTA] = delta0
        samples[q, S_FORCE] = _force(delta0, mode, par, 1.0) if mode != FLIGHT else 0.0
        samples[q, S_CONTACT] = 1.0 if mode != FLIGHT else 0.0
    kp = 0
    while kp < kinks.size and kinks[kp] <= v * t + 1e-15:
        kp += 1
    while t < t1:
        if nsteps + nrej >= max_steps:
            status = TOO_MANY_STEPS
            break
        hmax = t1 - t
        if mode != FLIGHT:
            hmax = min(hmax, par[P_HMAX_CONTACT])
        hit_kink = False
        if mode != FLIGHT and kp < kinks.size:
            tk = kinks[kp] / v
            if tk - t <= hmax:
                hmax = tk - t
                hit_kink = True
        if h >= hmax:
            h = hmax
        else:
            hit_kink = False
        if h < hmin_abs:
            if hit_kink:
                # already on the kink (to round-off): pass it
                kp += 1
                h = max(h, 1e-9)
                continue
            status = STEP_TOO_SMALL
            break
        # --- attempt steps until accepted
        rejected = False
        if mode != FLIGHT:
            ck_start, hint = table_value(tx, ty, tsl, tsr, period, v * t, hint)
            dstage[0] = -y[0] + ck_start + y[2]
        while True:
            err, hint = _rk_step(
                t, y, h, mode, K, ynew, dstage, tmp, par, tx, ty, tsl, tsr, tscale, period, hint
            )
            nrhs += 12
            if err <= 1.0:
                break
            nrej += 1
            rejected = True
            factor = max(MIN_FACTOR, SAFETY * err ** (-1.0 / 8.0))
            if mode == ELASTIC:
                # An attempt that ran past a loss of contact (a stage or its end with
                # δ < 0), where F ~ δ^(3/2) stops being smooth and the error estimate
                # explodes: aim the next attempt just short of the first crossing the
                # stage values bracket, instead of shrinking blindly.
                c_neg = 2.0
                for q in range(1, 13):
                    if dstage[q] < 0.0 and _C[q] < c_neg:
                        c_neg = _C[q]
                if c_neg <= 1.0:
                    c_pos = 0.0
                    d_pos = max(dstage[0], 0.0)
                    d_neg = 0.0
                    for q in range(1, 13):
                        if _C[q] < c_neg and _C[q] > c_pos and dstage[q] > 0.0:
                            c_pos = _C[q]
                            d_pos = dstage[q]
                        if _C[q] == c_neg:
                            d_neg = dstage[q]
                    c_cross = c_pos + (c_neg - c_pos) * d_pos / (d_pos - d_neg)
                    factor = max(factor, min(0.98 * c_cross, 0.9))
            h *= factor
            hit_kink = False
            if h < hmin_abs:
                status = STEP_TOO_SMALL
                break
        if status != OK:
            break
        nsteps += 1
        factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / 8.0))
        if rejected:
            factor = min(1.0, factor)
        j1c, j1m, hint = _jerks(
            t + h, ynew, K[12, 3], mode, par, tx, ty, tsl, tsr, period, hint, True
        )
        _fill_dense(coef, h, y, K[0], j0c, j0m, ynew, K[12], j1c, j1m)
        # --- events
        ev_s = -1.0
        ev_kind = -1
        if mode == FLIGHT:
            s_from = 0.0
            while True:
                ev_s = _flight_scan(
                    t, h, coef, par, tx, ty, tsl, tsr, period, kinks, stack_s, stack_g, s_from
                )
                if ev_s < 0.0:
                    break
                _, rate = _delta_rate(ev_s, t, h, coef, par, tx, ty, tsl, tsr, period)
                if rate > 0.0:
                    ev_kind = EV_CONTACT
                    break
                # a grazing touch (δ reaches 0 without rising through it): look on after it
                s_from = ev_s + max(1e-12, 1e-14 / h)
                if s_from >= 1.0:
                    ev_s = -1.0
                    break
        else:
            dmin = dstage[12]
            dmax = dstage[12]
            amax_c = 0.0
            amax_m = 0.0
            for q in range(0, 13):
                if q > 0:
                    dmin = min(dmin, dstage[q])
                    dmax = max(dmax, dstage[q])
                amax_c = max(amax_c, abs(K[q, 1]))
                amax_m = max(amax_m, abs(K[q, 3]))
            # Between the stage times (largest gap 0.267·h) δ can leave the range of
            # the stage values by at most |δ''|max·gap²/8: scan only if that reaches a threshold.
            gap = 0.2667 * h
            slack = 1.5 * (amax_c + amax_m + v * v * par[P_C2MAX]) * gap * gap / 8.0
            if mode == ELASTIC:
                if dmin - slack <= 0.0:
                    s_l = _first_crossing_scan(1, t, h, coef, par, tx, ty, tsl, tsr, period, 16)
                    if s_l >= 0.0:
                        ev_s = s_l
                        ev_kind = EV_LOSS
                if int(par[P_LAW]) != HERTZ and dmax + slack > par[P_DY]:
                    s_y = _first_crossing_scan(2, t, h, coef, par, tx, ty, tsl, tsr, period, 16)
                    if s_y >= 0.0 and (ev_s < 0.0 or s_y < ev_s):
                        ev_s = s_y
                        ev_kind = EV_YIELD
            else:
                if dmin - slack < par[P_DY]:
                    s_u = _first_crossing_scan(3, t, h, coef, par, tx, ty, tsl, tsr, period, 16)
                    if s_u >= 0.0:
                        ev_s = s_u
                        ev_kind = EV_UNYIELD
        if ev_kind >= 0:
            # grazing test: the rate of δ at the root must point the right way
            _, rate = _delta_rate(ev_s, t, h, coef, par, tx, ty, tsl, tsr, period)
            if ev_kind == EV_LOSS and rate >= 0.0:
                ev_kind = -1
        hstep = h
        if ev_kind >= 0:
            hstep = ev_s * h
            if hstep > hmin_abs:
                # redo the step so that it ends exactly on the event
                for q in range(4):
                    K1[0, q] = K[0, q]
                _, hint = _rk_step(
                    t,
                    y,
                    hstep,
                    mode,
                    K1,
                    ynew,
                    dstage,
                    tmp,
                    par,
                    tx,
                    ty,
                    tsl,
                    tsr,
                    tscale,
                    period,
                    hint,
                )
                nrhs += 12
                for q in range(13):
                    for j in range(4):
                        K[q, j] = K1[q, j]
                j1c, j1m, hint = _jerks(
                    t + hstep, ynew, K[12, 3], mode, par, tx, ty, tsl, tsr, period, hint, True
                )
                _fill_dense(coef, hstep, y, K[0], j0c, j0m, ynew, K[12], j1c, j1m)
            else:
                hstep = 0.0
                for q in range(4):
                    ynew[q] = y[q]
                    K[12, q] = K[0, q]
                _fill_dense(coef, 1.0, y, K[0], j0c, j0m, ynew, K[12], j0c, j0m)
            hit_kink = False
        tn = t + hstep
        if hit_kink:
            tn = kinks[kp] / v
        d_b = 0.0
        r_b = 0.0
        # --- dense output: samples, extrema, dents
        while si < ns and sample_t[si] <= tn:
            ts = sample_t[si]
            s = (ts - t) / hstep if hstep > 0.0 else 0.0
            yc, vc, ym, vm = _dense(s, hstep, coef)
            ck, _, sc, hint = _constraint(tx, ty, tsl, tsr, tscale, period, v * ts, hint)
            d = -yc + ck + ym
            samples[si, S_T] = ts
            samples[si, S_X] = v * ts
            samples[si, S_YC] = yc
            samples[si, S_VC] = vc
            samples[si, S_YM] = ym
            samples[si, S_VM] = vm
            samples[si, S_YCK] = ck
            samples[si, S_DELTA] = d
            samples[si, S_FORCE] = _force(d, mode, par, sc)
            samples[si, S_CONTACT] = 1.0 if mode != FLIGHT else 0.0
            si += 1
        if mode == FLIGHT:
            t_flight += hstep
        elif hstep > 0.0:
            # δ and dδ/dt at the step's ends come from the states themselves
            ck_a, dck_a, hint = table_eval(tx, ty, tsl, tsr, period, v * t, hint)
            ck_b, dck_b, hint = table_eval(
                tx, ty, tsl, tsr, period, _before(v * (t + hstep), True), hint
            )
            d_a = -y[0] + ck_a + y[2]
            r_a = -y[1] + v * dck_a + y[3]
            d_b = -ynew[0] + ck_b + ynew[2]
            r_b = -ynew[1] + v * dck_b + ynew[3]
            peak_delta = max(peak_delta, d_a, d_b)
            min_delta = min(min_delta, d_a, d_b)
            if (r_a > 0.0 and r_b < 0.0) or (r_a < 0.0 and r_b > 0.0):
                # a local extremum of δ inside: Illinois on dδ/dt (δ is flat there, so
                # 1e-11 s in time is far below 1e-15 m in δ)
                sa = 0.0
                sb = 1.0
                ra = r_a
                rb = r_b
                side = 0
                sm = 0.5
                for _ in range(60):
                    sm = (sa * rb - sb * ra) / (rb - ra)
                    if not (sa < sm < sb):
                        sm = 0.5 * (sa + sb)
                    _, rm = _delta_rate(sm, t, hstep, coef, par, tx, ty, tsl, tsr, period)
                    if (rm > 0.0) == (ra > 0.0):
                        sa = sm
                        ra = rm
                        if side == 1:
                            rb *= 0.5
                        side = 1
                    else:
                        sb = sm
                        rb = rm
                        if side == -1:
                            ra *= 0.5
                        side = -1
                    if (sb - sa) * hstep < 1e-11 or abs(rm) * hstep < 1e-16:
                        break
                d_m, _ = _delta_rate(sm, t, hstep, coef, par, tx, ty, tsl, tsr, period)
                peak_delta = max(peak_delta, d_m)
                min_delta = min(min_delta, d_m)
                if not scaled or mode != ELASTIC:
                    f_m = _loading_force(d_m, par, 1.0)
                    peak_f = max(peak_f, f_m)
                    min_f = min(min_f, f_m)
            if not scaled or mode != ELASTIC:
                # F rises with δ in every mode and σ only scales the elastic branch: the
                # extrema of F are those of δ
                f_a = _loading_force(d_a, par, 1.0)
                f_b = _loading_force(d_b, par, 1.0)
                peak_f = max(peak_f, f_a, f_b)
                min_f = min(min_f, f_a, f_b)
            else:
                # F = σ(x)·C·δ^(3/2): its extrema are not those of δ; locate them on q
                f_a, q_a = _elastic_force_rate(
                    0.0, t, hstep, coef, par, tx, ty, tsl, tsr, tscale, period, False
                )
                f_b, q_b = _elastic_force_rate(
                    1.0, t, hstep, coef, par, tx, ty, tsl, tsr, tscale, period, True
                )
                peak_f = max(peak_f, f_a, f_b)
                min_f = min(min_f, f_a, f_b)
                if (q_a > 0.0 and q_b < 0.0) or (q_a < 0.0 and q_b > 0.0):
                    sa = 0.0
                    sb = 1.0
                    qa = q_a
                    qb = q_b
                    side = 0
                    sm = 0.5
                    for _ in range(60):
                        sm = (sa * qb - sb * qa) / (qb - qa)
                        if not (sa < sm < sb):
                            sm = 0.5 * (sa + sb)
                        _, qm = _elastic_force_rate(
                            sm, t, hstep, coef, par, tx, ty, tsl, tsr, tscale, period, False
                        )
                        if (qm > 0.0) == (qa > 0.0):
                            sa = sm
                            qa = qm
                            if side == 1:
                                qb *= 0.5
                            side = 1
                        else:
                            sb = sm
                            qb = qm
                            if side == -1:
                                qa *= 0.5
                            side = -1
                        if (sb - sa) * hstep < 1e-11:
                            break
                    f_m, _ = _elastic_force_rate(
                        sm, t, hstep, coef, par, tx, ty, tsl, tsr, tscale, period, False
                    )
                    peak_f = max(peak_f, f_m)
                    min_f = min(min_f, f_m)
            if mode == PLASTIC and track_dents:
                npts = math.ceil(v * hstep / dent_dx) + 1
                if n_dent + npts + 1 >= cap_dent:
                    cap_dent = 2 * (n_dent + npts + 1)
                    nd = np.empty((cap_dent, 3))
                    nd[:n_dent] = dents[:n_dent]
                    dents = nd
                for q in range(npts + 1):
                    s = q / npts
                    d_q, _ = _delta_rate(s, t, hstep, coef, par, tx, ty, tsl, tsr, period)
                    xq = v * (t + s * hstep)
                    xw, shift = wrap(xq, tx[0], period)
                    j = locate(tx, xw, hint)
                    if xw <= tx[0]:
                        xd = tcx[0] + (xw - tx[0])
                    elif xw >= tx[tx.size - 1]:
                        xd = tcx[tx.size - 1] + (xw - tx[tx.size - 1])
                    else:
                        u = (xw - tx[j]) / (tx[j + 1] - tx[j])
                        xd = tcx[j] + u * (tcx[j + 1] - tcx[j])
                    dents[n_dent, 0] = t + s * hstep
                    dents[n_dent, 1] = xd + shift
                    dents[n_dent, 2] = d_q
                    n_dent += 1
        # --- advance
        t = tn
        for q in range(4):
            y_prev[q] = y[q]
            y[q] = ynew[q]
        if hit_kink:
            kp += 1
        while kp < kinks.size and kinks[kp] <= v * t + 1e-15:
            kp += 1
        if ev_kind >= 0:
            if n_tr >= cap_tr:
                cap_tr *= 2
                nt = np.empty(cap_tr)
                nk = np.empty(cap_tr, dtype=np.int64)
                nt[:n_tr] = tr_t[:n_tr]
                nk[:n_tr] = tr_k[:n_tr]
                tr_t = nt
                tr_k = nk
            tr_t[n_tr] = t
            tr_k[n_tr] = ev_kind
            n_tr += 1
            # Put the state exactly on the new side of the switching surface: the step
            # that reached the event carries an error of ~rtol·|y| (1e-14 m), enough to
            # leave δ on the old side and fool the next scan at its very first instant.
            ck_e, hint = table_value(tx, ty, tsl, tsr, period, v * t, hint)
            if ev_kind == EV_LOSS:
                target = -EVENT_OFFSET
            elif ev_kind == EV_CONTACT:
                target = EVENT_OFFSET
            elif ev_kind == EV_YIELD:
                target = par[P_DY] + par[P_HYST] + EVENT_OFFSET
            else:
                target = par[P_DY] - par[P_HYST] - EVENT_OFFSET
            y[0] = ck_e + y[2] - target
            if ev_kind == EV_LOSS:
                mode = FLIGHT
                min_delta = min(min_delta, 0.0)
            elif ev_kind == EV_CONTACT:
                mode = ELASTIC
            elif ev_kind == EV_YIELD:
                mode = PLASTIC
            else:
                mode = ELASTIC
            ac, am, _, hint = _rhs(
                t, y[0], y[1], y[2], y[3], mode, par, tx, ty, tsl, tsr, tscale, period, hint
            )
            nrhs += 1
            K[0, 0] = y[1]
            K[0, 1] = ac
            K[0, 2] = y[3]
            K[0, 3] = am
            j0c, j0m, hint = _jerks(t, y, am, mode, par, tx, ty, tsl, tsr, period, hint, False)
            if ev_kind == EV_CONTACT:
                # Hertz impact duration ~ 2.87·(m²/(C²·v_impact))^(1/5) (Johnson, Contact
                # Mechanics §11.4): start with a small fraction of it.
                _, rate = _delta_rate(
                    1.0,
                    t - hstep,
                    hstep,
                    coef,
                    par,
                    tx,
                    ty,
                    tsl,
                    tsr,
                    period,
                )
                rate = max(abs(rate), 1e-6)
                tau = 2.87 * (par[P_MASS] ** 2 / (par[P_C] ** 2 * rate)) ** 0.2
                h = min(h, IMPACT_FIRST_STEP * tau)
            elif ev_kind == EV_LOSS and par[P_COMPLIANT] == 0.0:
                # ballistic flight: the parabola is exact, the scan finds the landing
                h = t1 - t
            else:
                h = max(h, 1e-9)
        else:
            for q in range(4):
                K[0, q] = K[12, q]
            if hit_kink:
                # the constraint's slope jumps here: the jerk does too
                j0c, j0m, hint = _jerks(
                    t, y, K[0, 3], mode, par, tx, ty, tsl, tsr, period, hint, False
                )
            else:
                j0c = j1c
                j0m = j1m
            h = h * factor
            if mode == ELASTIC and r_b < 0.0 and d_b > 0.0 and h * -r_b > d_b:
                # The next step would run past a loss of contact, where F ~ δ^(3/2) stops
                # being smooth: aim it just past the crossing predicted from δ and dδ/dt, so
                # that the step holding the event is accepted and then redone onto it.
                h = LOSS_AIM * d_b / -r_b
    stats = np.array([nsteps, nrej, nrhs], dtype=np.int64)
    extrema = np.array([peak_delta, min_delta, t_flight, t, float(mode), peak_f, min_f])
    return (
        status,
        samples,
        tr_t[:n_tr].copy(),
        tr_k[:n_tr].copy(),
        extrema,
        dents[:n_dent].copy(),
        stats,
        y,
    )
