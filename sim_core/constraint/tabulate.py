"""The exact rigid constraint y_C^k(x_C) of MODEL.md §2, tabulated for the integrator.

For a wheel outline r(θ) turned by φ = φ0 + x_C/R on a rail y_r(x):

    y_C^k(x_C) = max over ψ of [ y_r(x_C + ρ·sin ψ) + ρ·cos ψ ] - R,   ρ = r(ψ + φ)

(the height of the wheel centre relative to a round wheel on a flat rail).
The maximiser gives the contact point x_D = x_C + ρ·sin ψ. The result is a
:class:`~sim_core.constraint.table.ConstraintTable`: exact values and slopes on
nodes, cubic Hermite in between, and explicit kinks where the contact point
jumps (the wheel bridges a hollow, rolls on to a flat's corner, a concave rail
vertex, a step's corner).

How it is solved (all compiled with numba):

- *Round wheel on a polyline rail* (sampled or step rail): closed form. The
  constraint is the upper envelope of one circular arc per rail vertex
  (y_i + sqrt(R² - (x_i - x)²) - R) and one straight piece per segment of
  slope s (the wheel tangent to the segment: y_i + s(x - x_i) + R(sqrt(1+s²) - 1)).
  Nodes hold the active piece; every change of piece between two nodes is
  inserted as a node: tangent junctions (segment → its end vertex → next
  segment) in closed form, crossings of non-adjacent pieces (kinks) by
  bisection to the last bit. So the table is exact piecewise (arcs and lines).
- *An out-of-round wheel on a flat or cosine rail*: the piece sweep of
  :mod:`sim_core.constraint.wheel_pieces` (the outline cut into pieces with one
  smooth formula each, closed forms and Newton per piece, the changes of piece
  located as roots of closed forms). ``method="general"`` forces the ψ-search
  below instead (for cross-checks).
- *An out-of-round wheel on a sampled (measured, file, dented) rail*: the cell sweep of
  :mod:`sim_core.constraint.polyline` (each wheel piece against each rail segment and
  vertex: closed forms, or Newton on a unimodal piece; changes of contact located between
  nodes) inside the stretches where the out-of-roundness can reach the contact, and the
  round wheel's closed form below elsewhere, cut from a table of the whole rail that is
  made once per rail and radius and kept (wheel-independent). ``method="general"`` forces
  the ψ-search.
- *Any other pair*: a global search over a ψ grid finer than both inputs'
  features, in a window bounded by the height range (a wheel point at ψ can
  only win if ``rail max + wheel bulge - 2R·sin²(ψ/2)`` reaches the value at
  ψ = 0), then golden-section refinement of the best grid maxima on the
  continuous interpolated objective, split at every corner of either outline
  (rail vertices, wheel samples, a flat's ends), whose values are taken exactly. Slopes are central differences (±1e-8 m) of these re-optimised
  values. Kinks are found from jumps of the contact angle ψ between nodes and
  located by bisection to ~1e-13 m; intervals whose Hermite midpoint misses the
  exact value by more than 1e-13 m are split (this resolves C² breaks such as
  where a flat's corner starts to carry the wheel).

Periodic tables: a round wheel on a cosine (period λ) and any wheel on a flat
rail (period 2πR). Otherwise the table covers [x_start, x_end] plus a margin
of 10 mm + 2·dx on each side.

``resolution`` is the finest input feature: the rail's (sample spacing, λ/16)
and the wheel's (sample arc length, flat length/16), at most 10 mm. The default
node spacing ``dx`` is the resolution for the closed-form polyline case (its
pieces are exact between inserted nodes) capped at 1 mm, and half of it for the
general case capped at 2 mm.

Worked example (the paper's Fig. 3 reference): a round wheel (R = 0.475 m) on
a cosine rail a = 0.1 mm, λ = 5 cm reaches exactly ±a, and its fundamental is
0.93a (0.931), the 2nd harmonic 0.155a:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_constraint(WheelOutline.round(0.475), RailProfile.cosine(1e-4, 0.05), 0.0, 1.0)
    >>> t.period, round(float(t.y.max()) / 1e-4, 9), round(float(t.y.min()) / 1e-4, 9)
    (0.05, 1.0, -1.0)
    >>> amp = amplitude_spectrum(t, 0.0, 0.05, 2)
    >>> round(float(amp[1]) / 1e-4, 3), round(float(amp[2]) / 1e-4, 3)
    (0.931, 0.155)
"""

from __future__ import annotations

import math
import weakref

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.polyline import (
    RailPolyline,
    flat_zones,
    polyline_pieces,
    rail_polyline,
    supports_polyline,
    sweep_kernel,
)
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import N_K as PN_K
from sim_core.constraint.wheel_pieces import N_SL as PN_SL
from sim_core.constraint.wheel_pieces import N_SR as PN_SR
from sim_core.constraint.wheel_pieces import N_V as PN_V
from sim_core.constraint.wheel_pieces import N_X as PN_X
from sim_core.constraint.wheel_pieces import N_XD as PN_XD
from sim_core.constraint.wheel_pieces import supports as supports_pieces
from sim_core.constraint.wheel_pieces import tabulate_pieces
from sim_core.rail import RAIL_SAMPLED, RAIL_STEP, RailProfile, rail_height
from sim_core.wheel import (
    TWO_PI,
    WHEEL_IDEAL_FLAT,
    WHEEL_SAMPLED,
    WheelOutline,
    wheel_offset,
)

__all__ = [
    "amplitude_spectrum",
    "curvature_stiffness_scale",
    "evaluate_exact",
    "flat_constraint",
    "profile_constraint",
    "tabulate_constraint",
    "warm_up_constraint",
]

MAX_RESOLUTION = 0.01
"""Upper bound of a table's ``resolution`` (m) when the inputs have no finer feature."""

SLOPE_STEP = 1e-8
"""Half-width (m) of the central differences that give the general case's node slopes."""

HERMITE_TOL = 1e-13
"""Largest accepted miss (m) of the Hermite interpolant at an interval's midpoint (general case)."""

PSI_JUMP = 1e-7
"""Smallest jump of the contact angle ψ (rad) treated as a kink (general case)."""

KINK_SLOPE = 1e-7
"""Slope jumps at or below this are treated as round-off: no kink, the mean slope on both sides
(a Hermite error of at most ~h·1e-7/8 m if such a jump were real)."""

KINK_CURVATURE = 1e3
"""A second difference of y_C^k over ±SLOPE_STEP above this curvature (1/m) flags a kink."""

# node columns of the compiled tabulators
_X, _V, _SL, _SR, _XD, _PL, _PR, _GL, _GR, _K = range(10)
_NCOL = 10


# ======================================================================================
# general case: ψ search on the continuous interpolated objective
# ======================================================================================
@numba.njit(cache=True)
def _objective(
    x: float,
    psi: float,
    phi: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
    rp: NDArray[np.float64],
    rxs: NDArray[np.float64],
    rys: NDArray[np.float64],
) -> tuple[float, float]:
    """(y_r(x_D) + ρ cos ψ - R, x_D) without cancellation; wp = [code, R, a, b, bulge], rp = [code, a, b]."""
    R = wp[1]
    dr = wheel_offset(int(wp[0]), R, wp[2], wp[3], wth, wdr, psi + phi)
    s = math.sin(0.5 * psi)
    xd = x + (R + dr) * math.sin(psi)
    g = rail_height(int(rp[0]), rp[1], rp[2], rxs, rys, xd) + dr * math.cos(psi) - 2.0 * R * s * s
    return g, xd


@numba.njit(cache=True)
def _range_max(st: NDArray[np.float64], xs: NDArray[np.float64], x0: float, x1: float) -> float:
    """max of the samples covering [x0, x1] (sparse table ``st``, level k = max over 2^k samples)."""
    n = xs.size
    i0 = int(np.searchsorted(xs, x0)) - 1
    i1 = int(np.searchsorted(xs, x1))
    i0 = max(i0, 0)
    i1 = min(i1, n - 1)
    ln = i1 - i0 + 1
    k = 0
    while (1 << (k + 1)) <= ln:
        k += 1
    return max(st[k, i0], st[k, i1 - (1 << k) + 1])


