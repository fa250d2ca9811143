"""A round wheel on a polyline rail (sampled, file, dented or step): closed form.

The constraint is the upper envelope of one circular arc per rail vertex
(y_i + sqrt(R² - (x_i - x)²) - R) and one straight piece per segment of slope s (the wheel
tangent to the segment: y_i + s(x - x_i) + R(sqrt(1+s²) - 1)). Per closed segment j the best
contact g_j(x) is its line where the tangent point is inside, else an end vertex's arc; the
winning contact point never moves back as x grows, so a later segment that overtakes an
earlier one stays on top: one pass over the segments keeps the envelope as a stack (each
pushed once, popped at most once; :func:`_envelope_nodes`). Adjacent segments hand over in
closed form (a convex vertex's arc, C¹; a concave vertex's lines crossing, a kink), others
(the wheel bridging a hollow) where the later overtakes, by Newton on the two closed forms
to the last bit. Nodes: the grid, every hand-over and every change of form, so the table is
exact piecewise (arcs and lines): the nodes hold exact values and slopes, and no refinement
is needed between them (a line's Hermite is exact, an arc's within h⁴/(128R³): 5e-15 m for
h = 0.5 mm and R = 0.46 m). Measured on 6 m sampled every 0.5 mm: 16-25 ms against the
former grid of global solves' 220-300 ms, same nodes to 4e-19 m, same kinks (a loaded
2-core machine).

The round wheel's table of a whole sampled rail is wheel-independent: it is made once per
rail and radius (:func:`round_nodes`, cached) and the out-of-round wheels of
:mod:`sim_core.constraint.polyline` take it outside their flat zones.

Worked example: a round wheel rolling over a 1 mm step climbs on the corner's arc: 10 mm
before the corner it is R - sqrt(R² - 0.01²) = 0.105 mm below the step's top:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_round_polyline(0.475, RailProfile.step(1e-3, 0.0), -0.02, 0.02, None, 1e-3)
    >>> round(float(t.evaluate(np.array([-0.01]))[0]) * 1e3, 4)
    0.8947
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.nodes import (
    NCOL,
    ROUND_K,
    ROUND_NCOL,
    SL,
    SR,
    XD,
    V,
    X,
    stretch,
    table_from_nodes,
)
from sim_core.constraint.rail_polyline import PerRailCache, rail_polyline
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RailProfile

__all__ = ["poly_points", "round_nodes", "tabulate_round_polyline"]

_borrowing = numba.njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # _nrt: not in the stubs
"""The decorator of the functions that allocate nothing and return no array (the per-point
helpers :func:`_piece`, :func:`_eff`, :func:`_poly_solve`, :func:`_seg_breaks`,
:func:`_overtake`, and the envelope's two passes :func:`_stack` and :func:`_emit`): compiled
without numba's runtime, they borrow their arrays instead of taking a reference count on each
(an atomic increment and decrement per array, per call and per inlined helper: the envelope
of a 6 m rail sampled every 0.5 mm spent ~80 % of its 14 ms in ``NRT_incref``/``NRT_decref``,
measured with ``perf``; without them 1.6 ms, the same nodes to the last bit)."""


@_borrowing
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


@_borrowing
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


@_borrowing
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


_ROUND_CACHE: PerRailCache[NDArray[np.float64]] = PerRailCache(16)


def round_nodes(
    rail: RailProfile, R: float, step: float, x0: float, x1: float
) -> NDArray[np.float64]:
    """The round wheel's node rows (radius R) on the whole polyline rail, made once per rail and R.

    Wheel-independent: every out-of-round wheel of radius R on this rail takes its nodes
    outside its flat zones from here (cut exactly at the zone ends by :func:`poly_points`).
    """
    nodes = _ROUND_CACHE.get(rail, (float(R), float(step)), x0, x1)
    if nodes is not None:
        return nodes
    poly = rail_polyline(rail, x0, x1, R)
    lo = min(x0, float(poly.vx[1]) - 0.05)
    hi = max(x1, float(poly.vx[-2]) + 0.05)
    poly = rail_polyline(rail, lo, hi, R)
    # its nodes are already more than the merging distance apart (table_from_nodes' 1e-13·|x|)
    nodes = _envelope_nodes(lo, hi, max(math.ceil((hi - lo) / step), 2), R, poly.vx, poly.vy)
    _ROUND_CACHE.put(rail, (float(R), float(step)), lo, hi, nodes)
    return nodes


@numba.njit(cache=True)
def poly_points(
    xs: NDArray[np.float64], R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Exact nodes of the round wheel on the polyline at the positions ``xs``."""
    B = 16
    bmax = _block_max(vy, B)
    gmax = vy.max()
    out = np.zeros((xs.size, NCOL))
    for i in range(xs.size):
        v, p = _poly_solve(xs[i], R, vx, vy, bmax, B, gmax)
        _, sl, xd = _piece(p, xs[i], R, vx, vy)
        out[i, X] = xs[i]
        out[i, V] = v
        out[i, SL] = sl
        out[i, SR] = sl
        out[i, XD] = xd
    return out


def tabulate_round_polyline(
    R: float, rail: RailProfile, a: float, b: float, dx: float | None, resolution: float
) -> ConstraintTable:
    """The table of a round wheel of radius ``R`` on a sampled or step rail over [a, b]
    (node spacing ``dx``, default the resolution capped at 1 mm: the pieces are exact
    between the inserted nodes)."""
    step = float(dx) if dx is not None else min(resolution, 1e-3)
    x0, x1, nint = stretch(a, b, step, 0.0)
    poly = rail_polyline(rail, x0, x1, R)
    nodes = _envelope_nodes(x0, x1, nint, R, poly.vx, poly.vy)
    return table_from_nodes(nodes, 0.0, resolution, step)


# ======================================================================================
# the envelope by one pass over the rail's segments
# ======================================================================================
@numba.njit(cache=True, inline="always")
def _seg_value(
    j: int, x: float, R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> tuple[float, float, float, int]:
    """(value, slope, x_D, piece) of g_j(x) = the best wheel contact on the closed segment j:
    its line where the tangent point is inside, else the arc of the nearer end vertex."""
    pid = _eff(2 * j + 1, x, R, vx, vy)
    v, s, xd = _piece(pid, x, R, vx, vy)
    return v, s, xd, pid


@numba.njit(cache=True)
def _lines(
    R: float, vx: NDArray[np.float64], vy: NDArray[np.float64], jlo: int, jhi: int
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per segment j in [jlo, jhi] (rising in x): its slope s, its line's lift R·s²/(c + 1) and
    its tangent point's offset s·R/c (c = √(1 + s²)), the same expressions as
    :func:`_piece`'s, computed once (NaN-free zeros elsewhere)."""
    n = vx.size
    ss = np.zeros(n)
    so = np.zeros(n)
    sto = np.zeros(n)
    for k in range(jlo, jhi + 1):
        dxs = vx[k + 1] - vx[k]
        if dxs > 0.0:
            sl = (vy[k + 1] - vy[k]) / dxs
            c = math.sqrt(1.0 + sl * sl)
            ss[k] = sl
            so[k] = R * sl * sl / (c + 1.0)
            sto[k] = sl * R / c
    return ss, so, sto


@numba.njit(cache=True, inline="always")
def _seg_value_l(
    j: int,
    x: float,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    ss: NDArray[np.float64],
    so: NDArray[np.float64],
    sto: NDArray[np.float64],
) -> tuple[float, float, float, int]:
    """:func:`_seg_value` of a segment rising in x from :func:`_lines`' columns: the same
    numbers to the last bit, without the line's square root and divisions."""
    p = x + sto[j]
    if p < vx[j]:
        v, s, xd = _piece(2 * j, x, R, vx, vy)
        return v, s, xd, 2 * j
    if p > vx[j + 1]:
        v, s, xd = _piece(2 * j + 2, x, R, vx, vy)
        return v, s, xd, 2 * j + 2
    return so[j] + vy[j] + ss[j] * (x - vx[j]), ss[j], p, 2 * j + 1


@_borrowing
def _seg_breaks(
    j: int, R: float, vx: NDArray[np.float64], vy: NDArray[np.float64]
) -> tuple[float, float]:
    """Where g_j passes from its lo vertex's arc to its line, and from its line to its hi
    vertex's arc (the line's tangent point at the segment's ends)."""
    dxs = vx[j + 1] - vx[j]
    if dxs <= 0.0:  # a vertical riser: no line, the two arcs meet under it
        return vx[j], vx[j]
    s = (vy[j + 1] - vy[j]) / dxs
    off = s * R / math.sqrt(1.0 + s * s)
    return vx[j] - off, vx[j + 1] - off


@_borrowing
def _overtake(
    t: int,
    j: int,
    lo: float,
    hi: float,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
) -> float:
    """The x in (lo, hi] from which g_j (a later segment) is at or above g_t, given g_j < g_t
    at lo (g_j - g_t only grows with x: the round wheel's contact point never moves back);
    inf if g_j stays below up to hi. Within the bracket where both keep one closed form, the
    root of their difference by Newton (bisection where a step leaves the bracket)."""
    hi_in = hi
    a0, a1 = _seg_breaks(t, R, vx, vy)
    b0, b1 = _seg_breaks(j, R, vx, vy)
    # g_t ends where its last point leaves the wheel's reach: j (reaching further) is on top
    # from there (never on a rail whose heights span less than R)
    hi = min(hi, vx[t + 1] + R * (1.0 - 1e-12))
    a = lo
    # the forms' break points above lo, in order, then hi
    for _ in range(5):
        nxt = hi
        for e in (a0, a1, b0, b1):
            if a < e < nxt:
                nxt = e
        vj = _seg_value(j, nxt, R, vx, vy)[0]
        vt = _seg_value(t, nxt, R, vx, vy)[0]
        if vj >= vt:
            break
        if nxt >= hi:
            return hi if hi < hi_in else np.inf
        a = nxt
    b = nxt
    # one form each on (a, b): their difference is smooth and increasing there
    m = 0.5 * (a + b)
    pt = _seg_value(t, m, R, vx, vy)[3]
    pj = _seg_value(j, m, R, vx, vy)[3]
    x = m
    for _ in range(100):
        vt, st, _ = _piece(pt, x, R, vx, vy)
        vj, sj, _ = _piece(pj, x, R, vx, vy)
        d = vj - vt
        if d >= 0.0:
            b = x
        else:
            a = x
        mid = 0.5 * (a + b)
        if d == 0.0 or not a < mid < b:  # no double left between a and b
            break
        den = sj - st
        nx = x - d / den if den > 0.0 else mid
        if not a < nx < b:
            nx = mid
        x = nx
    return b


@numba.njit(cache=True, inline="always")
def _row(
    nodes: NDArray[np.float64],
    n: int,
    x: float,
    v: float,
    sl: float,
    sr: float,
    xd: float,
    k: float,
) -> None:
    """Row n of ``nodes`` (room known; ``ROUND_NCOL`` columns) set to a node
    (:func:`~sim_core.constraint.nodes.add_node`'s columns), in place: the envelope's ~30 000
    nodes of a 6 m rail cost 4x less than through add_node's returned array."""
    nodes[n, X] = x
    nodes[n, V] = v
    nodes[n, SL] = sl
    nodes[n, SR] = sr
    nodes[n, XD] = xd
    nodes[n, ROUND_K] = k


@numba.njit(cache=True)
def _envelope_nodes(
    x0: float,
    x1: float,
    nint: int,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Nodes of a round wheel on a polyline over [x0, x1]: the grid (nint intervals) and
    every change of piece, by one pass over the segments within reach.

    y_C^k(x) = max_j g_j(x) over the rail's closed segments j, and the winning contact point
    never moves back as x grows (∂²/∂x∂p of the wheel's height over a rail point p is
    R²/(R² - (p - x)²)^{3/2} > 0), so a later segment that overtakes an earlier one stays on
    top of it: the envelope is a stack of segments, each pushed once and popped at most once
    (the convex-hull trick). Adjacent segments hand over at the vertex between them in
    closed form (a convex vertex's arc, C¹; a concave vertex's two lines crossing, a kink);
    others where the later overtakes (the wheel bridging a hollow, a kink)."""
    n = vx.size
    jlo = max(int(np.searchsorted(vx, x0 - R, side="right")) - 1, 0)
    jhi = min(int(np.searchsorted(vx, x1 + R, side="left")), n - 2)
    cap = jhi - jlo + 2
    ss, so, sto = _lines(R, vx, vy, jlo, jhi)
    st = np.empty(cap, np.int64)  # segments on the stack
    sx = np.empty(cap)  # where each starts to win
    sk = np.empty(cap)  # 1.0 if its start is a kink
    ns = _stack(x0, x1, R, vx, vy, ss, so, sto, jlo, jhi, st, sx, sk)
    nodes = np.empty((nint + 1 + 3 * ns + 1, ROUND_NCOL))  # grid, and per segment <= 3
    nn = _emit(x0, x1, nint, R, vx, vy, ss, so, sto, st, sx, sk, ns, nodes)
    return nodes[:nn]


@_borrowing
def _stack(
    x0: float,
    x1: float,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    ss: NDArray[np.float64],
    so: NDArray[np.float64],
    sto: NDArray[np.float64],
    jlo: int,
    jhi: int,
    st: NDArray[np.int64],
    sx: NDArray[np.float64],
    sk: NDArray[np.float64],
) -> int:
    """:func:`_envelope_nodes`' pass over the segments: the stack (``st`` its segments, ``sx``
    where each starts to win, ``sk`` 1.0 where that start is a kink) and its size."""
    ns = 0
    for j in range(jlo, jhi + 1):
        if not vx[j + 1] > vx[j]:
            continue  # a vertical riser: its corners are the arcs of the segments beside it
        start = x0
        kink = 0.0
        while ns > 0:
            t = st[ns - 1]
            xs = sx[ns - 1]
            vj = _seg_value_l(j, xs, R, vx, vy, ss, so, sto)[0]
            vt = _seg_value_l(t, xs, R, vx, vy, ss, so, sto)[0]
            if vj >= vt:
                ns -= 1  # j at or above t wherever t won
                continue
            if t == j - 1 and vx[j + 1] > vx[j] and vx[j] > vx[j - 1]:
                # adjacent: the vertex j between them, in closed form
                s0 = ss[j - 1]
                s1 = ss[j]
                if s1 <= s0 + 1e-12:
                    # convex (or collinear to round-off): line j-1, then vertex j's arc
                    # (j's from there, C¹)
                    start = vx[j] - sto[j - 1]
                    kink = 0.0
                else:  # concave: the two offset lines cross between their tangent ends
                    start = vx[j] + (so[j] - so[j - 1]) / (s0 - s1)
                    kink = 1.0
                    # valid where both are their lines (not where a segment too short for
                    # its tangent point hands over by its end vertex's arc)
                    if not (
                        vx[j] - sto[j - 1] - (vx[j] - vx[j - 1]) <= start <= vx[j] - sto[j - 1]
                        and vx[j] - sto[j] <= start <= vx[j + 1] - sto[j]
                    ):
                        start = xs  # not found: the general case below
                if not start > xs:
                    start = _overtake(t, j, xs, x1, R, vx, vy)
                    kink = 1.0
            else:
                start = _overtake(t, j, xs, x1, R, vx, vy)
                kink = 1.0
            break
        if ns > 0 and not start < x1:
            continue  # j never wins on [x0, x1)
        st[ns] = j
        sx[ns] = start if ns > 0 else x0
        sk[ns] = kink if ns > 0 else 0.0
        ns += 1
    return ns


@_borrowing
def _emit(
    x0: float,
    x1: float,
    nint: int,
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    ss: NDArray[np.float64],
    so: NDArray[np.float64],
    sto: NDArray[np.float64],
    st: NDArray[np.int64],
    sx: NDArray[np.float64],
    sk: NDArray[np.float64],
    ns: int,
    nodes: NDArray[np.float64],
) -> int:
    """:func:`_envelope_nodes`' nodes from the stack, written into ``nodes`` (room known):
    their number."""
    # the nodes: grid points, the starts of the stack's segments, and their forms' breaks
    nn = 0
    h = (x1 - x0) / nint
    i = 0
    for m in range(ns):
        j = st[m]
        a = sx[m]
        b = sx[m + 1] if m + 1 < ns else x1
        if m > 0:
            # the start of j: the left side from the segment before
            vl, sl, _, _ = _seg_value_l(st[m - 1], a, R, vx, vy, ss, so, sto)
            vr, sr, xd, _ = _seg_value_l(j, a, R, vx, vy, ss, so, sto)
            if nn > 0 and a - nodes[nn - 1, X] <= 1e-13 * max(1.0, abs(a)):
                nn -= 1
                sl = nodes[nn, SL]
            _row(nodes, nn, a, max(vl, vr), sl, sr, xd, sk[m])
            nn += 1
        e0, e1 = vx[j] - sto[j], vx[j + 1] - sto[j]  # _seg_breaks
        for e in (e0, e1):
            # grid points before the break
            while i <= nint:
                xg = x0 + i * h if i < nint else x1
                if xg >= e or xg >= b:
                    break
                if (xg > a or (m == 0 and xg >= a)) and (
                    nn == 0 or xg - nodes[nn - 1, X] > 1e-13 * max(1.0, abs(xg))
                ):
                    v, s, xd, _ = _seg_value_l(j, xg, R, vx, vy, ss, so, sto)
                    _row(nodes, nn, xg, v, s, s, xd, 0.0)
                    nn += 1
                i += 1
            if a < e < b and e - nodes[nn - 1, X] > 1e-13 * max(1.0, abs(e)):
                v, s, xd, _ = _seg_value_l(j, e, R, vx, vy, ss, so, sto)
                _row(nodes, nn, e, v, s, s, xd, 0.0)
                nn += 1
        while i <= nint:
            xg = x0 + i * h if i < nint else x1
            if xg >= b and not (m == ns - 1 and xg <= b):
                break
            if (xg > a or (m == 0 and xg >= a)) and (
                nn == 0 or xg - nodes[nn - 1, X] > 1e-13 * max(1.0, abs(xg))
            ):
                v, s, xd, _ = _seg_value_l(j, xg, R, vx, vy, ss, so, sto)
                _row(nodes, nn, xg, v, s, s, xd, 0.0)
                nn += 1
            i += 1
    return nn
