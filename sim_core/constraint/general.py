"""The general ψ-search: any wheel on any rail, the reference the fast methods are checked against.

For every wheel position x the objective of MODEL.md §2,

    G(ψ) = y_r(x + ρ·sin ψ) + ρ·cos ψ - R,   ρ = r(ψ + φ),

is maximised by a global search over a ψ grid finer than both inputs' features, in a
window bounded by the height range (a wheel point at ψ can only win if
``rail max + wheel bulge - 2R·sin²(ψ/2)`` reaches the value at ψ = 0), then golden-section
refinement of the best grid maxima on the continuous interpolated objective, split at
every corner of either outline (rail vertices, wheel samples, a flat's ends), whose values
are taken exactly. An ideal flat's two corners are also evaluated exactly at every x (the
grid cannot see a corner's maximum beside a close rail vertex, see :func:`_flat_corners`). Slopes are central differences (±1e-8 m) of these re-optimised values.
Kinks are found from jumps of the contact angle ψ between nodes and located by bisection
to ~1e-13 m; an interval is split at its midpoint unless the cubic Hermite matches the
exact value there to 1e-13 m and the exact slope to 8e-13/h (this resolves C² breaks such as
where a flat's corner starts to carry the wheel; the slope catches an error odd about the
midpoint, which a value check misses: 2.4e-12 m on a rounded flat over a rough rail before).

Worked example: a round wheel on a 1 mm step stands on the step's corner when its centre
is above it:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> y, xd = evaluate_exact(WheelOutline.round(0.475), RailProfile.step(1e-3, 0.0), np.array([0.0]))
    >>> round(float(y[0]) * 1e3, 9), float(xd[0])
    (1.0, 0.0)
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.nodes import (
    GL,
    GR,
    HERMITE_TOL,
    MAX_STEPS,
    NCOL,
    PL,
    PR,
    SL,
    SR,
    XD,
    K,
    V,
    X,
    grow,
    hermite_midpoint,
    interval_stack,
    next_interval,
    push,
    rail_feature_length,
    split,
    stretch,
    table_from_nodes,
)
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RAIL_SAMPLED, RAIL_STEP, RailProfile, rail_height
from sim_core.wheel import (
    TWO_PI,
    WHEEL_IDEAL_FLAT,
    WHEEL_SAMPLED,
    WheelOutline,
    wheel_offset,
)

__all__ = ["evaluate_exact", "general_nodes", "tabulate_general", "tabulate_nodes"]


class SearchCase(NamedTuple):
    """A wheel and a rail as the compiled ψ-search reads them."""

    wp: NDArray[np.float64]
    """[code, R, a, b, bulge] of the wheel (:meth:`WheelOutline.compiled_args`, max excess)."""
    wth: NDArray[np.float64]
    """Sampled outline: angles (rad)."""
    wdr: NDArray[np.float64]
    """Sampled outline: r - R (m)."""
    rp: NDArray[np.float64]
    """[code, a, b] of the rail (:meth:`RailProfile.compiled_args`)."""
    rxs: NDArray[np.float64]
    """Sampled rail: positions (m)."""
    rys: NDArray[np.float64]
    """Sampled rail: heights (m)."""


SLOPE_STEP = 1e-8
"""Half-width (m) of the central differences that give the general case's node slopes."""


PSI_JUMP = 1e-7
"""Smallest jump of the contact angle ψ (rad) treated as a kink (general case)."""


KINK_CURVATURE = 1e3
"""A second difference of y_C^k over ±SLOPE_STEP above this curvature (1/m) flags a kink."""