@numba.njit(cache=True)
def _golden(
    x: float,
    lo: float,
    hi: float,
    phi: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
    rp: NDArray[np.float64],
    rxs: NDArray[np.float64],
    rys: NDArray[np.float64],
) -> tuple[float, float, float]:
    """Maximise the objective over ψ in [lo, hi]: golden section to 1e-8 rad, then a parabolic polish.

    Used on smooth pieces (between corners, see :func:`_refine`); a smooth maximum is polished by one parabola through ±1e-6 rad
    (its value is then exact to rounding).
    """
    invphi = 0.6180339887498949
    a, b = lo, hi
    c = b - invphi * (b - a)
    d = a + invphi * (b - a)
    gc, _ = _objective(x, c, phi, wp, wth, wdr, rp, rxs, rys)
    gd, _ = _objective(x, d, phi, wp, wth, wdr, rp, rxs, rys)
    while b - a > 1e-8:
        if gc >= gd:
            b, d, gd = d, c, gc
            c = b - invphi * (b - a)
            gc, _ = _objective(x, c, phi, wp, wth, wdr, rp, rxs, rys)
        else:
            a, c, gc = c, d, gd
            d = a + invphi * (b - a)
            gd, _ = _objective(x, d, phi, wp, wth, wdr, rp, rxs, rys)
    p = c if gc >= gd else d
    g, xd = _objective(x, p, phi, wp, wth, wdr, rp, rxs, rys)
    dl = 1e-6
    gm, _ = _objective(x, p - dl, phi, wp, wth, wdr, rp, rxs, rys)
    gp, _ = _objective(x, p + dl, phi, wp, wth, wdr, rp, rxs, rys)
    den = gp - 2.0 * g + gm
    if den < 0.0:
        q = p - 0.5 * dl * (gp - gm) / den
        if abs(q - p) < 2.0 * dl:
            gq, xq = _objective(x, q, phi, wp, wth, wdr, rp, rxs, rys)
            if gq > g:
                p, g, xd = q, gq, xq
    return p, g, xd


@numba.njit(cache=True)
def _vertex_psi(
    x: float,
    xv: float,
    psi: float,
    phi: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
) -> float:
    """ψ with x + ρ(ψ + φ)·sin ψ = xv (Newton from ψ): the wheel point over the rail vertex xv."""
    code = int(wp[0])
    R = wp[1]
    pc = psi
    for _ in range(6):
        dr = wheel_offset(code, R, wp[2], wp[3], wth, wdr, pc + phi)
        f = x + (R + dr) * math.sin(pc) - xv
        pc -= f / ((R + dr) * math.cos(pc))
    return pc


@numba.njit(cache=True)
def _refine(
    x: float,
    lo: float,
    hi: float,
    phi: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
    rp: NDArray[np.float64],
    rxs: NDArray[np.float64],
    rys: NDArray[np.float64],
) -> tuple[float, float, float]:
    """Maximise over ψ in [lo, hi] exactly: split at every corner of either outline inside
    (rail vertices, wheel samples, flat corners), evaluate the corners exactly, and
    golden-search each smooth piece between them."""
    code = int(wp[0])
    R = wp[1]
    rcode = int(rp[0])
    bp = np.empty(66)
    nb = 0
    bp[nb] = lo
    nb += 1
    # wheel corners
    if code == WHEEL_IDEAL_FLAT:
        for sgn in (-1.0, 1.0):
            t = sgn * wp[2] - phi
            t = t - TWO_PI * math.floor((t - lo) / TWO_PI)
            if lo < t < hi:
                bp[nb] = t
                nb += 1
    elif code == WHEEL_SAMPLED:
        n = wth.size
        t0 = lo + phi
        base = TWO_PI * math.floor((t0 - wth[0]) / TWO_PI)
        i = np.searchsorted(wth, t0 - base)
        for _ in range(n + 1):
            if nb >= 32:
                break
            tj = (wth[i % n] if i < n else wth[i - n] + TWO_PI) + base
            if i >= 2 * n:
                break
            pj = tj - phi
            if pj >= hi:
                break
            if pj > lo:
                bp[nb] = pj
                nb += 1
            i += 1
    # rail vertices
    if rcode in (RAIL_SAMPLED, RAIL_STEP):
        _, xlo = _objective(x, lo, phi, wp, wth, wdr, rp, rxs, rys)
        _, xhi = _objective(x, hi, phi, wp, wth, wdr, rp, rxs, rys)
        if rcode == RAIL_STEP:
            if xlo < rp[2] < xhi:
                bp[nb] = _vertex_psi(x, rp[2], 0.5 * (lo + hi), phi, wp, wth, wdr)
                nb += 1
        else:
            j = np.searchsorted(rxs, xlo, side="right")
            while j < rxs.size and rxs[j] < xhi and nb < 64:
                pj = lo + (hi - lo) * (rxs[j] - xlo) / (xhi - xlo)
                pv = _vertex_psi(x, rxs[j], pj, phi, wp, wth, wdr)
                if lo < pv < hi:
                    bp[nb] = pv
                    nb += 1
                j += 1
    bp[nb] = hi
    nb += 1
    pts = np.sort(bp[:nb])
    best_g = -np.inf
    best_p = lo
    best_x = x
    for k in range(nb):
        pk = pts[k]
        g, xd = _objective(x, pk, phi, wp, wth, wdr, rp, rxs, rys)
        if rcode == RAIL_STEP and abs(xd - rp[2]) < 1e-9:
            s = math.sin(0.5 * pk)
            dr = wheel_offset(code, R, wp[2], wp[3], wth, wdr, pk + phi)
            g = max(0.0, rp[1]) + dr * math.cos(pk) - 2.0 * R * s * s
        if g > best_g:
            best_g, best_p, best_x = g, pk, xd
        if k + 1 < nb and pts[k + 1] - pk > 1e-12:
            p, g, xd = _golden(x, pk, pts[k + 1], phi, wp, wth, wdr, rp, rxs, rys)
            if g > best_g:
                best_g, best_p, best_x = g, p, xd
    return best_p, best_g, best_x


@numba.njit(cache=True)
def _solve(
    x: float,
    phase: float,
    dpsi: float,
    gmax: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
    rp: NDArray[np.float64],
    rxs: NDArray[np.float64],
    rys: NDArray[np.float64],
    st: NDArray[np.float64],
) -> tuple[float, float, float]:
    """(y_C^k, ψ*, x_D) at wheel position x: windowed grid search, golden refinement, snap."""
    R = wp[1]
    bulge = wp[4]
    phi = phase + x / R
    g0, xd0 = _objective(x, 0.0, phi, wp, wth, wdr, rp, rxs, rys)
    # window: a point at ψ can only win if ymax + bulge - 2R sin²(ψ/2) >= g0
    ymax = gmax
    psimax = 0.0
    for it in range(2):
        s2 = (ymax + bulge - g0) / (2.0 * R)
        psimax = 2.0 * math.asin(math.sqrt(min(max(s2, 0.0), 1.0))) if s2 > 0.0 else 0.0
        psimax = min(psimax * 1.001 + dpsi, 1.2)
        if it == 0 and int(rp[0]) == RAIL_SAMPLED:
            w = (R + bulge) * math.sin(psimax)
            ymax = _range_max(st, rxs, x - w, x + w)
        else:
            break
    n = int(2.0 * psimax / dpsi) + 3
    if n < 5:
        n = 5
    h = 2.0 * psimax / (n - 1)
    # scan the grid, keep the 3 best local maxima
    kb = np.full(3, -np.inf)
    ki = np.full(3, -1, np.int64)
    gprev, _ = _objective(x, -psimax, phi, wp, wth, wdr, rp, rxs, rys)
    gcur, _ = _objective(x, -psimax + h, phi, wp, wth, wdr, rp, rxs, rys)
    if gprev >= gcur:
        kb[0] = gprev
        ki[0] = 0
    for i in range(1, n):
        if i + 1 < n:
            gnext, _ = _objective(x, -psimax + (i + 1) * h, phi, wp, wth, wdr, rp, rxs, rys)
        else:
            gnext = -np.inf
        if gcur >= gprev and gcur >= gnext:
            # insert into the top-3
            j = 2
            if gcur > kb[2]:
                while j > 0 and gcur > kb[j - 1]:
                    kb[j] = kb[j - 1]
                    ki[j] = ki[j - 1]
                    j -= 1
                kb[j] = gcur
                ki[j] = i
        gprev, gcur = gcur, gnext
    best_g = g0
    best_p = 0.0
    best_x = xd0
    # a local maximum can exceed its grid value by at most ~ |dG/dψ|·h
    margin = h * (R * (psimax + 0.2) + 10.0 * bulge + 1e-3)
    for j in range(3):
        if ki[j] < 0 or kb[j] < kb[0] - margin:
            continue
        lo = -psimax + max(ki[j] - 2, 0) * h
        hi = -psimax + min(ki[j] + 2, n - 1) * h
        p, g, xd = _refine(x, lo, hi, phi, wp, wth, wdr, rp, rxs, rys)
        gi = kb[j]
        if gi > g:
            p = -psimax + ki[j] * h
            g, xd = _objective(x, p, phi, wp, wth, wdr, rp, rxs, rys)
        if g > best_g:
            best_g, best_p, best_x = g, p, xd
    return best_g, best_p, best_x


@numba.njit(cache=True)
def _grow(a: NDArray[np.float64], n: int) -> NDArray[np.float64]:
    if n < a.shape[0]:
        return a
    b = np.empty((2 * a.shape[0] + 16, a.shape[1]))
    b[: a.shape[0]] = a
    return b


