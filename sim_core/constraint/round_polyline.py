"""A round wheel on a polyline rail (sampled, file, dented or step): closed form.

The constraint is the upper envelope of one circular arc per rail vertex
(y_i + sqrt(R² - (x_i - x)²) - R) and one straight piece per segment of slope s (the wheel
tangent to the segment: y_i + s(x - x_i) + R(sqrt(1+s²) - 1)). Nodes hold the active piece;
every change of piece between two nodes is inserted as a node: tangent junctions (segment →
its end vertex → next segment) in closed form, crossings of non-adjacent pieces (kinks) by
bisection to the last bit. So the table is exact piecewise (arcs and lines): the nodes hold
exact values and slopes, and no refinement is needed between them (a line's Hermite is
exact, an arc's within h⁴/(128R³): 5e-15 m for h = 0.5 mm and R = 0.46 m).

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
    SL,
    SR,
    XD,
    K,
    V,
    X,
    add_node,
    grow,
    merge_close,
    stretch,
    table_from_nodes,
)
from sim_core.constraint.rail_polyline import PerRailCache, rail_polyline
from sim_core.constraint.roots import bisect
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RailProfile

__all__ = ["poly_points", "round_nodes", "tabulate_round_polyline"]


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
    return bisect(_first_on_top, a, b, (pa, pb, R, vx, vy), 0.0)


@numba.njit(cache=True)
def _first_on_top(
    m: float, args: tuple[int, int, float, NDArray[np.float64], NDArray[np.float64]]
) -> bool:
    """True if piece pa is (still) at or above pb at m; args = (pa, pb, R, vx, vy)."""
    pa, pb, R, vx, vy = args
    va, _, _ = _piece(_eff(pa, m, R, vx, vy), m, R, vx, vy)
    vb, _, _ = _piece(_eff(pb, m, R, vx, vy), m, R, vx, vy)
    return va >= vb


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


@numba.njit(cache=True, inline="always")
def _interval_task(
    tf: NDArray[np.float64], ti: NDArray[np.int64], nt: int, a: float, b: float, pa: int, pb: int
) -> int:
    """Task row nt: resolve the changes of piece from pa (at a) to pb (at b); returns nt + 1."""
    tf[nt, 0] = a
    tf[nt, 1] = b
    ti[nt, 0] = 0
    ti[nt, 1] = pa
    ti[nt, 2] = pb
    return nt + 1


@numba.njit(cache=True, inline="always")
def _node_task(
    tf: NDArray[np.float64],
    ti: NDArray[np.int64],
    nt: int,
    x: float,
    v: float,
    xd: float,
    sr: float,
    kink: float,
    piece: int,
) -> int:
    """Task row nt: emit the node at x (value, contact point, right slope, kink flag, the
    piece on its left); returns nt + 1."""
    tf[nt, 0] = x
    tf[nt, 1] = v
    tf[nt, 2] = xd
    tf[nt, 3] = sr
    tf[nt, 4] = kink
    ti[nt, 0] = 1
    ti[nt, 1] = piece
    return nt + 1


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
    nodes = np.empty((4 * nint + 64, NCOL))
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
            _interval_task(tf, ti, 0, xprev, xv, pprev, p)
            nt = 1
            budget = 100_000
            while nt > 0 and budget > 0:
                budget -= 1
                nt -= 1
                kind = ti[nt, 0]
                if kind == 1:
                    nodes = grow(nodes, nn + 1)
                    xn = tf[nt, 0]
                    if nn > 0 and xn - nodes[nn - 1, X] <= 1e-13 * max(1.0, abs(xn)):
                        nodes[nn - 1, SR] = tf[nt, 3]
                        nodes[nn - 1, XD] = tf[nt, 2]
                        nodes[nn - 1, K] = max(nodes[nn - 1, K], tf[nt, 4])
                    else:
                        sln = _piece(ti[nt, 1], xn, R, vx, vy)[1]
                        nodes = add_node(
                            nodes, nn, xn, tf[nt, 1], sln, tf[nt, 3], tf[nt, 2], tf[nt, 4]
                        )
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
                tf = grow(tf, nt + 4)
                ti = grow(ti, nt + 4)
                if vc > top + 1e-15 and pc != pa and pc != target and pc != ea and pc != eb:
                    # a third piece is on top at xs: split there (pop order: left, node, right)
                    _, slc, xdc = _piece(pc, xs, R, vx, vy)
                    nt = _interval_task(tf, ti, nt, xs, b, pc, pb)
                    nt = _node_task(tf, ti, nt, xs, vc, xdc, slc, 0.0, pc)
                    nt = _interval_task(tf, ti, nt, a, xs, pa, pc)
                    continue
                # the transition node, with what remains on either side of it
                if via >= 0:
                    nt = _interval_task(tf, ti, nt, xs, b, via, pb)
                elif eb != pb:
                    nt = _interval_task(tf, ti, nt, xs, b, eb, pb)
                nt = _node_task(tf, ti, nt, xs, top, xdb, srb, 0.0 if c1 else 1.0, ea)
                if ea != pa:
                    nt = _interval_task(tf, ti, nt, a, xs, pa, ea)
        # the grid node itself
        nodes = grow(nodes, nn + 1)
        _, sl, xd = _piece(p, xv, R, vx, vy)
        if nn > 0 and xv - nodes[nn - 1, X] <= 1e-13 * max(1.0, abs(xv)):
            nodes[nn - 1, X] = xv
            nodes[nn - 1, SR] = sl
            nodes[nn - 1, XD] = xd
        else:
            nodes = add_node(nodes, nn, xv, v, sl, sl, xd, 0.0)
            nn += 1
        xprev, pprev = xv, p
    return nodes[:nn]


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
    nodes = merge_close(
        _tabulate_poly(lo, hi, max(math.ceil((hi - lo) / step), 2), R, poly.vx, poly.vy, 16)
    )
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
    nodes = _tabulate_poly(x0, x1, nint, R, poly.vx, poly.vy, 16)
    return table_from_nodes(nodes, 0.0, resolution, step)