@numba.njit(cache=True)
def _objective(
    x: float,
    psi: float,
    phi: float,
    sc: SearchCase,
) -> tuple[float, float]:
    """(y_r(x_D) + ρ cos ψ - R, x_D) without cancellation; wp = [code, R, a, b, bulge], rp = [code, a, b]."""
    wp, wth, wdr, rp, rxs, rys = sc.wp, sc.wth, sc.wdr, sc.rp, sc.rxs, sc.rys
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
    sc: SearchCase,
) -> tuple[float, float, float]:
    """Maximise the objective over ψ in [lo, hi]: golden section to 1e-8 rad, then a parabolic polish.

    Used on smooth pieces (between corners, see :func:`_refine`); a smooth maximum is polished by one parabola through ±1e-6 rad
    (its value is then exact to rounding).
    """
    invphi = 0.6180339887498949
    a, b = lo, hi
    c = b - invphi * (b - a)
    d = a + invphi * (b - a)
    gc, _ = _objective(x, c, phi, sc)
    gd, _ = _objective(x, d, phi, sc)
    while b - a > 1e-8:
        if gc >= gd:
            b, d, gd = d, c, gc
            c = b - invphi * (b - a)
            gc, _ = _objective(x, c, phi, sc)
        else:
            a, c, gc = c, d, gd
            d = a + invphi * (b - a)
            gd, _ = _objective(x, d, phi, sc)
    p = c if gc >= gd else d
    g, xd = _objective(x, p, phi, sc)
    dl = 1e-6
    gm, _ = _objective(x, p - dl, phi, sc)
    gp, _ = _objective(x, p + dl, phi, sc)
    den = gp - 2.0 * g + gm
    if den < 0.0:
        q = p - 0.5 * dl * (gp - gm) / den
        if abs(q - p) < 2.0 * dl:
            gq, xq = _objective(x, q, phi, sc)
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
    sc: SearchCase,
) -> tuple[float, float, float]:
    """Maximise over ψ in [lo, hi] exactly: split at every corner of either outline inside
    (rail vertices, wheel samples, flat corners), evaluate the corners exactly, and
    golden-search each smooth piece between them."""
    wp, wth, wdr, rp, rxs = sc.wp, sc.wth, sc.wdr, sc.rp, sc.rxs
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
        _, xlo = _objective(x, lo, phi, sc)
        _, xhi = _objective(x, hi, phi, sc)
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
        g, xd = _objective(x, pk, phi, sc)
        if rcode == RAIL_STEP and abs(xd - rp[2]) < 1e-9:
            s = math.sin(0.5 * pk)
            dr = wheel_offset(code, R, wp[2], wp[3], wth, wdr, pk + phi)
            g = max(0.0, rp[1]) + dr * math.cos(pk) - 2.0 * R * s * s
        if g > best_g:
            best_g, best_p, best_x = g, pk, xd
        if k + 1 < nb and pts[k + 1] - pk > 1e-12:
            p, g, xd = _golden(x, pk, pts[k + 1], phi, sc)
            if g > best_g:
                best_g, best_p, best_x = g, p, xd
    return best_p, best_g, best_x


@numba.njit(cache=True)
def _solve(
    x: float,
    phase: float,
    dpsi: float,
    gmax: float,
    sc: SearchCase,
    st: NDArray[np.float64],
) -> tuple[float, float, float]:
    """(y_C^k, ψ*, x_D) at wheel position x: windowed grid search, golden refinement, snap."""
    wp, rp, rxs = sc.wp, sc.rp, sc.rxs
    R = wp[1]
    bulge = wp[4]
    phi = phase + x / R
    g0, xd0 = _objective(x, 0.0, phi, sc)
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
    gprev, _ = _objective(x, -psimax, phi, sc)
    gcur, _ = _objective(x, -psimax + h, phi, sc)
    if gprev >= gcur:
        kb[0] = gprev
        ki[0] = 0
    for i in range(1, n):
        if i + 1 < n:
            gnext, _ = _objective(x, -psimax + (i + 1) * h, phi, sc)
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
        p, g, xd = _refine(x, lo, hi, phi, sc)
        gi = kb[j]
        if gi > g:
            p = -psimax + ki[j] * h
            g, xd = _objective(x, p, phi, sc)
        if g > best_g:
            best_g, best_p, best_x = g, p, xd
    if int(wp[0]) == WHEEL_IDEAL_FLAT:
        p, g, xd = _flat_corners(x, psimax, h, phi, best_g, sc)
        if g > best_g:
            best_g, best_p, best_x = g, p, xd
    return best_g, best_p, best_x