@numba.njit(cache=True)
def _jumpy(d1: float, d2: float) -> bool:
    dd = abs(d2 - d1)
    return dd > PSI_JUMP and dd > 0.5 * (abs(d1) + abs(d2))


@numba.njit(cache=True)
def _solve_t(x: float, args: tuple) -> tuple[float, float, float]:
    phase, dpsi, gmax, wp, wth, wdr, rp, rxs, rys, st = args
    return _solve(x, phase, dpsi, gmax, wp, wth, wdr, rp, rxs, rys, st)


@numba.njit(cache=True)
def _locate(
    lo: float, hi: float, plo: float, glo: float, phi_: float, ghi: float, args: tuple
) -> float:
    """Bisection for a kink in (lo, hi): classify ψ at the midpoint against the two branches."""
    xl, xh = lo, hi
    for _ in range(200):
        if xh - xl <= 1e-13 * max(1.0, abs(xl)):
            break
        m = 0.5 * (xl + xh)
        _, pm, _ = _solve_t(m, args)
        da = abs(pm - (plo + glo * (m - lo)))
        db = abs(pm - (phi_ + ghi * (m - hi)))
        if da <= db:
            xl = m
        else:
            xh = m
    return 0.5 * (xl + xh)


@numba.njit(cache=True)
def _kink_row(xk: float, args: tuple, out: NDArray[np.float64]) -> None:
    """A kink node at xk: one-sided second-order slopes and ψ-branches on both sides."""
    eps = SLOPE_STEP
    vk, _, _ = _solve_t(xk, args)
    vl1, pl1, _ = _solve_t(xk - eps, args)
    vl2, pl2, _ = _solve_t(xk - 2.0 * eps, args)
    vr1, pr1, xdr = _solve_t(xk + eps, args)
    vr2, pr2, _ = _solve_t(xk + 2.0 * eps, args)
    out[_X] = xk
    out[_V] = vk
    out[_SL] = (3.0 * vk - 4.0 * vl1 + vl2) / (2.0 * eps)
    out[_SR] = (-3.0 * vk + 4.0 * vr1 - vr2) / (2.0 * eps)
    out[_XD] = xdr
    out[_GL] = (pl1 - pl2) / eps
    out[_GR] = (pr2 - pr1) / eps
    out[_PL] = pl1 + out[_GL] * eps
    out[_PR] = pr1 - out[_GR] * eps
    out[_K] = 1.0


@numba.njit(cache=True)
def _make_node(
    xv: float, fixed: bool, args: tuple, row: NDArray[np.float64], row2: NDArray[np.float64]
) -> int:
    """Node(s) at xv into row (and row2, sorted by x); returns how many (1 or 2).

    Slopes are central differences; if the contact angle jumps within ±eps the
    kink is located and becomes the node (a fixed node stays and gets a
    one-sided slope, and the kink is a second node).
    """
    eps = SLOPE_STEP
    v0, p0, xd0 = _solve_t(xv, args)
    vm, pm, _ = _solve_t(xv - eps, args)
    vp, pp, _ = _solve_t(xv + eps, args)
    if not (_jumpy(p0 - pm, pp - p0) or abs(vm - 2.0 * v0 + vp) > KINK_CURVATURE * eps * eps):
        row[_X] = xv
        row[_V] = v0
        row[_SL] = (vp - vm) / (2.0 * eps)
        row[_SR] = row[_SL]
        row[_XD] = xd0
        row[_PL] = p0
        row[_PR] = p0
        row[_GL] = (pp - pm) / (2.0 * eps)
        row[_GR] = row[_GL]
        row[_K] = 0.0
        return 1
    xk = _locate(xv - eps, xv + eps, pm, 0.0, pp, 0.0, args)
    if not fixed or abs(xk - xv) < 1e-12 * max(1.0, abs(xv)):
        _kink_row(xv if fixed else xk, args, row)
        return 1
    side = -1.0 if xk > xv else 1.0
    v1, p1, _ = _solve_t(xv + side * eps, args)
    v2, _, _ = _solve_t(xv + 2.0 * side * eps, args)
    row[_X] = xv
    row[_V] = v0
    row[_SL] = side * (-3.0 * v0 + 4.0 * v1 - v2) / (2.0 * eps)
    row[_SR] = row[_SL]
    row[_XD] = xd0
    row[_PL] = p0
    row[_PR] = p0
    row[_GL] = side * (p1 - p0) / eps
    row[_GR] = row[_GL]
    row[_K] = 0.0
    _kink_row(xk, args, row2)
    if xk < xv:
        tmp = row.copy()
        row[:] = row2
        row2[:] = tmp
    return 2


@numba.njit(cache=True)
def _push(stack: NDArray[np.int64], ns: int, ia: int, ib: int) -> NDArray[np.int64]:
    if ns >= stack.shape[0]:
        s2 = np.empty((2 * stack.shape[0] + 16, 2), np.int64)
        s2[:ns] = stack[:ns]
        stack = s2
    stack[ns, 0] = ia
    stack[ns, 1] = ib
    return stack


@numba.njit(cache=True)
def _tabulate_general(
    x0: float,
    x1: float,
    nint: int,
    periodic: bool,
    args: tuple,
) -> NDArray[np.float64]:
    """Nodes (rows: x, y, slopes, x_D, ψ, dψ/dx, kink flag) of the general case, sorted by x."""
    eps = SLOPE_STEP
    nodes = np.empty((2 * nint + 64, _NCOL))
    nn = 0
    row = np.empty(_NCOL)
    row2 = np.empty(_NCOL)
    # ---------------------------------------------------------------- grid
    hgrid = (x1 - x0) / nint
    last = nint - 1 if periodic else nint
    for i in range(last + 1):
        xv = x0 + i * hgrid if i < nint else x1
        k = _make_node(xv, (i == 0) or (i == nint), args, row, row2)
        nodes = _grow(nodes, nn + 2)
        nodes[nn] = row
        nn += 1
        if k == 2:
            nodes[nn] = row2
            nn += 1
    if periodic:
        nodes = _grow(nodes, nn + 1)
        nodes[nn] = nodes[0]
        nodes[nn, _X] = x1
        nodes[nn, _XD] = nodes[0, _XD] + (x1 - x0)
        nn += 1
    # ---------------------------------------------------------------- refinement
    stack = np.empty((nn + 64, 2), np.int64)
    ns = 0
    for i in range(nn - 1):
        stack = _push(stack, ns, i, i + 1)
        ns += 1
    guard = 0
    while ns > 0 and guard < 20_000_000:
        guard += 1
        ns -= 1
        ia = stack[ns, 0]
        ib = stack[ns, 1]
        xa = nodes[ia, _X]
        xb = nodes[ib, _X]
        h = xb - xa
        scale = max(1.0, abs(xa))
        if h <= 4e-13 * scale:
            continue
        ea = abs(nodes[ib, _PL] - (nodes[ia, _PR] + nodes[ia, _GR] * h))
        eb = abs(nodes[ia, _PR] - (nodes[ib, _PL] - nodes[ib, _GL] * h))
        smooth = abs(nodes[ib, _GL] - nodes[ia, _GR]) * h + PSI_JUMP
        have = False
        if min(ea, eb) > smooth:
            # the contact point jumps inside: locate the kink, or find a third branch
            lo, hi = xa, xb
            third = math.nan
            if h > 8.0 * eps:
                for _ in range(200):
                    if hi - lo <= 1e-13 * scale:
                        break
                    m = 0.5 * (lo + hi)
                    _, pm, _ = _solve_t(m, args)
                    pa = nodes[ia, _PR] + nodes[ia, _GR] * (m - xa)
                    pb = nodes[ib, _PL] + nodes[ib, _GL] * (m - xb)
                    da = abs(pm - pa)
                    db = abs(pm - pb)
                    if (
                        min(da, db) > max(0.25 * abs(pa - pb), PSI_JUMP)
                        and m - xa > 4.0 * eps
                        and xb - m > 4.0 * eps
                    ):
                        third = m
                        break
                    if da <= db:
                        lo = m
                    else:
                        hi = m
            else:
                lo = _locate(
                    xa, xb, nodes[ia, _PR], nodes[ia, _GR], nodes[ib, _PL], nodes[ib, _GL], args
                )
                hi = lo
            if not math.isnan(third):
                k = _make_node(third, False, args, row, row2)
            else:
                _kink_row(0.5 * (lo + hi), args, row)
                k = 1
            have = True
        elif h > 4.0 * eps:
            m = 0.5 * (xa + xb)
            vm, _, _ = _solve_t(m, args)
            hm = 0.5 * (nodes[ia, _V] + nodes[ib, _V]) + 0.125 * h * (
                nodes[ia, _SR] - nodes[ib, _SL]
            )
            if abs(vm - hm) > HERMITE_TOL:
                k = _make_node(m, False, args, row, row2)
                have = True
        if not have:
            continue
        if not (xa < row[_X] < xb):
            continue
        nodes = _grow(nodes, nn + 2)
        nodes[nn] = row
        ic = nn
        nn += 1
        if k == 2 and xa < row2[_X] < xb:
            nodes[nn] = row2
            id2 = nn
            nn += 1
            stack = _push(stack, ns, ia, ic)
            ns += 1
            stack = _push(stack, ns, ic, id2)
            ns += 1
            stack = _push(stack, ns, id2, ib)
            ns += 1
        else:
            stack = _push(stack, ns, ia, ic)
            ns += 1
            stack = _push(stack, ns, ic, ib)
            ns += 1
    out = nodes[:nn]
    order = np.argsort(out[:, _X], kind="mergesort")
    return out[order]