@numba.njit(cache=True)
def _flat_corners(
    x: float, psimax: float, h: float, phi: float, best: float, sc: SearchCase
) -> tuple[float, float, float]:
    """(ψ, G, x_D) of the best maximum next to an ideal flat's corners in the window ±psimax
    that beats ``best`` (G = -inf if none does).

    The grid cannot see a corner's maximum when a rail vertex lies less than a grid step
    beside it on the flat: G falls from the corner to the vertex and rises again to the
    next vertex, so the grid shows one slope and the corner lies outside every refined
    window. Each corner is therefore evaluated exactly, and refined (±2 grid steps, split
    at the corner and the rail vertices there) when it beats the grid's best. Example:
    a 50 mm flat on a rough rail sampled every 0.5 mm at x = 0.0197185 m, its corner
    0.4 µm left of the vertex at x_D = -5 mm: the search took the next vertex instead,
    7.6e-11 m too low, over 70 nm of x.
    """
    wp = sc.wp
    best_g = -np.inf
    best_p = 0.0
    best_x = x
    for sgn in (-1.0, 1.0):
        t = sgn * wp[2] - phi
        t -= TWO_PI * math.floor((t + math.pi) / TWO_PI)
        if not (-psimax < t < psimax):
            continue
        g, _ = _objective(x, t, phi, sc)
        if g <= best:
            continue
        p, g, xd = _refine(x, max(t - 2.0 * h, -psimax), min(t + 2.0 * h, psimax), phi, sc)
        if g > best_g:
            best_g, best_p, best_x = g, p, xd
    return best_p, best_g, best_x


@numba.njit(cache=True)
def _jumpy(d1: float, d2: float) -> bool:
    dd = abs(d2 - d1)
    return dd > PSI_JUMP and dd > 0.5 * (abs(d1) + abs(d2))


@numba.njit(cache=True)
def _solve_t(x: float, args: tuple) -> tuple[float, float, float]:
    phase, dpsi, gmax, sc, st = args
    return _solve(x, phase, dpsi, gmax, sc, st)


@numba.njit(cache=True, inline="always")
def _locate(
    solve: Any,
    lo: float,
    hi: float,
    plo: float,
    glo: float,
    phi_: float,
    ghi: float,
    args: tuple,
) -> float:
    """Bisection for a kink in (lo, hi): classify ψ at the midpoint against the two branches
    (:func:`_on_left_branch`; as :func:`~sim_core.constraint.roots.bisect` to 1e-13, written out:
    a solve function in a tuple would not be cached)."""
    a, b = lo, hi
    for _ in range(200):
        if b - a <= 1e-13 * max(1.0, abs(a)):
            break
        m = 0.5 * (a + b)
        if m <= a or m >= b:
            break
        if _on_left_branch(solve, m, lo, plo, glo, hi, phi_, ghi, args):
            a = m
        else:
            b = m
    return 0.5 * (a + b)


@numba.njit(cache=True, inline="always")
def _on_left_branch(
    solve: Any,
    m: float,
    lo: float,
    plo: float,
    glo: float,
    hi: float,
    phi_: float,
    ghi: float,
    args: tuple,
) -> bool:
    """True if ψ at m is nearer the left branch (ψ = plo + glo·(m - lo)) than the right."""
    _, pm, _ = solve(m, args)
    da = abs(pm - (plo + glo * (m - lo)))
    db = abs(pm - (phi_ + ghi * (m - hi)))
    return da <= db


@numba.njit(cache=True, inline="always")
def _kink_row(solve: Any, xk: float, args: tuple, out: NDArray[np.float64]) -> None:
    """A kink node at xk: one-sided second-order slopes and ψ-branches on both sides."""
    eps = SLOPE_STEP
    vk, _, _ = solve(xk, args)
    vl1, pl1, _ = solve(xk - eps, args)
    vl2, pl2, _ = solve(xk - 2.0 * eps, args)
    vr1, pr1, xdr = solve(xk + eps, args)
    vr2, pr2, _ = solve(xk + 2.0 * eps, args)
    out[X] = xk
    out[V] = vk
    out[SL] = (3.0 * vk - 4.0 * vl1 + vl2) / (2.0 * eps)
    out[SR] = (-3.0 * vk + 4.0 * vr1 - vr2) / (2.0 * eps)
    out[XD] = xdr
    out[GL] = (pl1 - pl2) / eps
    out[GR] = (pr2 - pr1) / eps
    out[PL] = pl1 + out[GL] * eps
    out[PR] = pr1 - out[GR] * eps
    out[K] = 1.0


@numba.njit(cache=True, inline="always")
def _make_node(
    solve: Any,
    xv: float,
    fixed: bool,
    args: tuple,
    row: NDArray[np.float64],
    row2: NDArray[np.float64],
) -> int:
    """Node(s) at xv into row (and row2, sorted by x); returns how many (1 or 2).

    Slopes are central differences; if the contact angle jumps within ±eps the
    kink is located and becomes the node (a fixed node stays and gets a
    one-sided slope, and the kink is a second node).
    """
    eps = SLOPE_STEP
    v0, p0, xd0 = solve(xv, args)
    vm, pm, _ = solve(xv - eps, args)
    vp, pp, _ = solve(xv + eps, args)
    if not (_jumpy(p0 - pm, pp - p0) or abs(vm - 2.0 * v0 + vp) > KINK_CURVATURE * eps * eps):
        row[X] = xv
        row[V] = v0
        row[SL] = (vp - vm) / (2.0 * eps)
        row[SR] = row[SL]
        row[XD] = xd0
        row[PL] = p0
        row[PR] = p0
        row[GL] = (pp - pm) / (2.0 * eps)
        row[GR] = row[GL]
        row[K] = 0.0
        return 1
    xk = _locate(solve, xv - eps, xv + eps, pm, 0.0, pp, 0.0, args)
    if not fixed or abs(xk - xv) < 1e-12 * max(1.0, abs(xv)):
        _kink_row(solve, xv if fixed else xk, args, row)
        return 1
    side = -1.0 if xk > xv else 1.0
    v1, p1, _ = solve(xv + side * eps, args)
    v2, _, _ = solve(xv + 2.0 * side * eps, args)
    row[X] = xv
    row[V] = v0
    row[SL] = side * (-3.0 * v0 + 4.0 * v1 - v2) / (2.0 * eps)
    row[SR] = row[SL]
    row[XD] = xd0
    row[PL] = p0
    row[PR] = p0
    row[GL] = side * (p1 - p0) / eps
    row[GR] = row[GL]
    row[K] = 0.0
    _kink_row(solve, xk, args, row2)
    if xk < xv:
        tmp = row.copy()
        row[:] = row2
        row2[:] = tmp
    return 2


@numba.njit(cache=True, inline="always")
def tabulate_nodes(
    solve: Any,
    x0: float,
    x1: float,
    nint: int,
    periodic: bool,
    args: tuple,
) -> NDArray[np.float64]:
    """Nodes (rows: x, y, slopes, x_D, ψ, dψ/dx, kink flag) over [x0, x1], sorted by x, from
    the global solve ``solve(x, args)`` → (y_C^k, ψ*, x_D) (the ψ-search's :func:`_solve_t`,
    or another exact global solve with a contact angle continuous along each contact branch).

    It and the helpers that take ``solve`` are inlined into each caller (``_tabulate_general``,
    :mod:`sim_core.constraint.cosine_hybrid`): a compiled function handed to a function that is
    not inlined makes the caller impossible to cache."""
    eps = SLOPE_STEP
    nodes = np.empty((2 * nint + 64, NCOL))
    nn = 0
    row = np.empty(NCOL)
    row2 = np.empty(NCOL)
    # ---------------------------------------------------------------- grid
    hgrid = (x1 - x0) / nint
    last = nint - 1 if periodic else nint
    for i in range(last + 1):
        xv = x0 + i * hgrid if i < nint else x1
        k = _make_node(solve, xv, (i == 0) or (i == nint), args, row, row2)
        nodes = grow(nodes, nn + 2)
        nodes[nn] = row
        nn += 1
        if k == 2:
            nodes[nn] = row2
            nn += 1
    if periodic:
        nodes = grow(nodes, nn + 1)
        nodes[nn] = nodes[0]
        nodes[nn, X] = x1
        nodes[nn, XD] = nodes[0, XD] + (x1 - x0)
        nn += 1
    # ---------------------------------------------------------------- refinement
    stack, ns = interval_stack(nn)
    for _ in range(MAX_STEPS):
        ns, ia, ib, _, xa, xb, h, scale = next_interval(stack, ns, nodes)
        if ia < 0:
            break
        ea = abs(nodes[ib, PL] - (nodes[ia, PR] + nodes[ia, GR] * h))
        eb = abs(nodes[ia, PR] - (nodes[ib, PL] - nodes[ib, GL] * h))
        smooth = abs(nodes[ib, GL] - nodes[ia, GR]) * h + PSI_JUMP
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
                    _, pm, _ = solve(m, args)
                    pa = nodes[ia, PR] + nodes[ia, GR] * (m - xa)
                    pb = nodes[ib, PL] + nodes[ib, GL] * (m - xb)
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
                    solve, xa, xb, nodes[ia, PR], nodes[ia, GR], nodes[ib, PL], nodes[ib, GL], args
                )
                hi = lo
            if not math.isnan(third):
                k = _make_node(solve, third, False, args, row, row2)
            else:
                _kink_row(solve, 0.5 * (lo + hi), args, row)
                k = 1
            have = True
        elif h > 4.0 * eps:
            # the node at the midpoint, kept unless the Hermite matches its value and its slope
            # (an error odd about m is 0 there in value, but ~h/8 times its slope miss beside)
            m = 0.5 * (xa + xb)
            k = _make_node(solve, m, False, args, row, row2)
            hm, dm = hermite_midpoint(nodes, ia, ib, h)
            have = (
                k == 2
                or row[K] > 0.0
                or abs(row[V] - hm) > HERMITE_TOL
                or 0.125 * h * abs(row[SL] - dm) > HERMITE_TOL
            )
        if not have:
            continue
        if not (xa < row[X] < xb):
            continue
        nodes = grow(nodes, nn + 2)
        nodes[nn] = row
        ic = nn
        nn += 1
        if k == 2 and xa < row2[X] < xb:
            nodes[nn] = row2
            id2 = nn
            nn += 1
            stack, ns = split(stack, ns, ic, id2, ib)
            stack, ns = push(stack, ns, ia, ic, 0)
        else:
            stack, ns = split(stack, ns, ia, ic, ib)
    out = nodes[:nn]
    order = np.argsort(out[:, X], kind="mergesort")
    return out[order]