# ======================================================================================
# round wheel on a polyline: closed form
# ======================================================================================
@numba.njit(cache=True)
def _piece(
    pid: int, x: float, R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> tuple[float, float, float]:
    """(value, slope, x_D) of piece ``pid`` (2k: arc of vertex k, 2k+1: line of segment k)."""
    k = pid >> 1
    if pid & 1 == 0:
        u = vx[k] - x
        if abs(u) >= R:
            return -np.inf, 0.0, vx[k]
        sq = math.sqrt(R * R - u * u)
        return vy[k] - u * u / (R + sq), u / sq, vx[k]
    dxs = vx[k + 1] - vx[k]
    if dxs <= 0.0:
        return -np.inf, 0.0, vx[k]
    s = (vy[k + 1] - vy[k]) / dxs
    c = math.sqrt(1.0 + s * s)
    return R * s * s / (c + 1.0) + vy[k] + s * (x - vx[k]), s, x + s * R / c


@numba.njit(cache=True)
def _poly_solve(
    x: float,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    bmax: NDArray[np.float64],
    B: int,
    gmax: float,
) -> tuple[float, int]:
    """(y_C^k, active piece) of a round wheel on the polyline (vx, vy) at wheel position x."""
    n = vx.size
    j = int(np.searchsorted(vx, x, side="right")) - 1
    j = min(max(j, 0), n - 2)
    best = -np.inf
    bp = -1
    # segment under the wheel centre
    v, _, xd = _piece(2 * j + 1, x, R, vx, vy)
    if vx[j] <= xd <= vx[j + 1] and v > best:
        best, bp = v, 2 * j + 1
    # scan right: vertex k, then segment k
    k = j + 1
    while k < n:
        u = vx[k] - x
        if u >= R:
            break
        drop = u * u / (R + math.sqrt(R * R - u * u))
        if gmax - drop < best:
            break
        b = k // B
        if (k == j + 1 or k % B == 0) and bmax[b] - drop < best:
            k = (b + 1) * B
            continue
        v, _, _ = _piece(2 * k, x, R, vx, vy)
        if v > best:
            best, bp = v, 2 * k
        if k < n - 1:
            v, _, xd = _piece(2 * k + 1, x, R, vx, vy)
            if vx[k] <= xd <= vx[k + 1] and v > best:
                best, bp = v, 2 * k + 1
        k += 1
    # scan left: vertex k, then segment k-1
    k = j
    while k >= 0:
        u = x - vx[k]
        if u >= R:
            break
        drop = u * u / (R + math.sqrt(R * R - u * u))
        if gmax - drop < best:
            break
        b = k // B
        if (k == j or k % B == B - 1) and bmax[b] - drop < best:
            k = b * B - 1
            continue
        v, _, _ = _piece(2 * k, x, R, vx, vy)
        if v > best:
            best, bp = v, 2 * k
        if k >= 1:
            v, _, xd = _piece(2 * k - 1, x, R, vx, vy)
            if vx[k - 1] <= xd <= vx[k] and v > best:
                best, bp = v, 2 * k - 1
        k -= 1
    return best, bp


@numba.njit(cache=True)
def _eff(pid: int, x: float, R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]) -> int:
    """The piece a closed segment really contributes at x: itself, or the end vertex nearer its tangent point."""
    if pid & 1 == 0:
        return pid
    k = pid >> 1
    _, _, p = _piece(pid, x, R, vx, vy)
    if p < vx[k]:
        return 2 * k
    if p > vx[k + 1]:
        return 2 * k + 2
    return pid


@numba.njit(cache=True)
def _crossing(
    a: float, b: float, pa: int, pb: int, R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> float:
    """Where piece pb overtakes pa in [a, b] (bisection to the last bit)."""
    lo, hi = a, b
    for _ in range(200):
        m = 0.5 * (lo + hi)
        if m <= lo or m >= hi:
            break
        va, _, _ = _piece(_eff(pa, m, R, vx, vy), m, R, vx, vy)
        vb, _, _ = _piece(_eff(pb, m, R, vx, vy), m, R, vx, vy)
        if va >= vb:
            lo = m
        else:
            hi = m
    return 0.5 * (lo + hi)


@numba.njit(cache=True)
def _block_max(vy: NDArray[np.float64], B: int) -> NDArray[np.float64]:
    """Highest vertex of each block of ``B`` vertices, the neighbours' shared ends included
    (the bound that lets the polyline solve skip whole blocks)."""
    n = vy.size
    nb = (n + B - 1) // B + 1
    bmax = np.full(nb, -np.inf)
    for k in range(n):
        b = k // B
        bmax[b] = max(bmax[b], vy[k])
        if k % B == 0 and b > 0:
            bmax[b - 1] = max(bmax[b - 1], vy[k])
        if k % B == B - 1 and b + 1 < nb:
            bmax[b + 1] = max(bmax[b + 1], vy[k])
    return bmax


@numba.njit(cache=True)
def _tabulate_poly(
    x0: float,
    x1: float,
    nint: int,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    B: int,
) -> NDArray[np.float64]:
    """Nodes of a round wheel on a polyline: grid nodes plus every change of active piece."""
    bmax = _block_max(vy, B)
    gmax = vy.max()
    nodes = np.empty((4 * nint + 64, _NCOL))
    nn = 0
    h = (x1 - x0) / nint
    # task stack: (kind, xa, xb, pa, pb, xnode, sl, sr, kink); kind 0 = interval, 1 = emit node
    tf = np.empty((256, 5))
    ti = np.empty((256, 3), np.int64)
    xprev = x0
    vprev, pprev = _poly_solve(x0, R, vx, vy, bmax, B, gmax)
    for i in range(nint + 1):
        xv = x0 + i * h if i < nint else x1
        if i == 0:
            v, p = vprev, pprev
        else:
            v, p = _poly_solve(xv, R, vx, vy, bmax, B, gmax)
            # resolve the changes of piece in (xprev, xv)
            nt = 0
            tf[0, 0] = xprev
            tf[0, 1] = xv
            ti[0, 0] = 0
            ti[0, 1] = pprev
            ti[0, 2] = p
            nt = 1
            budget = 100_000
            while nt > 0 and budget > 0:
                budget -= 1
                nt -= 1
                kind = ti[nt, 0]
                if kind == 1:
                    nodes = _grow(nodes, nn + 1)
                    xn = tf[nt, 0]
                    if nn > 0 and xn - nodes[nn - 1, _X] <= 1e-13 * max(1.0, abs(xn)):
                        nodes[nn - 1, _SR] = tf[nt, 3]
                        nodes[nn - 1, _XD] = tf[nt, 2]
                        nodes[nn - 1, _K] = max(nodes[nn - 1, _K], tf[nt, 4])
                    else:
                        nodes[nn, _X] = xn
                        nodes[nn, _V] = tf[nt, 1]
                        nodes[nn, _SL] = _piece(ti[nt, 1], xn, R, vx, vy)[1]
                        nodes[nn, _SR] = tf[nt, 3]
                        nodes[nn, _XD] = tf[nt, 2]
                        nodes[nn, _K] = tf[nt, 4]
                        nn += 1
                    continue
                a = tf[nt, 0]
                b = tf[nt, 1]
                pa = ti[nt, 1]
                pb = ti[nt, 2]
                if pa == pb or pa < 0 or pb < 0:
                    continue
                ka, kb = pa >> 1, pb >> 1
                c1 = False
                via = -1
                if (pa & 1) == 1 and (pb & 1) == 0 and kb == ka + 1:
                    _, s, _ = _piece(pa, a, R, vx, vy)
                    xs = vx[kb] - s * R / math.sqrt(1.0 + s * s)
                    c1 = True
                elif (pa & 1) == 0 and (pb & 1) == 1 and kb == ka:
                    _, s, _ = _piece(pb, a, R, vx, vy)
                    xs = vx[ka] - s * R / math.sqrt(1.0 + s * s)
                    c1 = True
                elif (pa & 1) == 1 and (pb & 1) == 1 and kb == ka + 1:
                    _, sa, _ = _piece(pa, a, R, vx, vy)
                    _, sb, _ = _piece(pb, a, R, vx, vy)
                    if sb <= sa:  # convex vertex kb between: its arc joins the two lines
                        xs = vx[kb] - sa * R / math.sqrt(1.0 + sa * sa)
                        via = 2 * kb
                        c1 = True
                    else:
                        xs = _crossing(a, b, pa, pb, R, vx, vy)
                else:
                    xs = _crossing(a, b, pa, pb, R, vx, vy)
                xs = min(max(xs, a), b)
                vc, pc = _poly_solve(xs, R, vx, vy, bmax, B, gmax)
                target = pb if via < 0 else via
                if c1:  # closed-form junction: the pieces are exactly these
                    ea, eb = pa, target
                else:
                    ea = _eff(pa, xs, R, vx, vy)
                    eb = _eff(target, xs, R, vx, vy)
                va, _, _ = _piece(ea, xs, R, vx, vy)
                vb, srb, xdb = _piece(eb, xs, R, vx, vy)
                top = max(va, vb)
                if nt + 4 >= tf.shape[0]:
                    tf2 = np.empty((2 * tf.shape[0], 5))
                    ti2 = np.empty((2 * tf.shape[0], 3), np.int64)
                    tf2[:nt] = tf[:nt]
                    ti2[:nt] = ti[:nt]
                    tf, ti = tf2, ti2
                if vc > top + 1e-15 and pc != pa and pc != target and pc != ea and pc != eb:
                    # a third piece is on top at xs: split there (pop order: left, node, right)
                    _, slc, xdc = _piece(pc, xs, R, vx, vy)
                    tf[nt, 0] = xs
                    tf[nt, 1] = b
                    ti[nt, 0] = 0
                    ti[nt, 1] = pc
                    ti[nt, 2] = pb
                    tf[nt + 1, 0] = xs
                    tf[nt + 1, 1] = vc
                    tf[nt + 1, 2] = xdc
                    tf[nt + 1, 3] = slc
                    tf[nt + 1, 4] = 0.0
                    ti[nt + 1, 0] = 1
                    ti[nt + 1, 1] = pc
                    tf[nt + 2, 0] = a
                    tf[nt + 2, 1] = xs
                    ti[nt + 2, 0] = 0
                    ti[nt + 2, 1] = pa
                    ti[nt + 2, 2] = pc
                    nt += 3
                    continue
                # the transition node, with what remains on either side of it
                if via >= 0:
                    tf[nt, 0] = xs
                    tf[nt, 1] = b
                    ti[nt, 0] = 0
                    ti[nt, 1] = via
                    ti[nt, 2] = pb
                    nt += 1
                elif eb != pb:
                    tf[nt, 0] = xs
                    tf[nt, 1] = b
                    ti[nt, 0] = 0
                    ti[nt, 1] = eb
                    ti[nt, 2] = pb
                    nt += 1
                tf[nt, 0] = xs
                tf[nt, 1] = top
                tf[nt, 2] = xdb
                tf[nt, 3] = srb
                tf[nt, 4] = 0.0 if c1 else 1.0
                ti[nt, 0] = 1
                ti[nt, 1] = ea
                nt += 1
                if ea != pa:
                    tf[nt, 0] = a
                    tf[nt, 1] = xs
                    ti[nt, 0] = 0
                    ti[nt, 1] = pa
                    ti[nt, 2] = ea
                    nt += 1
        # the grid node itself
        nodes = _grow(nodes, nn + 1)
        _, sl, xd = _piece(p, xv, R, vx, vy)
        if nn > 0 and xv - nodes[nn - 1, _X] <= 1e-13 * max(1.0, abs(xv)):
            nodes[nn - 1, _X] = xv
            nodes[nn - 1, _SR] = sl
            nodes[nn - 1, _XD] = xd
        else:
            nodes[nn, _X] = xv
            nodes[nn, _V] = v
            nodes[nn, _SL] = sl
            nodes[nn, _SR] = sl
            nodes[nn, _XD] = xd
            nodes[nn, _K] = 0.0
            nn += 1
        xprev, pprev = xv, p
    return nodes[:nn]


# ======================================================================================
# public API
# ======================================================================================
def _check_range(x_start: float, x_end: float) -> tuple[float, float]:
    a, b = float(x_start), float(x_end)
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(
            f"constraint: x_start and x_end must be finite, got {x_start!r}, {x_end!r}"
        )
    if not b > a:
        raise ValueError(f"constraint: x_end must exceed x_start, got x_start={a!r}, x_end={b!r}")
    return a, b


def _resolution(wheel: WheelOutline, rail: RailProfile) -> float:
    return min(rail.min_feature_length, wheel.min_feature_length, MAX_RESOLUTION)


def flat_constraint(period: float = 1.0, resolution: float = MAX_RESOLUTION) -> ConstraintTable:
    """y_C^k ≡ 0: a round wheel on a flat rail (periodic, contact point under the centre).

    >>> t = flat_constraint()
    >>> float(t.evaluate(np.array([123.4]))[0]), t.kinks.size
    (0.0, 0)
    """
    x = np.array([0.0, float(period)])
    z = np.zeros(2)
    return ConstraintTable(
        x=x,
        y=z,
        slope_left=z.copy(),
        slope_right=z.copy(),
        contact_x=x.copy(),
        kinks=np.empty(0),
        period=float(period),
        resolution=float(resolution),
    )


def _table_from_nodes(
    nodes: NDArray[np.float64], period: float, resolution: float, dx: float
) -> ConstraintTable:
    nodes = _merge_close(nodes)
    # a slope jump below KINK_SLOPE is round-off, not a kink: make the node smooth
    tiny = np.abs(nodes[:, _SL] - nodes[:, _SR]) <= KINK_SLOPE
    mean = 0.5 * (nodes[:, _SL] + nodes[:, _SR])
    nodes[tiny, _SL] = mean[tiny]
    nodes[tiny, _SR] = mean[tiny]
    kink = (nodes[:, _K] > 0) & ~tiny
    if period > 0:
        nodes[-1, _X] = nodes[0, _X] + period
        kink[-1] = False
    return ConstraintTable(
        x=nodes[:, _X].copy(),
        y=nodes[:, _V].copy(),
        slope_left=nodes[:, _SL].copy(),
        slope_right=nodes[:, _SR].copy(),
        contact_x=nodes[:, _XD].copy(),
        kinks=nodes[kink, _X].copy(),
        period=float(period),
        resolution=float(resolution),
        meta={"dx": float(dx), "nodes": float(nodes.shape[0])},
    )


@numba.njit(cache=True)
def _merge_close(nodes: NDArray[np.float64]) -> NDArray[np.float64]:
    """Nodes closer than the position round-off merged (the left slope of the first, the
    right slope and contact point of the last, a kink if any was one)."""
    n = nodes.shape[0]
    out = np.empty_like(nodes)
    m = 0
    for i in range(n):
        xi = nodes[i, _X]
        if m > 0 and xi - nodes[i - 1, _X] <= 1e-13 * max(1.0, abs(xi)):
            out[m - 1, _SR] = nodes[i, _SR]
            out[m - 1, _XD] = nodes[i, _XD]
            out[m - 1, _K] = max(out[m - 1, _K], nodes[i, _K])
            continue
        out[m] = nodes[i]
        m += 1
    return out[:m]


def _general_args(
    wheel: WheelOutline, rail: RailProfile
) -> tuple[
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.float64],
    float,
]:
    code, R, a, b, th, dr = wheel.compiled_args()
    wp = np.array([float(code), R, a, b, wheel.max_excess])
    rcode, ra, rb, rxs, rys = rail.compiled_args()
    rp = np.array([float(rcode), ra, rb])
    if rcode == RAIL_SAMPLED:
        levels = [rys]
        k = 1
        while (1 << k) <= rys.size:
            prev = levels[-1]
            half = 1 << (k - 1)
            nxt = prev.copy()
            nxt[: rys.size - half] = np.maximum(prev[: rys.size - half], prev[half:])
            levels.append(nxt)
            k += 1
        st = np.vstack(levels)
    else:
        st = np.zeros((1, 1))
    gmax = rail.height_range[1]
    return wp, th, dr, rp, rxs, rys, st, gmax


def _dpsi(wheel: WheelOutline, rail: RailProfile) -> float:
    R = wheel.nominal_radius
    feat = min(rail.min_feature_length, wheel.min_feature_length)
    if wheel.kind == "ideal_flat":
        feat = min(feat, wheel.flat_length / 16.0)
    return min(0.25 * feat / R, 0.01)