@numba.njit(cache=True)
def _tabulate_general(
    x0: float, x1: float, nint: int, periodic: bool, args: tuple
) -> NDArray[np.float64]:
    """:func:`tabulate_nodes` with the ψ-search's solve."""
    return tabulate_nodes(_solve_t, x0, x1, nint, periodic, args)


def _general_args(
    wheel: WheelOutline, rail: RailProfile
) -> tuple[SearchCase, NDArray[np.float64], float]:
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
    return SearchCase(wp, th, dr, rp, rxs, rys), st, gmax


def _dpsi(wheel: WheelOutline, rail: RailProfile) -> float:
    R = wheel.nominal_radius
    feat = min(rail_feature_length(rail), wheel.min_feature_length)
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
    sc, st, gmax = _general_args(wheel, rail)
    dpsi = _dpsi(wheel, rail)
    y = np.empty(xq.shape)
    xd = np.empty(xq.shape)
    _solve_many(xq.ravel(), float(phase), dpsi, gmax, sc, st, y.reshape(-1), xd.reshape(-1))
    return y, xd


@numba.njit(cache=True)
def _solve_many(
    xq: NDArray[np.float64],
    phase: float,
    dpsi: float,
    gmax: float,
    sc: SearchCase,
    st: NDArray[np.float64],
    y: NDArray[np.float64],
    xd: NDArray[np.float64],
) -> None:
    for i in range(xq.size):
        v, _, d = _solve(xq[i], phase, dpsi, gmax, sc, st)
        y[i] = v
        xd[i] = d


def tabulate_general(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
) -> ConstraintTable:
    """The table of ``wheel`` on ``rail`` over [a, b] by the ψ-search (node spacing ``dx``,
    default half the resolution capped at 2 mm; periodic where the geometry repeats)."""
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(0.5 * resolution, 2e-3)
    periodic = 0.0
    if rail.kind == "flat":
        periodic = TWO_PI * R
    elif rail.kind == "cosine" and wheel.kind == "round":
        periodic = rail.wavelength
    x0, x1, nint = stretch(a, b, step, periodic)
    nodes = general_nodes(wheel, rail, phase, x0, x1, nint, periodic > 0)
    return table_from_nodes(nodes, periodic, resolution, step)


def general_nodes(
    wheel: WheelOutline,
    rail: RailProfile,
    phase: float,
    x0: float,
    x1: float,
    nint: int,
    periodic: bool = False,
) -> NDArray[np.float64]:
    """Node rows (:mod:`sim_core.constraint.nodes`) of the ψ-search over exactly [x0, x1],
    from ``nint`` grid intervals (refined where needed), sorted by x."""
    sc, st, gmax = _general_args(wheel, rail)
    args = (float(phase), _dpsi(wheel, rail), gmax, sc, st)
    return _tabulate_general(float(x0), float(x1), int(nint), periodic, args)