def evaluate_exact(
    wheel: WheelOutline, rail: RailProfile, x: NDArray[np.float64], *, phase: float = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(y_C^k, x_D) solved directly (no table) at the wheel positions ``x`` (m).

    The general ψ-search of this module, for checks and for isolated points.

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> y, xd = evaluate_exact(WheelOutline.round(0.475), RailProfile.step(1e-3, 0.0), np.array([0.0]))
    >>> round(float(y[0]) * 1e3, 9), float(xd[0])
    (1.0, 0.0)
    """
    xq = np.asarray(x, dtype=np.float64)
    wp, th, dr, rp, rxs, rys, st, gmax = _general_args(wheel, rail)
    dpsi = _dpsi(wheel, rail)
    y = np.empty(xq.shape)
    xd = np.empty(xq.shape)
    _solve_many(
        xq.ravel(),
        float(phase),
        dpsi,
        gmax,
        wp,
        th,
        dr,
        rp,
        rxs,
        rys,
        st,
        y.reshape(-1),
        xd.reshape(-1),
    )
    return y, xd


@numba.njit(cache=True)
def _solve_many(
    xq: NDArray[np.float64],
    phase: float,
    dpsi: float,
    gmax: float,
    wp: NDArray[np.float64],
    wth: NDArray[np.float64],
    wdr: NDArray[np.float64],
    rp: NDArray[np.float64],
    rxs: NDArray[np.float64],
    rys: NDArray[np.float64],
    st: NDArray[np.float64],
    y: NDArray[np.float64],
    xd: NDArray[np.float64],
) -> None:
    for i in range(xq.size):
        v, _, d = _solve(xq[i], phase, dpsi, gmax, wp, wth, wdr, rp, rxs, rys, st)
        y[i] = v
        xd[i] = d


def _polyline(
    rail: RailProfile, lo: float, hi: float, R: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Vertices of a sampled or step rail, extended flat to cover [lo - 2R, hi + 2R]."""
    if rail.kind == "step":
        p, hgt = rail.step_position, rail.step_height
        vx = np.array([min(lo, p) - 2 * R, p, p, max(hi, p) + 2 * R])
        vy = np.array([0.0, 0.0, hgt, hgt])
        return vx, vy
    vx = np.concatenate(([min(lo, rail.x[0]) - 2 * R], rail.x, [max(hi, rail.x[-1]) + 2 * R]))
    vy = np.concatenate(([rail.y[0]], rail.y, [rail.y[-1]]))
    return vx, vy


def _ideal_flat_on_flat(
    wheel: WheelOutline, x0: float, phase: float, step: float, resolution: float
) -> ConstraintTable:
    """Closed form for an ideal flat on a flat rail, over one turn from x0.

    With φ wrapped to [-π, π): y_C^k = R·cos(θ0 - |φ|) - R = -2R·sin²((θ0 - |φ|)/2)
    for |φ| < θ0 (the wheel rests on the flat's corner nearer the bottom), else 0.
    """
    R = wheel.nominal_radius
    th0 = wheel.flat_half_angle
    P = TWO_PI * R
    n = max(math.ceil(P / step), 8)
    special = []
    for phi_s in (0.0, -th0, th0):  # kink at the centre, C² breaks at the corners
        xs = R * (phi_s - phase)
        xs = x0 + ((xs - x0) % P)
        special.append(xs)
    x = np.unique(np.concatenate((x0 + P * np.arange(n) / n, special)))
    x = x[x < x0 + P]
    x = x[np.concatenate(([True], np.diff(x) > 1e-12))]
    x = np.append(x, x0 + P)
    phi = phase + x / R
    phw = phi - TWO_PI * np.floor((phi + math.pi) / TWO_PI)
    # snap the special points onto their exact phase (x carries round-off)
    kink_i = int(np.argmin(np.abs(np.minimum(np.abs(x - special[0]), np.abs(x - special[0] - P)))))
    on = np.abs(phw) < th0
    u = th0 - np.abs(phw)
    su = np.sin(0.5 * u)
    y = np.where(on, -2.0 * R * su * su, 0.0)
    sgn = np.sign(phw)
    slope = np.where(on, sgn * np.sin(u), 0.0)
    xd = np.where(on, x + sgn * R * np.sin(u), x)
    sl = slope.copy()
    sr = slope.copy()
    y[kink_i] = -2.0 * R * math.sin(0.5 * th0) ** 2
    sl[kink_i] = -math.sin(th0)
    sr[kink_i] = math.sin(th0)
    xd[kink_i] = x[kink_i] + R * math.sin(th0)
    y[-1], sl[-1], sr[-1] = y[0], sl[0], sr[0]
    xd[-1] = xd[0] + P
    return ConstraintTable(
        x=x,
        y=y,
        slope_left=sl,
        slope_right=sr,
        contact_x=xd,
        kinks=np.array([x[kink_i] if kink_i < x.size - 1 else x[0]]),
        period=P,
        resolution=resolution,
        meta={"dx": float(step), "nodes": float(x.size)},
    )


def tabulate_constraint(
    wheel: WheelOutline,
    rail: RailProfile,
    x_start: float,
    x_end: float,
    *,
    phase: float = 0.0,
    dx: float | None = None,
    method: str = "auto",
) -> ConstraintTable:
    """The exact rigid constraint y_C^k of ``wheel`` on ``rail`` as a table.

    Args:
        wheel, rail: the geometry (MODEL.md §2).
        x_start, x_end: the stretch of wheel-centre positions x_C needed (m);
            non-periodic tables add a margin of 10 mm + 2·dx on both sides.
        phase: φ0 (rad): the wheel has turned by φ0 + x_C/R.
        dx: node spacing (m); default from the resolution (module docstring).
        method: ``"auto"``; ``"general"`` forces the ψ-search even where the
            closed form applies (for cross-checks).

    Worked example: an ideal flat of 61.6 mm on a flat rail lifts the wheel
    centre to R·cos(θ0 - |φ|) - R around φ = 0, with a kink at the flat's centre:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_constraint(WheelOutline.ideal_flat(0.475, 0.0616), RailProfile.flat(), 0.0, 6.0)
    >>> round(t.period, 6), t.kinks.tolist(), round(float(t.y.min()) * 1e3, 4)
    (2.984513, [0.0], -0.9996)
    """
    a, b = _check_range(x_start, x_end)
    if not math.isfinite(phase):
        raise ValueError(f"constraint: phase must be finite (rad), got {phase!r}")
    if method not in ("auto", "general"):
        raise ValueError(f"constraint: method must be 'auto' or 'general', got {method!r}")
    R = wheel.nominal_radius
    resolution = _resolution(wheel, rail)
    if dx is not None and not (math.isfinite(dx) and dx > 0):
        raise ValueError(f"constraint: dx must be a positive finite length (m), got {dx!r}")
    lo_h, hi_h = rail.height_range
    if (hi_h - lo_h) + wheel.max_depth + wheel.max_excess > 0.2 * R:
        raise ValueError(
            f"constraint: rail height range {hi_h - lo_h!r} m plus wheel out-of-roundness "
            f"{wheel.max_depth + wheel.max_excess!r} m is not small against R = {R!r} m"
        )
    polyline = wheel.kind == "round" and rail.kind in ("sampled", "step") and method == "auto"
    if wheel.kind == "round" and rail.kind == "flat" and method == "auto":
        return flat_constraint(period=TWO_PI * R, resolution=resolution)
    if wheel.kind == "ideal_flat" and rail.kind == "flat" and method == "auto":
        step = float(dx) if dx is not None else min(0.25 * resolution, 1e-3)
        return _ideal_flat_on_flat(wheel, a, float(phase), step, resolution)
    if method == "auto" and supports_pieces(wheel, rail):
        return _tabulate_wheel_pieces(wheel, rail, a, b, float(phase), dx, resolution)
    if method == "auto" and supports_polyline(wheel, rail):
        return _tabulate_polyline(wheel, rail, a, b, float(phase), dx, resolution)
    if polyline:
        step = float(dx) if dx is not None else min(resolution, 1e-3)
    else:
        step = float(dx) if dx is not None else min(0.5 * resolution, 2e-3)
    periodic = 0.0
    if rail.kind == "flat":
        periodic = TWO_PI * R
    elif rail.kind == "cosine" and wheel.kind == "round":
        periodic = rail.wavelength
    if periodic > 0:
        x0, x1 = a, a + periodic
    else:
        margin = 0.01 + 2.0 * step
        x0, x1 = a - margin, b + margin
    nint = max(math.ceil((x1 - x0) / step), 4 if periodic else 2)
    if polyline:
        vx, vy = _polyline(rail, x0, x1, R)
        nodes = _tabulate_poly(x0, x1, nint, R, vx, vy, 16)
    else:
        wp, th, dr, rp, rxs, rys, st, gmax = _general_args(wheel, rail)
        args = (float(phase), _dpsi(wheel, rail), gmax, wp, th, dr, rp, rxs, rys, st)
        nodes = _tabulate_general(x0, x1, nint, periodic > 0, args)
    return _table_from_nodes(nodes, periodic, resolution, step)


def _tabulate_wheel_pieces(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
) -> ConstraintTable:
    """An out-of-round wheel on a flat or cosine rail by the piece sweep (sim_core.constraint.wheel_pieces)."""
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(resolution, 2e-3)
    periodic = TWO_PI * R if rail.kind == "flat" else 0.0
    if periodic > 0:
        x0, x1 = a, a + periodic
    else:
        margin = 0.01 + 2.0 * step
        x0, x1 = a - margin, b + margin
    nint = max(math.ceil((x1 - x0) / step), 4)
    pn = tabulate_pieces(wheel, rail, x0, x1, nint, phase, HERMITE_TOL)
    nodes = np.zeros((pn.shape[0], _NCOL))
    nodes[:, _X] = pn[:, PN_X]
    nodes[:, _V] = pn[:, PN_V]
    nodes[:, _SL] = pn[:, PN_SL]
    nodes[:, _SR] = pn[:, PN_SR]
    nodes[:, _XD] = pn[:, PN_XD]
    nodes[:, _K] = pn[:, PN_K]
    if periodic > 0:
        # both ends are the same point: the left slope comes from the last node, the right from the first
        nodes[0, _SL] = nodes[-1, _SL]
        nodes[-1, _SR] = nodes[0, _SR]
        nodes[0, _K] = max(nodes[0, _K], nodes[-1, _K])
    return _table_from_nodes(nodes, periodic, resolution, step)


_ROUND_CACHE: dict[
    tuple[int, float, float], tuple[weakref.ref[RailProfile], float, float, NDArray[np.float64]]
] = {}


def _round_nodes(
    rail: RailProfile, poly: RailPolyline, R: float, step: float, x0: float, x1: float
) -> NDArray[np.float64]:
    """The round wheel's table (radius R) on the whole sampled rail, made once per rail and R.

    Wheel-independent: every out-of-round wheel of radius R on this rail takes its nodes
    outside its flat zones from here (cut exactly at the zone ends by :func:`_poly_points`).
    """
    key = (id(rail), float(R), float(step))
    hit = _ROUND_CACHE.get(key)
    if hit is not None and hit[0]() is rail and hit[1] <= x0 and hit[2] >= x1:
        return hit[3]
    lo = min(x0, float(rail.x[0]) - 0.05)
    hi = max(x1, float(rail.x[-1]) + 0.05)
    nodes = _merge_close(
        _tabulate_poly(lo, hi, max(math.ceil((hi - lo) / step), 2), R, poly.vx, poly.vy, 16)
    )
    for k in [k for k, v in _ROUND_CACHE.items() if v[0]() is None]:
        del _ROUND_CACHE[k]
    while len(_ROUND_CACHE) >= 16:
        del _ROUND_CACHE[next(iter(_ROUND_CACHE))]
    _ROUND_CACHE[key] = (weakref.ref(rail), lo, hi, nodes)
    return nodes


@numba.njit(cache=True)
def _poly_points(
    xs: NDArray[np.float64], R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact nodes of the round wheel on the polyline at the positions ``xs``."""
    B = 16
    bmax = _block_max(vy, B)
    gmax = vy.max()
    out = np.zeros((xs.size, _NCOL))
    for i in range(xs.size):
        v, p = _poly_solve(xs[i], R, vx, vy, bmax, B, gmax)
        _, sl, xd = _piece(p, xs[i], R, vx, vy)
        out[i, _X] = xs[i]
        out[i, _V] = v
        out[i, _SL] = sl
        out[i, _SR] = sl
        out[i, _XD] = xd
    return out


FLAT_ZONE_MARGIN = 1e-4
"""Margin (rad) on the flat's angular extent when deciding where the round table holds."""


def _contact_zones(
    rn: NDArray[np.float64], R: float, half: float, phase: float, x0: float, x1: float
) -> list[tuple[float, float]]:
    """Stretches of [x0, x1] where a flat (|θ| <= ``half``, r <= R) can change y_C^k.

    A flat lies inside the nominal circle, so y_C^k equals the round wheel's constraint
    wherever the round wheel's own contact point is on the round part of the outline. That
    point's wheel angle θ* = asin((x_D - x)/R) + φ is non-decreasing along the stretch (the
    contact point of a round wheel only moves forward; while it pivots on a rail vertex θ*
    falls by at most (1 - cos ψ)/(R cos ψ) per metre, ~1e-7 rad per node interval, far
    below FLAT_ZONE_MARGIN), so between two nodes of the round table it stays between its
    values at the nodes: an interval belongs to a zone if that range meets a flat.
    """
    x = rn[:, _X]
    i0 = max(int(np.searchsorted(x, x0, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(x, x1, side="left")) + 1, x.size)
    xs = x[i0:i1]
    th = np.arcsin(np.clip((rn[i0:i1, _XD] - xs) / R, -1.0, 1.0)) + phase + xs / R
    lo, hi = th[:-1] - FLAT_ZONE_MARGIN, th[1:] + FLAT_ZONE_MARGIN
    k = np.floor((lo + half) / TWO_PI)
    # the first flat at or after lo - half ... the interval meets it if it starts before its end
    hit = np.zeros(lo.size, bool)
    for kk in (k, k + 1.0):
        hit |= (lo <= TWO_PI * kk + half) & (hi >= TWO_PI * kk - half)
    zones: list[tuple[float, float]] = []
    for i in np.flatnonzero(hit):
        a, b = max(float(xs[i]), x0), min(float(xs[i + 1]), x1)
        if b <= a:
            continue
        if zones and a <= zones[-1][1]:
            zones[-1] = (zones[-1][0], b)
        else:
            zones.append((a, b))
    return zones


def _tabulate_polyline(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
) -> ConstraintTable:
    """An out-of-round wheel on a sampled rail (sim_core.constraint.polyline).

    The cell sweep inside the stretches where the wheel's out-of-roundness can reach the
    contact (all of it for a sampled outline), the round wheel's closed form elsewhere.
    """
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(resolution, 1e-3)
    margin = 0.01 + 2.0 * step
    x0, x1 = a - margin, b + margin
    poly = rail_polyline(rail, x0, x1, R)
    P = polyline_pieces(wheel)
    parts: list[NDArray[np.float64]] = []

    def nint(lo: float, hi: float) -> int:
        return max(math.ceil((hi - lo) / step), 2)

    if wheel.kind in ("ideal_flat", "rounded_flat"):
        zones = _contact_zones(
            _round_nodes(rail, poly, R, step, x0, x1), R, wheel.flat_half_angle, phase, x0, x1
        )
    else:
        zones = flat_zones(wheel, poly, phase, x0, x1)
    # the stretch in order: gaps (round closed form, cut from the rail's round table at exact
    # end nodes unless a zone supplies the node) and zones (the cell sweep)
    pieces: list[tuple[str, float, float]] = []
    cur = x0
    for za, zb in zones:
        if za > cur:
            pieces.append(("gap", cur, za))
        pieces.append(("zone", za, zb))
        cur = zb
    if cur < x1:
        pieces.append(("gap", cur, x1))
    zone_ends = {e for _, za, zb in pieces if _ == "zone" for e in (za, zb)}
    rn = np.empty((0, _NCOL))
    ends = np.empty((0, _NCOL))
    if any(kind == "gap" for kind, _, _ in pieces):
        rn = _round_nodes(rail, poly, R, step, x0, x1)
        cuts = np.array(
            [e for kind, c, d in pieces if kind == "gap" for e in (c, d) if e not in zone_ends]
        )
        ends = _poly_points(cuts, R, poly.vx, poly.vy) if cuts.size else ends
    ie = 0
    for kind, c, d in pieces:
        if kind == "zone":
            parts.append(
                sweep_kernel(
                    P, R, poly.vx, poly.vy, poly.slope, phase, c, d, nint(c, d), HERMITE_TOL
                )
            )
            continue
        if c not in zone_ends:
            parts.append(ends[ie : ie + 1])
            ie += 1
        lo_i = int(np.searchsorted(rn[:, _X], c, side="right"))
        hi_i = int(np.searchsorted(rn[:, _X], d, side="left"))
        parts.append(rn[lo_i:hi_i])
        if d not in zone_ends:
            parts.append(ends[ie : ie + 1])
            ie += 1
    nodes = np.concatenate(parts)
    if not np.all(np.diff(nodes[:, _X]) > 0):
        nodes = nodes[np.argsort(nodes[:, _X], kind="mergesort")]
    return _table_from_nodes(nodes, 0.0, resolution, step)


def warm_up_constraint() -> float:
    """Compile (or load from numba's cache) and run every tabulation path on tiny inputs.

    A long-running process (the streaming service) calls this once at start, before the
    first wheel: no wheel then pays for compilation. Covers the round wheel on flat,
    cosine, step and sampled rails, the ideal flat on a flat rail, the piece sweep (sampled
    outline on flat and cosine rails), the polyline sweep (ideal flat, rounded flat and
    sampled outline on a sampled rail, with the round wheel's cached table), the general
    ψ-search, the direct solve and the table look-up. Returns the wall time it took (s).

    >>> warm_up_constraint() >= 0.0
    True
    """
    import time

    t0 = time.perf_counter()
    R = 0.46
    th = np.linspace(0.0, TWO_PI, 64, endpoint=False)
    sampled_wheel = WheelOutline.sampled(th, R + 2e-5 * np.cos(3 * th) - 1e-5 * np.cos(7 * th))
    wheels = [
        WheelOutline.round(R),
        WheelOutline.ideal_flat(R, 0.02),
        WheelOutline.rounded_flat(R, 0.03, 0.03**2 / (16 * R)),
        sampled_wheel,
    ]
    xs = np.arange(0.0, 0.06, 5e-4)
    rails = [
        RailProfile.flat(),
        RailProfile.cosine(2e-6, 0.06),
        RailProfile.step(1e-5, 0.002),
        RailProfile.sampled(xs - 0.03, 2e-6 * np.sin(400.0 * xs) + 1e-6 * np.cos(1300.0 * xs)),
    ]
    xq = np.linspace(-0.002, 0.002, 5)
    for wheel in wheels:
        for rail in rails:
            for method in ("auto", "general"):
                t = tabulate_constraint(wheel, rail, -0.002, 0.002, method=method)
                t.evaluate(xq)
            # a flat away from the window: the round table cut at exact end nodes
            tabulate_constraint(wheel, rail, -0.002, 0.002, phase=1.0).evaluate(xq)
        evaluate_exact(wheel, rails[-1], xq)
    profile_constraint(rails[-1], -0.002, 0.002).evaluate(xq)
    return time.perf_counter() - t0


def profile_constraint(rail: RailProfile, x_start: float, x_end: float) -> ConstraintTable:
    """The option "the profile is the constraint": y_C^k = y_r(x_C), x_D = x_C.

    The wheel's geometric filtering is ignored (MODEL.md §6, Fig. 9). A cosine
    gives a periodic table (512 nodes per wavelength, exact slopes); a sampled
    rail a table on its samples with a kink at every vertex where the slope
    changes; a step cannot be a constraint (it is discontinuous).

    >>> t = profile_constraint(RailProfile.cosine(1e-4, 0.05), 0.0, 1.0)
    >>> round(float(t.evaluate(np.array([0.0125]))[0]) * 1e4, 9), t.period
    (0.0, 0.05)
    """
    a, b = _check_range(x_start, x_end)
    res = min(rail.min_feature_length, MAX_RESOLUTION)
    if rail.kind == "flat":
        return flat_constraint(resolution=res)
    if rail.kind == "step":
        raise ValueError(
            "profile constraint: a step rail is discontinuous and cannot itself be the constraint; "
            "use the exact constraint (tabulate_constraint)"
        )
    if rail.kind == "cosine":
        lam, amp = rail.wavelength, rail.amplitude
        x = a + np.linspace(0.0, lam, 513)
        k = 2 * math.pi / lam
        y = amp * np.cos(k * x)
        y[-1] = y[0]
        s = -amp * k * np.sin(k * x)
        s[-1] = s[0]
        return ConstraintTable(
            x=x,
            y=y,
            slope_left=s,
            slope_right=s.copy(),
            contact_x=x.copy(),
            kinks=np.empty(0),
            period=lam,
            resolution=res,
        )
    margin = 0.01
    xs = rail.x
    inside = (xs > a - margin) & (xs < b + margin)
    xn = np.concatenate(
        ([min(a - margin, xs[0]) - 1e-3], xs[inside], [max(b + margin, xs[-1]) + 1e-3])
    )
    yn = rail.height(xn)
    seg = np.diff(yn) / np.diff(xn)
    sl = np.concatenate(([0.0], seg))
    sr = np.concatenate((seg, [0.0]))
    kink = sl != sr
    kink[0] = kink[-1] = False
    return ConstraintTable(
        x=xn,
        y=yn,
        slope_left=sl,
        slope_right=sr,
        contact_x=xn.copy(),
        kinks=xn[kink].copy(),
        period=0.0,
        resolution=res,
    )


def amplitude_spectrum(
    table: ConstraintTable, x_start: float, length: float, n_harmonics: int
) -> NDArray[np.float64]:
    """One-sided harmonic amplitudes of y_C^k over [x_start, x_start + length] (m).

    ``length`` is taken as the fundamental period (λ for a cosine rail, 2πR for
    one wheel turn); returns A[0..n_harmonics], A[0] the mean and A[k] the
    amplitude of the k-th harmonic cos(2πk x/length). Computed from 2^16 (or
    more) samples of the table by FFT.

    >>> t = profile_constraint(RailProfile.cosine(2e-4, 0.1), 0.0, 1.0)
    >>> [round(v * 1e4, 6) for v in amplitude_spectrum(t, 0.0, 0.1, 2).tolist()]
    [0.0, 2.0, 0.0]
    """
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"amplitude spectrum: length must be positive (m), got {length!r}")
    if n_harmonics < 1:
        raise ValueError(f"amplitude spectrum: n_harmonics must be >= 1, got {n_harmonics!r}")
    n = max(1 << 16, 8 * n_harmonics)
    x = float(x_start) + length * np.arange(n) / n
    c = np.fft.rfft(table.evaluate(x)) / n
    amp = 2.0 * np.abs(c[: n_harmonics + 1])
    amp[0] = abs(c[0].real)
    return np.asarray(amp)


def _hamrock_brewe_coefficient(
    rx: NDArray[np.float64], ry: NDArray[np.float64]
) -> NDArray[np.float64]:
    """C/(2E*) of an elliptical Hertz contact (Hamrock & Brewe 1983 approximations)."""
    big = np.maximum(rx, ry)
    small = np.minimum(rx, ry)
    ratio = big / small
    kell = 1.0339 * ratio**0.6360
    e_int = 1.0003 + 0.5968 / ratio
    f_int = 1.5277 + 0.6023 * np.log(ratio)
    r_eff = 1.0 / (1.0 / rx + 1.0 / ry)
    return np.asarray(math.pi * kell * np.sqrt(2.0 * e_int * r_eff) / (3.0 * f_int**1.5))


def curvature_stiffness_scale(
    table: ConstraintTable,
    rail: RailProfile,
    radius: float,
    *,
    min_radius: float = 0.01,
    max_radius: float = 100.0,
) -> NDArray[np.float64]:
    """Per node the factor C(x)/C of the curvature-dependent Hertz coefficient (MODEL.md §3).

    Longitudinal relative curvature 1/R + κ_r(x_D) (κ_r > 0 on a crest),
    transverse 1/R; the radii Rx = 1/(1/R + κ_r) and Ry = R are clamped to
    [``min_radius``, ``max_radius``] (default 10 mm … 100 m: a concave rail
    with κ_r <= -1/R would otherwise give a conforming contact). The elliptical
    correction uses Hamrock & Brewe's approximations of the ellipticity and
    the elliptic integrals; the result is normalised by the same formula at
    Rx = Ry = R, so that a flat rail gives exactly 1.

    Use ``dataclasses.replace(table, stiffness_scale=...)`` to attach it.
    Worked example: on the crest of the 0.1 mm, 5 cm cosine (κ_r = 1.58 1/m)
    the contact is 17 % softer than on a flat rail; at the inflection it is the same:

    >>> t = profile_constraint(RailProfile.cosine(1e-4, 0.05), 0.0, 1.0)
    >>> s = curvature_stiffness_scale(t, RailProfile.cosine(1e-4, 0.05), 0.475)
    >>> round(float(s[0]), 3), round(float(s[128]), 3)
    (0.827, 1.0)
    """
    R = float(radius)
    if not (math.isfinite(R) and R > 0):
        raise ValueError(f"curvature stiffness: radius must be positive (m), got {radius!r}")
    if not (0 < min_radius < max_radius):
        raise ValueError(
            f"curvature stiffness: need 0 < min_radius < max_radius, got {min_radius!r}, {max_radius!r}"
        )
    kappa = rail.curvature(table.contact_x)
    curv = 1.0 / R + kappa
    with np.errstate(divide="ignore"):
        rx = np.where(curv > 1.0 / max_radius, 1.0 / np.maximum(curv, 1e-300), max_radius)
    rx = np.clip(rx, min_radius, max_radius)
    ry = np.full_like(rx, min(max(R, min_radius), max_radius))
    ref = _hamrock_brewe_coefficient(np.array([R]), np.array([R]))[0]
    return np.asarray(_hamrock_brewe_coefficient(rx, ry) / ref)
