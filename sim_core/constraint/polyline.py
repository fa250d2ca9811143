"""Fast exact y_C^k of an out-of-round wheel on a polyline (sampled, file, dented, step) rail.

On a polyline rail y_r(p) (vertices (x_i, y_i), segment slopes s_j) and a wheel cut into
pieces (:func:`sim_core.constraint.wheel_pieces.wheel_pieces`: one smooth formula r(θ) each,
marked convex or concave; the round part of a flat wheel is one arc), the objective of
MODEL.md §2,

    G(ψ) = y_r(x + ρ sin ψ) + ρ cos ψ - R,   ρ = r(ψ + φ),

is cut in ψ into *cells* (piece g × segment j): on a cell the rail is the straight line of
segment j, so G is unimodal on a convex piece (its maximum is the root of G', by safeguarded
Newton; closed form tan ψ = s_j on an arc) and has its maximum at an end on a concave piece or
a flat's chord. A cell ends either at a wheel vertex (the end of a piece, ψ = θ_v - φ) or at a
rail vertex (the ψ with x + ρ sin ψ = x_i: Newton, closed form on an arc). The winner of
y_C^k(x) is a *feature*:

- ``T(g, j)``: the interior of piece g tangent to segment j;
- ``W(g, j)``: the wheel vertex at the hi end of piece g on segment j;
- ``V(g, i)``: rail vertex i under the interior of piece g.

Each has a closed-form slope (envelope theorem at fixed ψ for T, at fixed θ for W, at fixed
rail point for V). Pieces are numbered over all turns (piece k of turn m is g = m·n + k).

A global solve at x evaluates the cells of the window of ψ that can win, a wheel point at ψ
can only win if ``max rail + max bulge - R(1 - cos ψ)`` reaches the best so far (each segment
is skipped by the same bound with its own heights). The sweep starts from grid nodes; between
two nodes of different features the change is located by bisection on the winner among the
two features' own cells (a few closed forms per step, to ~1e-13 m), and a global solve at the
located point splits the interval if a third feature is on top there (kinks: non-adjacent
features; C¹ handovers: a tangent point reaching a cell end). Between nodes of the same
feature the midpoint is solved globally (a missed feature splits the interval) and compared
with the cubic Hermite interpolant, by value only: a feature's closed form varies on the
scale of R or of the flat (cm), against intervals of at most the rail's sampling (<= 1 mm), so
the Hermite's error odd about the midpoint, which the piece sweep and the ψ-search also catch
by the slope there, stays far below it. Measured: with that slope check added, the site's
three tables (6 m) and the tests' nine windows were bit-identical.

For an ideal or rounded flat (r <= R everywhere), y_C^k equals the round wheel's constraint
wherever the flat cannot reach the contact: any winning ψ has R(1 - cos ψ) <= Δy + d (Δy the
rail's height range, d the flat's depth), so outside the *flat zones* |φ| <= θ_flat + ψ_max
the round-wheel closed form (:mod:`sim_core.constraint.round_polyline`) is exact, and the
sweep above runs only inside the zones (a few % of the stretch).

The wheel-independent work (the polyline with its extension, segment slopes) is made once per
rail (:func:`rail_polyline`, cached per rail object) and reused by every wheel.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.contact_zones import contact_zones
from sim_core.constraint.nodes import (
    HERMITE_TOL,
    KINK_SLOPE,
    MAX_STEPS,
    NCOL,
    RISER,
    SL,
    SR,
    XD,
    K,
    X,
    add_node,
    grow,
    hermite_midpoint,
    interval_stack,
    next_interval,
    push,
    split,
    stretch,
    table_from_parts,
)
from sim_core.constraint.rail_polyline import RailPolyline, rail_polyline
from sim_core.constraint.round_polyline import _borrowing, poly_points, round_nodes
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import (
    PIECE_ARC,
    PIECE_CHORD,
    PIECE_HAVERSINE,
    PIECE_LINEAR,
    _piece_of,
    _rho,
    _shift,
    wheel_pieces,
)
from sim_core.constraint.wheel_pieces import _drop as _drop_lb
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = [
    "RailPolyline",
    "flat_zones",
    "polyline_pieces",
    "rail_polyline",
    "supports_polyline",
    "tabulate_polyline",
]

# the sweep's helpers that take the case's arrays (``PolylineCase``, six of them) are compiled
# ``_borrowing`` (round_polyline): no reference count on each array per call; they allocate
# nothing and return no array
# piece table columns (as in wheel_pieces)
_T0, _T1, _KIND, _C0, _C1, _CEN, _CONC, _DRMAX = range(8)


class PolylineCase(NamedTuple):
    """A wheel's pieces on a polyline rail, as the compiled sweep reads them."""

    P: NDArray[np.float64]
    """The piece table (:func:`polyline_pieces`)."""
    n: int
    """Pieces per turn."""
    R: float
    """Nominal radius (m)."""
    vx: NDArray[np.float64]
    """Rail vertices: positions (m)."""
    vy: NDArray[np.float64]
    """Rail vertices: heights (m)."""
    sl: NDArray[np.float64]
    """Segment slopes."""


FT_T, FT_W, FT_V = 0, 1, 2
"""Feature types: piece interior tangent to a segment, wheel vertex on a segment, rail vertex under a piece."""

MAX_RAIL_SLOPE = 0.2
"""The sweep is used on sampled rails whose segments are no steeper than this, risers
(:data:`sim_core.constraint.nodes.RISER`: a dented step's 1e-12 m ramp) aside: the sweep
carries the wheel on a riser's two corners as on a step rail's vertical riser."""

CLIP = 0.5
"""|ψ| bound (rad) of the cells of the restricted solves (x_D monotone in ψ inside)."""

HAVERSINE_SUBPIECES = 16
"""A rounded flat's haversine is cut into this many sub-pieces, each with its own largest
r - R: the bound of the global solve then skips the rail segments that cannot reach the flat."""


def supports_polyline(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True if the polyline sweep applies: an out-of-round wheel on a step rail or on a
    sampled rail whose segments are no steeper than ``MAX_RAIL_SLOPE``, risers aside.

    A step's riser is a vertical segment (only its two corners can carry the wheel), and so
    is a dented step's 1e-12 m ramp.
    """
    if wheel.kind == "round":
        return False
    if rail.kind == "step":
        return True
    if rail.kind != "sampled" or rail.x.size < 2:
        return False
    dx = np.diff(rail.x)
    s = np.abs(np.diff(rail.y)[dx >= RISER] / dx[dx >= RISER])
    return bool(s.size == 0 or s.max() <= MAX_RAIL_SLOPE)


def polyline_pieces(wheel: WheelOutline) -> NDArray[np.float64]:
    """The wheel's piece table with the round part of a flat as one arc (exact on any range)."""
    P = wheel_pieces(wheel)
    rows = [P[0].copy()]
    for row in P[1:]:
        if row[_KIND] == PIECE_ARC and rows[-1][_KIND] == PIECE_ARC:
            rows[-1][_T1] = row[_T1]
        else:
            rows.append(row.copy())
    # a rounded flat's haversine in sub-pieces (HAVERSINE_SUBPIECES over the flat), each with
    # its own largest r - R (at its end farther from the centre): the bound of the global
    # solve then skips most of the flat when it faces the rail
    out: list[NDArray[np.float64]] = []
    R = wheel.nominal_radius
    width = 2.0 * wheel.flat_half_angle / HAVERSINE_SUBPIECES
    for row in rows:
        if row[_KIND] != PIECE_HAVERSINE:
            out.append(row)
            continue
        m = max(math.ceil((row[_T1] - row[_T0]) / width - 1e-9), 1)
        edges = np.linspace(row[_T0], row[_T1], m + 1)
        for a, c in itertools.pairwise(edges):
            sub = row.copy()
            sub[_T0], sub[_T1] = a, c
            far = max(abs(a - row[_CEN]), abs(c - row[_CEN]))
            w = TWO_PI * R / row[_C1]
            sub[_DRMAX] = -0.5 * row[_C0] * (1.0 + math.cos(w * far))
            out.append(sub)
    return np.array(out)


def flat_zones(
    wheel: WheelOutline, poly: RailPolyline, phase: float, x0: float, x1: float
) -> list[tuple[float, float]]:
    """Stretches of [x0, x1] where a flat can carry the wheel (elsewhere the round closed form is exact).

    For a sampled outline: the whole stretch.
    """
    if wheel.kind not in ("ideal_flat", "rounded_flat"):
        return [(x0, x1)]
    R = wheel.nominal_radius
    c = 1.0 - (poly.ymax - poly.ymin + wheel.flat_depth) / R
    psimax = math.acos(max(c, -1.0))
    w = wheel.flat_half_angle + 1.05 * psimax + 1e-6
    out: list[tuple[float, float]] = []
    m = math.floor((phase + x0 / R - w) / TWO_PI)
    while True:
        a = R * (TWO_PI * m - phase - w)
        b = R * (TWO_PI * m - phase + w)
        m += 1
        if a >= x1:
            break
        if b <= x0:
            continue
        lo, hi = max(a, x0), min(b, x1)
        if out and lo <= out[-1][1]:
            out[-1] = (out[-1][0], hi)
        else:
            out.append((lo, hi))
    return out


# ======================================================================================
# compiled kernels
# ======================================================================================
@numba.njit(cache=True, inline="always")
def _seg_of(vx: NDArray[np.float64], p: float) -> int:
    """j with vx[j] <= p < vx[j + 1], clamped to the segments."""
    j = int(np.searchsorted(vx, p, side="right")) - 1
    return min(max(j, 0), vx.size - 2)


@numba.njit(cache=True, inline="always")
def _seg_from(vx: NDArray[np.float64], p: float, j: int) -> int:
    """:func:`_seg_of` by a walk from segment j (a nearby segment: a few steps)."""
    last = vx.size - 2
    while j > 0 and vx[j] > p:
        j -= 1
    while j < last and vx[j + 1] <= p:
        j += 1
    return j


@_borrowing
def _psi_at(
    P: NDArray[np.float64], k: int, sh: float, R: float, x: float, phi: float, xv: float
) -> float:
    """ψ of piece k (turn shift sh) with x + ρ sin ψ = xv."""
    u = (xv - x) / R
    psi = math.asin(min(max(u, -1.0), 1.0))
    kind = int(P[k, _KIND])
    if kind == PIECE_ARC:
        return psi
    if kind == PIECE_CHORD:
        # the chord is the line ρ cos(ψ + c) = R - d: tan ψ = u cos c / (R - d + u sin c)
        c = phi - sh - P[k, _CEN]
        du = xv - x
        return math.atan2(du * math.cos(c), R - P[k, _C0] + du * math.sin(c))
    for _ in range(12):
        dr, r1, _ = _rho(P, k, R, psi + phi - sh)
        rho = R + dr
        sp = math.sin(psi)
        f = x + rho * sp - xv
        fp = r1 * sp + rho * math.cos(psi)
        d = f / fp
        psi -= d
        if abs(d) <= 1e-9:  # quadratic convergence: this step left an error ~1e-18 rad
            break
    return psi


@_borrowing
def _vertex_point(
    P: NDArray[np.float64],
    k: int,
    sh: float,
    R: float,
    x: float,
    phi: float,
    xv: float,
    start: float = math.nan,
) -> tuple[float, float, float, float, float, float, float]:
    """(ψ, r - R, r', sin ψ, cos ψ, 1 - cos ψ, r'') of the wheel point of piece k (turn shift
    sh) over the rail position xv: :func:`_psi_at`, with the last Newton step (<= 1e-9 rad) of
    a haversine or sampled piece carried into r, r', sin and cos to second order (an error
    ~1e-27) instead of a new evaluation. ``start``: the Newton's first iterate (from
    :func:`_predict`; asin((xv - x)/R) if nan)."""
    kind = int(P[k, _KIND])
    if kind in (PIECE_HAVERSINE, PIECE_LINEAR):
        psi = start if not math.isnan(start) else math.asin(min(max((xv - x) / R, -1.0), 1.0))
        for _ in range(12):
            dr, r1, r2 = _rho(P, k, R, psi + phi - sh)
            rho = R + dr
            sp = math.sin(psi)
            cp = math.cos(psi)
            d = (x + rho * sp - xv) / (r1 * sp + rho * cp)
            if abs(d) <= 1e-9:
                omc = sp * sp / (1.0 + cp)  # 1 - cos ψ without cancellation
                q = 1.0 - 0.5 * d * d
                return (
                    psi - d,
                    dr - r1 * d + 0.5 * r2 * d * d,
                    r1 - r2 * d,
                    sp * q - cp * d,
                    cp * q + sp * d,
                    omc - sp * d + 0.5 * cp * d * d,
                    r2,
                )
            psi -= d
    else:
        psi = _psi_at(P, k, sh, R, x, phi, xv)
    return _wheel_point(P, k, sh, R, phi, psi)


@numba.njit(cache=True, inline="always")
def _predict(
    R: float, vp: tuple[float, float, float, float, float, float, float], du: float
) -> float:
    """ψ of the same piece's wheel point ``du`` further along the rail than the point ``vp``
    (:func:`_vertex_point`), to second order: from a rail vertex 0.5 mm away (δψ ~ 1e-3 rad)
    it is ~1e-10 rad off, so the Newton of :func:`_vertex_point` stops after one evaluation."""
    psi, dr, r1, sp, cp, _, r2 = vp
    rho = R + dr
    a1 = r1 * sp + rho * cp
    a2 = r2 * sp + 2.0 * r1 * cp - rho * sp
    d = du / a1
    return psi + d - 0.5 * a2 / a1 * d * d


@_borrowing
def _g_line(
    P: NDArray[np.float64],
    k: int,
    sh: float,
    R: float,
    x: float,
    phi: float,
    psi: float,
    xj: float,
    yj: float,
    s: float,
) -> tuple[float, float, float, float, float, float]:
    """(G, G', G'', x_D, r - R, r') of piece k at ψ against the line of a segment (xj, yj, slope s)."""
    dr, r1, r2 = _rho(P, k, R, psi + phi - sh)
    rho = R + dr
    sp = math.sin(psi)
    cp = math.cos(psi)
    h = math.sin(0.5 * psi)
    xd = x + rho * sp
    g = yj + s * (xd - xj) + dr * cp - 2.0 * R * h * h
    gp = s * (r1 * sp + rho * cp) + r1 * cp - rho * sp
    gpp = s * (r2 * sp + 2.0 * r1 * cp - rho * sp) + r2 * cp - 2.0 * r1 * sp - rho * cp
    return g, gp, gpp, xd, dr, r1


@numba.njit(cache=True, inline="always")
def _slope_tangent(R: float, sp: float, cp: float, r1: float, s: float) -> float:
    """dy_C/dx of a piece tangent to a segment of slope s at ψ (sin ψ, cos ψ; r')."""
    return s * (1.0 + r1 * sp / R) + r1 * cp / R


@numba.njit(cache=True, inline="always")
def _slope_wheel_vertex(R: float, sp: float, cp: float, dr: float, s: float) -> float:
    """dy_C/dx of a wheel vertex (sin ψ, cos ψ; r - R) on a segment of slope s."""
    rho = R + dr
    return s * (1.0 - rho * cp / R) + rho * sp / R


@numba.njit(cache=True, inline="always")
def _slope_rail_vertex(R: float, sp: float, cp: float, dr: float, r1: float) -> float:
    """dy_C/dx of a wheel point (sin ψ, cos ψ; r - R, r') pivoting on a rail vertex."""
    rho = R + dr
    dpsi = -(1.0 + r1 * sp / R) / (r1 * sp + rho * cp)
    return r1 * (dpsi + 1.0 / R) * cp - rho * sp * dpsi


@numba.njit(cache=True, inline="always")
def _hermite_root(lo: float, hi: float, f0: float, f1: float, d0: float, d1: float) -> float:
    """The root in (lo, hi) of the cubic Hermite interpolant of f (f0 > 0 > f1, slopes d0, d1
    at the ends), by a few Newton steps from the secant; the secant's root where the cubic is
    not monotone. Of G' on a haversine cell 1e-3 rad wide it is ~1e-10 rad off the root."""
    w = hi - lo
    m0 = d0 * w
    m1 = d1 * w
    t = f0 / (f0 - f1)
    for _ in range(4):
        t2 = t * t
        t3 = t2 * t
        p = (2.0 * t3 - 3.0 * t2 + 1.0) * f0 + (t3 - 2.0 * t2 + t) * m0
        p += (3.0 * t2 - 2.0 * t3) * f1 + (t3 - t2) * m1
        dp = (
            6.0 * (t2 - t) * (f0 - f1) + (3.0 * t2 - 4.0 * t + 1.0) * m0 + (3.0 * t2 - 2.0 * t) * m1
        )
        if not dp < 0.0:
            break
        tn = t - p / dp
        if not 0.0 < tn < 1.0:
            break
        t = tn
    return lo + t * w


@_borrowing
def _stationary(
    P: NDArray[np.float64],
    k: int,
    sh: float,
    R: float,
    x: float,
    phi: float,
    lo: float,
    hi: float,
    xj: float,
    yj: float,
    s: float,
    gplo: float = math.nan,
    gphi: float = math.nan,
    start: float = math.nan,
    gpplo: float = math.nan,
    gpphi: float = math.nan,
) -> tuple[float, float, float, float, float, float, float]:
    """(G, ψ, x_D, r', sin ψ, cos ψ, dψ/dx) at the root of G' in (lo, hi) (G'(lo) > 0 > G'(hi)).

    Safeguarded Newton on G' (bisection where a step leaves the bracket or G'' >= 0), from
    the root of the cubic Hermite interpolant of G' if its values and G'' at the ends
    (``gplo``, ``gphi``, ``gpplo``, ``gpphi``) are given, from the secant if only the values
    are, else from ``start`` (the root at a nearby x) if it is inside, else from the
    midpoint. The last Newton step (<= 1e-9 rad, leaving ~1e-18 rad) is carried into G, x_D,
    r', sin ψ and cos ψ to second order (G exact to ~1e-27 m) instead of a new evaluation;
    dψ/dx (nan if the Newton did not end on such a step) predicts the root at a nearby x.
    """
    if int(P[k, _KIND]) == PIECE_ARC:
        psi = math.atan(s)
        g, _, _, xd, _, r1 = _g_line(P, k, sh, R, x, phi, psi, xj, yj, s)
        return g, psi, xd, r1, math.sin(psi), math.cos(psi), 0.0
    if gplo > 0.0 > gphi:
        if gpplo < 0.0 and gpphi < 0.0:
            start = _hermite_root(lo, hi, gplo, gphi, gpplo, gpphi)
        else:
            start = lo + (hi - lo) * gplo / (gplo - gphi)
    a, b = lo, hi
    psi = start if lo < start < hi else 0.5 * (lo + hi)
    last = False
    for _ in range(61):
        dr, r1, r2 = _rho(P, k, R, psi + phi - sh)
        rho = R + dr
        sp = math.sin(psi)
        cp = math.cos(psi)
        ax = r1 * sp + rho * cp  # d x_D / dψ
        xd = x + rho * sp
        g = yj + s * (xd - xj) + dr * cp - R * sp * sp / (1.0 + cp)
        gp = s * ax + r1 * cp - rho * sp
        if last or gp == 0.0:
            break
        gpp = s * (r2 * sp + 2.0 * r1 * cp - rho * sp) + r2 * cp - 2.0 * r1 * sp - rho * cp
        if gp > 0.0:
            a = psi
        else:
            b = psi
        nxt = psi - gp / gpp if gpp < 0.0 else 0.5 * (a + b)
        if a < nxt < b:
            if gpp < 0.0 and abs(nxt - psi) <= 1e-9:
                d = nxt - psi
                # dψ/dx of the root: -(∂G'/∂x)/G'' (x turns the wheel: ∂θ/∂x = 1/R)
                gpx = (s * (r2 * sp + r1 * cp) + r2 * cp - r1 * sp) / R
                return (
                    g + d * (gp + 0.5 * gpp * d),
                    nxt,
                    xd + ax * d,
                    r1 + r2 * d,
                    sp + cp * d,
                    cp - sp * d,
                    -gpx / gpp,
                )
        else:
            nxt = 0.5 * (a + b)
        last = b - a <= 4e-16 or (gpp < 0.0 and abs(nxt - psi) <= 1e-9)
        psi = nxt
    return g, psi, xd, r1, sp, cp, math.nan


@numba.njit(cache=True, inline="always")
def _at_vertex(
    R: float, x: float, yv: float, psi: float, dr: float, r1: float
) -> tuple[float, float, float, float]:
    """(G, A, B, x_D) of a wheel point (ψ, r - R, r') over the rail vertex of height yv:
    G' on a segment of slope s is s·A + B there."""
    rho = R + dr
    sp = math.sin(psi)
    cp = math.cos(psi)
    h = math.sin(0.5 * psi)
    return yv + dr * cp - 2.0 * R * h * h, r1 * sp + rho * cp, r1 * cp - rho * sp, x + rho * sp


VertexPoint = tuple[float, float, float, float, float, float, float]
"""A wheel point over a rail vertex: (ψ, r - R, r', sin ψ, cos ψ, 1 - cos ψ, r'')."""
NO_POINT: VertexPoint = (0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0)
"""A placeholder :data:`VertexPoint` (no rail vertex)."""


@numba.njit(cache=True, inline="always")
def _at_point(R: float, x: float, yv: float, vp: VertexPoint) -> tuple[float, float, float, float]:
    """:func:`_at_vertex` from a :func:`_vertex_point` (its sines and cosines kept)."""
    _, dr, r1, sp, cp, omc, _ = vp
    rho = R + dr
    return yv + dr * cp - R * omc, r1 * sp + rho * cp, r1 * cp - rho * sp, x + rho * sp


@numba.njit(cache=True, inline="always")
def _curvature(
    R: float, dr: float, r1: float, r2: float, sp: float, cp: float
) -> tuple[float, float]:
    """(A2, B2) of a wheel point (r - R, r', r'', sin ψ, cos ψ): G'' on a segment of slope s
    is s·A2 + B2 there (A2 is also d²x_D/dψ²)."""
    rho = R + dr
    return r2 * sp + 2.0 * r1 * cp - rho * sp, r2 * cp - 2.0 * r1 * sp - rho * cp


@_borrowing
def _cell(
    pl: PolylineCase,
    g: int,
    j: int,
    x: float,
    phi: float,
    clip: float,
    cv: int = -1,
    cvp: VertexPoint = NO_POINT,
) -> tuple[float, int, int, int, float, float, int, VertexPoint]:
    """max of G over cell (piece g, segment j) at x: (value, type, g, r, slope, x_D, and the
    wheel point of :func:`_cell_in`); type -1 if empty. ``cv``, ``cvp``: as in :func:`_cell_in`."""
    P, n, R = pl.P, pl.n, pl.R
    k, sh = _shift(g, n)
    a = max(P[k, _T0] + sh - phi, -clip)
    b = min(P[k, _T1] + sh - phi, clip)
    if not a < b:
        return -np.inf, -1, 0, 0, 0.0, 0.0, cv, cvp
    dra, _, _ = _rho(P, k, R, a + phi - sh)
    drb, _, _ = _rho(P, k, R, b + phi - sh)
    xa = x + (R + dra) * math.sin(a)
    xb = x + (R + drb) * math.sin(b)
    return _cell_in(pl, g, k, sh, j, x, phi, a, b, xa, xb, cv, cvp)


@numba.njit(cache=True, inline="always")
def _wheel_point(
    P: NDArray[np.float64], k: int, sh: float, R: float, phi: float, psi: float
) -> VertexPoint:
    """The :data:`VertexPoint` tuple of piece k (turn shift sh) at ψ (a wheel vertex)."""
    dr, r1, r2 = _rho(P, k, R, psi + phi - sh)
    sp = math.sin(psi)
    cp = math.cos(psi)
    return psi, dr, r1, sp, cp, sp * sp / (1.0 + cp), r2


@_borrowing
def _cell_in(
    pl: PolylineCase,
    g: int,
    k: int,
    sh: float,
    j: int,
    x: float,
    phi: float,
    a: float,
    b: float,
    xa: float,
    xb: float,
    cv: int,
    cvp: VertexPoint,
) -> tuple[float, int, int, int, float, float, int, VertexPoint]:
    """:func:`_cell` on piece g = (k, turn shift sh) clipped to ψ in [a, b] (wheel points at
    x_D = xa, xb), with the piece's wheel point over rail vertex ``cv`` known (``cvp``, from
    :func:`_vertex_point`; -1: none): taken as it is over vertex j, else the start
    (:func:`_predict`) of the Newton for the cell's rail vertices. Returns the cell's best and
    the last wheel point over a rail vertex known (the hi one if the cell ends at one) for the
    next cell of the piece."""
    P, R, vx, vy, sl = pl.P, pl.R, pl.vx, pl.vy, pl.sl
    xj = vx[j]
    xj1 = vx[j + 1]
    s = sl[j]
    if xb < xj or xa > xj1:
        return -np.inf, -1, 0, 0, 0.0, 0.0, cv, cvp
    # lo end: a wheel vertex on the segment or the wheel point over rail vertex j
    if xa >= xj:
        p0 = _wheel_point(P, k, sh, R, phi, a)
        tlo, glo, rlo = FT_W, g - 1, j
        G0, A0, B0, xd0 = _at_point(R, x, 0.0, p0)
        G0 += vy[j] + s * (xd0 - xj)
    else:
        if cv == j:
            p0 = cvp
        else:
            st = _predict(R, cvp, xj - vx[cv]) if cv >= 0 else math.nan
            p0 = _vertex_point(P, k, sh, R, x, phi, xj, st)
            cv, cvp = j, p0
        tlo, glo, rlo = FT_V, g, j
        G0, A0, B0, xd0 = _at_point(R, x, vy[j], p0)
    if xb <= xj1:
        p1 = _wheel_point(P, k, sh, R, phi, b)
        thi, ghi, rhi = FT_W, g, j
        G1, A1, B1, xd1 = _at_point(R, x, 0.0, p1)
        G1 += vy[j] + s * (xd1 - xj)
    else:
        st = _predict(R, cvp, xj1 - vx[cv]) if cv >= 0 else math.nan
        p1 = _vertex_point(P, k, sh, R, x, phi, xj1, st)
        cv, cvp = j + 1, p1
        thi, ghi, rhi = FT_V, g, j + 1
        G1, A1, B1, xd1 = _at_point(R, x, vy[j + 1], p1)
    plo, dr0, r10 = p0[0], p0[1], p0[2]
    phi_, dr1, r11 = p1[0], p1[1], p1[2]
    gp0 = s * A0 + B0
    gp1 = s * A1 + B1
    convex = P[k, _CONC] == 0.0 and int(P[k, _KIND]) != PIECE_CHORD
    if convex and gp0 > 0.0 and gp1 < 0.0 and plo < phi_:
        a0, b0 = _curvature(R, dr0, r10, p0[6], p0[3], p0[4])
        a1, b1 = _curvature(R, dr1, r11, p1[6], p1[3], p1[4])
        G, _, xd, r1, sp, cp, _ = _stationary(
            P,
            k,
            sh,
            R,
            x,
            phi,
            plo,
            phi_,
            xj,
            vy[j],
            s,
            gp0,
            gp1,
            math.nan,
            s * a0 + b0,
            s * a1 + b1,
        )
        if G >= G0 and G >= G1:
            return G, FT_T, g, j, _slope_tangent(R, sp, cp, r1, s), xd, cv, cvp
    if G0 >= G1:
        if tlo == FT_V:
            sl0 = _slope_rail_vertex(R, p0[3], p0[4], dr0, r10)
            return G0, tlo, glo, rlo, sl0, xd0, cv, cvp
        sl0 = _slope_wheel_vertex(R, p0[3], p0[4], dr0, s)
        return G0, tlo, glo, rlo, sl0, xd0, cv, cvp
    if thi == FT_V:
        sl1 = _slope_rail_vertex(R, p1[3], p1[4], dr1, r11)
        return G1, thi, ghi, rhi, sl1, xd1, cv, cvp
    sl1 = _slope_wheel_vertex(R, p1[3], p1[4], dr1, s)
    return G1, thi, ghi, rhi, sl1, xd1, cv, cvp


_cell_scan = numba.njit(inline="always")(_cell_in.py_func)
""":func:`_cell_in` inlined into the global solve's scan (its one hot call site): a call
passes the rail's arrays with their reference counts, ~1/4 of a cell's cost."""


@_borrowing
def _cells_of(t: int, g: int, r: int, out: NDArray[np.int64], m: int) -> int:
    """Append the cells (g, j) of feature (t, g, r) to ``out`` from row m; returns the new count."""
    if t == FT_T:
        out[m, 0] = g
        out[m, 1] = r
        return m + 1
    if t == FT_W:
        out[m, 0] = g
        out[m, 1] = r
        out[m + 1, 0] = g + 1
        out[m + 1, 1] = r
        return m + 2
    out[m, 0] = g
    out[m, 1] = r - 1
    out[m + 1, 0] = g
    out[m + 1, 1] = r
    return m + 2


@_borrowing
def _chord_max(
    pl: PolylineCase,
    g: int,
    x: float,
    phi: float,
    a: float,
    b: float,
    psw: float,
) -> tuple[float, int, int, int, float, float]:
    """max of G over an ideal flat's chord (ψ in [a, b]) at x, the same features as :func:`_cell`.

    The chord is straight: over a rail vertex at offset u its depth is linear in u, so G at
    the rail vertices under it is y_i + dr(c) + u·tan c (c the chord's tilt), a loop of a
    multiply-add per vertex; its ends (wheel vertices) are evaluated on their segments.
    """
    P, n, R, vx, vy, sl = pl.P, pl.n, pl.R, pl.vx, pl.vy, pl.sl
    k, sh = _shift(g, n)
    c = phi - sh - P[k, _CEN]
    dr0, _, _ = _rho(P, k, R, c + P[k, _CEN])
    tc = math.tan(c)
    dra, _, _ = _rho(P, k, R, a + phi - sh)
    drb, _, _ = _rho(P, k, R, b + phi - sh)
    xa = x + (R + dra) * math.sin(a)
    xb = x + (R + drb) * math.sin(b)
    ia = int(np.searchsorted(vx, xa, side="right"))
    ib = int(np.searchsorted(vx, xb, side="left")) - 1
    best = -np.inf
    bi = -1
    for i in range(ia, ib + 1):
        v = vy[i] + (vx[i] - x) * tc
        if v > best:
            best, bi = v, i
    bt, bg, br = -1, 0, 0
    bs = bx = 0.0
    if bi >= 0:
        best += dr0
        vp = _vertex_point(P, k, sh, R, x, phi, vx[bi])
        best, _, _, bx = _at_point(R, x, vy[bi], vp)
        bt, bg, br = FT_V, g, bi
        bs = _slope_rail_vertex(R, vp[3], vp[4], vp[1], vp[2])
    # the chord's ends (not where the window clipped it)
    for end in range(2):
        pe = a if end == 0 else b
        if abs(pe) >= psw:
            continue
        xe = xa if end == 0 else xb
        j = _seg_of(vx, xe)
        ge, _, _, xd, dr, _ = _g_line(P, k, sh, R, x, phi, pe, vx[j], vy[j], sl[j])
        if ge > best:
            best, bt, bg, br = ge, FT_W, (g - 1 if end == 0 else g), j
            bs = _slope_wheel_vertex(R, math.sin(pe), math.cos(pe), dr, sl[j])
            bx = xd
    return best, bt, bg, br, bs, bx


@numba.njit(cache=True, inline="always")
def _asin_below(q: float) -> float:
    """A lower bound of asin(q) within ~0.075·q⁵ (|q| <= 0.5: the series' first two terms and
    a bound of the rest, whose terms have the sign of q and coefficients <= 3/40; asin itself
    beyond, q clamped to [-1, 1]). The global solve's bounds take it: no asin per segment."""
    if abs(q) > 0.5:
        return math.asin(min(max(q, -1.0), 1.0))
    q2 = q * q
    base = q * (1.0 + q2 / 6.0)
    return base + 0.075 * q * q2 * q2 / (1.0 - q2) if q < 0.0 else base


@numba.njit(cache=True, inline="always")
def _asin_above(q: float) -> float:
    """An upper bound of asin(q), as :func:`_asin_below`."""
    return -_asin_below(-q)


@numba.njit(cache=True, inline="always")
def _cos_below(y: float) -> float:
    """A lower bound of cos y on [-π, π] (Taylor to y¹⁰ less a bound of the remainder,
    y¹²/12!, and of the round-off): 4e-3 below at |y| = π, 2e-5 at |y| = 2. The haversine
    bound of the global solve takes it: no cos per segment."""
    y2 = y * y
    t = 1.0 + y2 * (
        -0.5 + y2 * (1.0 / 24.0 + y2 * (-1.0 / 720.0 + y2 * (1.0 / 40320.0 - y2 / 3628800.0)))
    )
    return t - y2 * y2 * y2 * y2 * y2 * y2 / 479001600.0 - 1e-15


@_borrowing
def _global(
    pl: PolylineCase,
    ymax: float,
    drg: float,
    phase: float,
    x: float,
    hint: int,
    seed_t: int = -1,
    seed_g: int = 0,
    seed_r: int = 0,
) -> tuple[float, int, int, int, float, float, int]:
    """(y_C^k, type, g, r, slope, x_D, piece at ψ = 0) at x: every cell that can win.

    The cells under the centre and those of the feature (seed_t, seed_g, seed_r) (the
    winner nearby, if seed_t >= 0) set the first bound: the window and the pruning follow.
    """
    P, n, R, vx, vy = pl.P, pl.n, pl.R, pl.vx, pl.vy
    phi = phase + x / R
    g0 = _piece_of(P, n, phi, hint)
    j0 = _seg_of(vx, x)
    best, bt, bg, br, bs, bx, cv, cvp = _cell(pl, g0, j0, x, phi, CLIP)
    # the seed feature's cells (a wheel point over a rail vertex shared with the cell before)
    sg0, sj0, sg1, sj1 = seed_g, -1, seed_g, -1
    if seed_t == FT_T:
        sj0 = seed_r
    elif seed_t == FT_W:
        sj0 = sj1 = seed_r
        sg1 = seed_g + 1
    elif seed_t == FT_V:
        sj0, sj1 = seed_r - 1, seed_r
    last = vx.size - 2
    pg = g0
    for sg, sj in ((sg0, sj0), (sg1, sj1)):
        if sj < 0 or sj > last or (sg == g0 and sj == j0):
            continue
        if sg != pg:
            cv, pg = -1, sg
        v, t, gg, r, s, xd, cv, cvp = _cell(pl, sg, sj, x, phi, CLIP, cv, cvp)
        if t >= 0 and v > best:
            best, bt, bg, br, bs, bx = v, t, gg, r, s, xd
    # the window of ψ that can win
    d = ymax + drg - best
    psw = math.sqrt(2.0 * max(d, 0.0) / R) * 1.01 + 1e-12
    if psw > CLIP:
        psw = CLIP
    ga = _piece_of(P, n, phi - psw, g0)
    gb = _piece_of(P, n, phi + psw, g0)
    rw = R + drg
    cpsw = math.cos(psw)
    # the last piece's end on either side: its ψ, x_D and segment
    rpsi, rx, rj = math.nan, x, j0
    lpsi, lx, lj = math.nan, x, j0
    for step in range(2 * max(g0 - ga, gb - g0) + 1):
        # pieces from the centre outward: the best so far rises early and prunes more
        g = g0 + (step + 1) // 2 if step % 2 == 1 else g0 - step // 2
        if g < ga or g > gb:
            continue
        k, sh = _shift(g, n)
        a = max(P[k, _T0] + sh - phi, -psw)
        b = min(P[k, _T1] + sh - phi, psw)
        if not a < b:
            continue
        pmin = 0.0 if a <= 0.0 <= b else min(abs(a), abs(b))
        # the largest (r - R)·cos ψ on the piece (a flat's sub-piece lies below the circle)
        dm = P[k, _DRMAX]
        top = dm if dm >= 0.0 else dm * cpsw
        if ymax + top - _drop_lb(pmin, R) < best:
            continue
        if int(P[k, _KIND]) == PIECE_CHORD:
            v, t, gg, r, s, xd = _chord_max(pl, g, x, phi, a, b, psw)
            if v > best:
                best, bt, bg, br, bs, bx = v, t, gg, r, s, xd
            continue
        # the piece's ends on the rail: an end it shares with the piece done before on its
        # side is taken from there (one wheel vertex), the segments are walked to from there
        if g >= g0 and a == rpsi:
            xa, ja = rx, rj
        else:
            dra, _, _ = _rho(P, k, R, a + phi - sh)
            xa = x + (R + dra) * math.sin(a)
            ja = _seg_from(vx, xa, rj if g > g0 else lj)
        if g <= g0 and b == lpsi:
            xb, jb = lx, lj
        else:
            drb, _, _ = _rho(P, k, R, b + phi - sh)
            xb = x + (R + drb) * math.sin(b)
            jb = _seg_from(vx, xb, ja)
        if g >= g0:
            rpsi, rx, rj = b, xb, jb
        if g <= g0:
            lpsi, lx, lj = a, xa, ja
        hav = int(P[k, _KIND]) == PIECE_HAVERSINE and P[k, _CEN] == 0.0
        hd = P[k, _C0]
        hw = TWO_PI * R / P[k, _C1] if hav else 0.0
        hhalf = 0.5 * P[k, _C1] / R
        ir = 1.0 / R
        ird = 1.0 / (R - hd)  # the 1e-9 rad margin below covers their round-off
        cv = -1  # the piece's last wheel point over a rail vertex (cv), from the cells before
        cvp = NO_POINT
        for j in range(ja, jb + 1):
            if (g == g0 and j == j0) or (g == sg0 and j == sj0) or (g == sg1 and j == sj1):
                continue  # evaluated above (on a wider clip: the same or a better value)
            # distance from x to the segment bounds |ψ| from below
            if vx[j + 1] < x:
                u = x - vx[j + 1]
            elif vx[j] > x:
                u = vx[j] - x
            else:
                u = 0.0
            bound = max(vy[j], vy[j + 1]) + top - _drop_lb(max(u / rw, pmin), R)
            if bound < best:
                continue
            if hav:
                # r - R grows with |θ| on a haversine: bound it at the segment's far wheel angle
                # (ρ in [R - d, R] puts ψ between asin(u/R) and asin(u/(R - d)))
                q0 = (vx[j] - x) * ir
                q1 = (vx[j + 1] - x) * ir
                q0d = (vx[j] - x) * ird
                q1d = (vx[j + 1] - x) * ird
                tlo = _asin_below(min(q0, q0d)) + phi - sh - 1e-9
                thi = _asin_above(max(q1, q1d)) + phi - sh + 1e-9
                tfar = min(max(abs(tlo), abs(thi)), hhalf)
                drb = min(-0.5 * hd * (1.0 + _cos_below(hw * tfar)), dm)
                bound2 = max(vy[j], vy[j + 1]) + drb * cpsw - _drop_lb(max(u / rw, pmin), R)
                if bound2 < best:
                    continue
            v, t, gg, r, s, xd, cv, cvp = _cell_scan(pl, g, k, sh, j, x, phi, a, b, xa, xb, cv, cvp)
            if v > best:
                best, bt, bg, br, bs, bx = v, t, gg, r, s, xd
    return best, bt, bg, br, bs, bx, g0


@_borrowing
def _restricted(
    pl: PolylineCase,
    phase: float,
    cells: NDArray[np.int64],
    nc: int,
    x: float,
) -> tuple[float, int, int, int, float, float]:
    """The best feature among the listed cells at x."""
    R, vx = pl.R, pl.vx
    phi = phase + x / R
    best = -np.inf
    bt = bg = br = -1
    bs = bx = 0.0
    last = vx.size - 2
    pg, cv, cvp = -1, -1, NO_POINT  # the piece of the cell before and its last wheel point
    for c in range(nc):
        j = cells[c, 1]
        if j < 0 or j > last:
            continue
        if cells[c, 0] != pg:
            cv, pg = -1, cells[c, 0]
        v, t, gg, r, s, xd, cv, cvp = _cell(pl, cells[c, 0], j, x, phi, CLIP, cv, cvp)
        if t >= 0 and v > best:
            best, bt, bg, br, bs, bx = v, t, gg, r, s, xd
    return best, bt, bg, br, bs, bx


@_borrowing
def _feature_eval(
    pl: PolylineCase,
    phase: float,
    t: int,
    g: int,
    r: int,
    x: float,
    start: float = math.nan,
) -> tuple[float, float, float, float, float]:
    """(value, slope, x_D, ψ, dψ/dx) of feature (t, g, r) at x by its own formula; value -inf
    where the feature is not a real contact candidate (its wheel point off the piece, its rail
    point off the segment), so that it never exceeds y_C^k. ``start``: a tangent's ψ at x
    predicted from a nearby x (:func:`_ahead`: the Newton's first iterate); dψ/dx: a
    tangent's (nan if not known), for the next prediction."""
    P, n, R, vx, vy, sl = pl.P, pl.n, pl.R, pl.vx, pl.vy, pl.sl
    phi = phase + x / R
    k, sh = _shift(g, n)
    if t == FT_W:
        psi = P[k, _T1] + sh - phi
        G, _, _, xd, dr, _ = _g_line(P, k, sh, R, x, phi, psi, vx[r], vy[r], sl[r])
        if xd < vx[r] - 1e-13 or xd > vx[r + 1] + 1e-13:
            return -np.inf, 0.0, xd, psi, math.nan
        return G, _slope_wheel_vertex(R, math.sin(psi), math.cos(psi), dr, sl[r]), xd, psi, math.nan
    lo = P[k, _T0] + sh - phi
    hi = P[k, _T1] + sh - phi
    if t == FT_V:
        vp = _vertex_point(P, k, sh, R, x, phi, vx[r])
        psi = vp[0]
        G, _, _, xd = _at_point(R, x, vy[r], vp)
        if psi < lo - 1e-13 or psi > hi + 1e-13:
            return -np.inf, 0.0, xd, psi, math.nan
        return G, _slope_rail_vertex(R, vp[3], vp[4], vp[1], vp[2]), xd, psi, math.nan
    lo = max(lo, -CLIP)
    hi = min(hi, CLIP)
    G, psi, xd, r1, sp, cp, dpsi = _stationary(
        P, k, sh, R, x, phi, lo, hi, vx[r], vy[r], sl[r], math.nan, math.nan, start
    )
    if not (lo <= psi <= hi) or xd < vx[r] - 1e-13 or xd > vx[r + 1] + 1e-13:
        return -np.inf, 0.0, xd, psi, math.nan
    return G, _slope_tangent(R, sp, cp, r1, sl[r]), xd, psi, dpsi


@_borrowing
def _handover(tA: int, gA: int, rA: int, tB: int, gB: int, rB: int) -> bool:
    """True if one feature is a piece's tangent and the other an end of its cell (a C¹ change)."""
    if tA != FT_T:
        if tB != FT_T:
            return False
        tA, gA, rA, tB, gB, rB = tB, gB, rB, tA, gA, rA
    if tB == FT_V:
        return gB == gA and (rB == rA or rB == rA + 1)
    if tB == FT_W:
        return rB == rA and (gB == gA or gB == gA - 1)
    return False


@_borrowing
def _handover_gap(
    pl: PolylineCase, phase: float, tA: int, gA: int, rA: int, tB: int, gB: int, rB: int, x: float
) -> float:
    """At a C¹ handover between a tangent T and an end E of its cell: a smooth function of x,
    positive where A wins and negative where B wins (G' at E's wheel point on T's segment,
    signed: the tangent point is inside the cell while G' at a lo end is > 0, at a hi end < 0)."""
    P, n, R, vx, sl = pl.P, pl.n, pl.R, pl.vx, pl.sl
    sign = 1.0
    gT, rT, tE, gE, rE = gA, rA, tB, gB, rB
    if tA != FT_T:
        sign = -1.0
        gT, rT, tE, gE, rE = gB, rB, tA, gA, rA
    phi = phase + x / R
    k, sh = _shift(gT, n)
    if tE == FT_V:
        psi = _psi_at(P, k, sh, R, x, phi, vx[rE])
        lo_end = rE == rT
    else:
        lo_end = gE == gT - 1
        psi = (P[k, _T0] if lo_end else P[k, _T1]) + sh - phi
    dr, r1, _ = _rho(P, k, R, psi + phi - sh)
    _, A, B, _ = _at_vertex(R, x, 0.0, psi, dr, r1)
    gp = sl[rT] * A + B
    return sign * (gp if lo_end else -gp)


@numba.njit(cache=True, inline="always")
def _ahead(psi: float, dpsi: float, dx: float) -> float:
    """A tangent's ψ predicted ``dx`` ahead from its ψ and dψ/dx (ψ itself if dψ/dx is nan)."""
    return psi if math.isnan(dpsi) else psi + dpsi * dx


@_borrowing
def _change_point(
    pl: PolylineCase,
    phase: float,
    handover: bool,
    tA: int,
    gA: int,
    rA: int,
    tB: int,
    gB: int,
    rB: int,
    lo: float,
    hi: float,
    flo: float,
    fhi: float,
    tol: float,
    tangents: tuple[float, float, float, float, float, float] = (
        0.0,
        math.nan,
        math.nan,
        0.0,
        math.nan,
        math.nan,
    ),
) -> tuple[float, float, tuple[float, float, float, float, float, float]]:
    """(lo, hi, tangents): the bracket [lo, hi] (width <= tol) of the change from A (f > 0) to B (f < 0) by Illinois
    false position on f: the difference of the two features' own values, or at a C¹ handover
    :func:`_handover_gap` (bisection where f is not finite; stops where f is nan, as the
    bisection on the sign did). ``tangents``: (x, ψ, dψ/dx) of A, then of B, where a tangent
    feature was last solved (:func:`_feature_eval`): its Newton starts from their prediction."""
    side = 0
    xa, psa, dpa, xb, psb, dpb = tangents
    for _ in range(200):
        if not hi - lo > tol:
            break
        if math.isfinite(flo) and math.isfinite(fhi) and flo > 0.0 > fhi:
            m = (lo * fhi - hi * flo) / (fhi - flo)
        else:
            m = 0.5 * (lo + hi)
        if not (lo < m < hi):
            m = 0.5 * (lo + hi)
        if m <= lo or m >= hi:
            break
        if handover:
            fm = _handover_gap(pl, phase, tA, gA, rA, tB, gB, rB, m)
        else:
            va, _, _, pa, da = _feature_eval(pl, phase, tA, gA, rA, m, _ahead(psa, dpa, m - xa))
            vb, _, _, pb, db = _feature_eval(pl, phase, tB, gB, rB, m, _ahead(psb, dpb, m - xb))
            if tA == FT_T and va > -np.inf:
                xa, psa, dpa = m, pa, da
            if tB == FT_T and vb > -np.inf:
                xb, psb, dpb = m, pb, db
            fm = va - vb
        if fm > 0.0:
            lo, flo = m, fm
            if side == 1:
                fhi *= 0.5
            side = 1
        elif fm < 0.0:
            hi, fhi = m, fm
            if side == -1:
                flo *= 0.5
            side = -1
        elif fm == 0.0:
            lo = hi = m
        else:  # neither feature is a candidate here
            break
    return lo, hi, (xa, psa, dpa, xb, psb, dpb)


@numba.njit(cache=True)
def _put_features(
    feats: NDArray[np.int64],
    i: int,
    tl: int,
    gl: int,
    rl: int,
    tr: int,
    gr: int,
    rr: int,
    hint: int,
) -> NDArray[np.int64]:
    """Row i of ``feats`` (grown if full): the features (type, piece, rail index) left and
    right of node i and the piece under the centre there (the next global solve's hint)."""
    feats = grow(feats, i)
    feats[i, 0] = tl
    feats[i, 1] = gl
    feats[i, 2] = rl
    feats[i, 3] = tr
    feats[i, 4] = gr
    feats[i, 5] = rr
    feats[i, 6] = hint
    return feats


@numba.njit(cache=True, nogil=True)
def sweep_kernel(
    P: NDArray[np.float64],
    R: float,
    vx: NDArray[np.float64],
    vy: NDArray[np.float64],
    sl: NDArray[np.float64],
    phase: float,
    x0: float,
    x1: float,
    nint: int,
    hermite_tol: float,
) -> NDArray[np.float64]:
    """Node rows (:mod:`sim_core.constraint.nodes`) over [x0, x1], sorted by x."""
    n = P.shape[0]
    pl = PolylineCase(P, n, R, vx, vy, sl)
    ymax = vy.max()
    drg = max(P[:, _DRMAX].max(), 0.0)
    nodes = np.zeros((2 * nint + 64, NCOL))
    feats = np.empty((2 * nint + 64, 7), np.int64)  # left (t, g, r), right (t, g, r), hint
    nn = 0
    h0 = (x1 - x0) / nint
    phi0 = phase + x0 / R
    hint = _piece_of(P, n, phi0, int(math.floor((phi0 - P[0, _T0]) / TWO_PI)) * n)  # noqa: RUF046
    pt, pg, pr = -1, 0, 0
    for i in range(nint + 1):
        xv = x0 + i * h0 if i < nint else x1
        v, t, g, r, s, xd, g0 = _global(pl, ymax, drg, phase, xv, hint, pt, pg, pr)
        pt, pg, pr = t, g, r
        hint = g0
        nodes = add_node(nodes, nn, xv, v, s, s, xd, 0.0)
        feats = _put_features(feats, nn, t, g, r, t, g, r, g0)
        nn += 1
    stack, ns = interval_stack(nn)
    cells = np.empty((8, 2), np.int64)
    for _ in range(MAX_STEPS):
        ns, ia, ib, _, xa, xb, hlen, scale = next_interval(stack, ns, nodes)
        if ia < 0:
            break
        tA, gA, rA = feats[ia, 3], feats[ia, 4], feats[ia, 5]
        tB, gB, rB = feats[ib, 0], feats[ib, 1], feats[ib, 2]
        hint = feats[ia, 6]
        same = tA == tB and gA == gB and rA == rB
        xn = math.nan
        plain = False  # True: a plain node (one feature) at xn from a global solve
        da = db = 0.0
        # a tangent feature's (x, ψ, dψ/dx) where it was last solved: A's, then B's
        tans = (xa, math.nan, math.nan, xa, math.nan, math.nan)
        if not same:
            va, _, _, pa, dpa = _feature_eval(pl, phase, tA, gA, rA, xa)
            vb, _, _, pb, dpb = _feature_eval(pl, phase, tB, gB, rB, xa)
            va2 = _feature_eval(pl, phase, tA, gA, rA, xb, _ahead(pa, dpa, xb - xa))[0]
            vb2 = _feature_eval(pl, phase, tB, gB, rB, xb, _ahead(pb, dpb, xb - xa))[0]
            da = va - vb
            db = va2 - vb2
            tans = (xa, pa, dpa, xa, pb, dpb)
            # two features within the tolerance of each other over the whole interval (a wheel
            # corner creeping over a rail vertex): where one hands over is immaterial
            same = abs(da) <= hermite_tol and abs(db) <= hermite_tol
        if not same:
            nc = _cells_of(tA, gA, rA, cells, 0)
            nc = _cells_of(tB, gB, rB, cells, nc)
            lo, hi = xa, xb
            third = False
            ho = _handover(tA, gA, rA, tB, gB, rB)
            direct = not ho
            if direct:
                direct = da >= -1e-15 and db <= 1e-15
            if direct:
                # a kink: the sign change of the difference of the two features' own values
                lo, hi, tans = _change_point(
                    pl, phase, False, tA, gA, rA, tB, gB, rB, lo, hi, da, db, 1e-13 * scale, tans
                )
            elif ho:
                # a C¹ handover: the tangent point reaching its cell's end
                fa = _handover_gap(pl, phase, tA, gA, rA, tB, gB, rB, xa)
                fb = _handover_gap(pl, phase, tA, gA, rA, tB, gB, rB, xb)
                if fa > 0.0 > fb:
                    lo, hi, _ = _change_point(
                        pl, phase, True, tA, gA, rA, tB, gB, rB, lo, hi, fa, fb, 1e-13 * scale
                    )
                    direct = True  # located: no bisection on the cells below
            while not direct and hi - lo > 1e-13 * scale:
                m = 0.5 * (lo + hi)
                if m <= lo or m >= hi:
                    break
                _, t, g, r, _, _ = _restricted(pl, phase, cells, nc, m)
                if t == tA and g == gA and r == rA:
                    lo = m
                elif t == tB and g == gB and r == rB:
                    hi = m
                else:
                    third = True
                    xn = m
                    break
            if not third:
                xs = 0.5 * (lo + hi)
                xr, pa, dpa, xr2, pb, dpb = tans
                va, sa, _, _, _ = _feature_eval(pl, phase, tA, gA, rA, xs, _ahead(pa, dpa, xs - xr))
                vb, sb, xdb, _, _ = _feature_eval(
                    pl, phase, tB, gB, rB, xs, _ahead(pb, dpb, xs - xr2)
                )
                vg, tg, gg, rg, _, _, _ = _global(pl, ymax, drg, phase, xs, hint, tA, gA, rA)
                top = max(va, vb)
                isab = (tg == tA and gg == gA and rg == rA) or (tg == tB and gg == gB and rg == rB)
                valid = va > -np.inf and vb > -np.inf
                if (vg > top + 1e-17 and not isab) or top > vg + 1e-15 or not valid:
                    xn = xs
                    third = True
                elif xa < xs < xb:
                    nodes = add_node(nodes, nn, xs, max(top, vg), sa, sb, xdb, 1.0)
                    feats = _put_features(feats, nn, tA, gA, rA, tB, gB, rB, hint)
                    ic = nn
                    nn += 1
                    stack, ns = split(stack, ns, ia, ic, ib)
                    continue
                else:
                    # the change sits on an end node: that node takes both sides' features
                    if xs - xa <= xb - xs:
                        nodes[ia, SR] = sb
                        nodes[ia, XD] = xdb
                        nodes[ia, K] = 1.0
                        feats[ia, 3] = tB
                        feats[ia, 4] = gB
                        feats[ia, 5] = rB
                    else:
                        nodes[ib, SL] = sa
                        nodes[ib, K] = 1.0
                        feats[ib, 0] = tA
                        feats[ib, 1] = gA
                        feats[ib, 2] = rA
                    stack, ns = push(stack, ns, ia, ib, 0)
                    continue
            plain = True
            if not (xa < xn < xb):
                xn = 0.5 * (xa + xb)
                if hlen <= 1.6e-12 * scale:
                    continue
        else:
            xn = 0.5 * (xa + xb)
            if hlen <= 1.6e-12 * scale:
                continue
        vg, tg, gg, rg, sg, xdg, g0 = _global(pl, ymax, drg, phase, xn, hint, tA, gA, rA)
        if not plain:
            hm, _ = hermite_midpoint(nodes, ia, ib, hlen)
            if abs(vg - hm) <= hermite_tol:
                if tg == tA and gg == gA and rg == rA:
                    continue
                # another feature at the midpoint: a split unless it only ties with A
                fa = _feature_eval(pl, phase, tA, gA, rA, xn)[0]
                if vg <= fa + hermite_tol:
                    continue
        if not (xa < xn < xb):
            continue
        nodes = add_node(nodes, nn, xn, vg, sg, sg, xdg, 0.0)
        feats = _put_features(feats, nn, tg, gg, rg, tg, gg, rg, g0)
        ic = nn
        nn += 1
        stack, ns = split(stack, ns, ia, ic, ib)
    out = nodes[:nn]
    order = np.argsort(out[:, X], kind="mergesort")
    return out[order]


def _join_round(
    sw: NDArray[np.float64],
    i: int,
    rn: NDArray[np.float64],
    R: float,
    poly: RailPolyline,
    col: int,
) -> None:
    """Node i of the sweep's rows ``sw``, a zone's end shared with a gap, given the round
    wheel's slope on the gap's side (``col``: SL at a zone's start, SR at its end; and the
    round contact point at its end): the round table's node there (the zones end at its
    nodes), else the round closed form's (smooth between the round table's nodes).

    The sweep's global solve at its end node finds one winner, and at a kink of the round
    wheel (a valley of the rail: two segments carry the wheel) which one is a tie to the last
    bit; the other side's slope taken from it made the table dip by up to ~3e-10 m under the
    true y_C^k next to the zone (found on a CPU where the rail's last bits flipped the tie).
    """
    x = float(sw[i, X])
    j = int(np.searchsorted(rn[:, X], x))
    if j < rn.shape[0] and rn[j, X] == x:
        row = rn[j]
    else:
        row = poly_points(np.array([x]), R, poly.vx, poly.vy)[0]
    sw[i, col] = row[col]
    if col == SR:
        sw[i, XD] = row[XD]
    if abs(sw[i, SL] - sw[i, SR]) > KINK_SLOPE:
        sw[i, K] = 1.0


def tabulate_polyline(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
) -> ConstraintTable:
    """An out-of-round wheel on a sampled or step rail (sim_core.constraint.polyline).

    The cell sweep inside the stretches where the wheel's out-of-roundness can reach the
    contact (all of it for a sampled outline), the round wheel's closed form elsewhere.
    """
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(resolution, 1e-3)
    x0, x1, _ = stretch(a, b, step, 0.0)
    poly = rail_polyline(rail, x0, x1, R)
    P = polyline_pieces(wheel)

    def nint(lo: float, hi: float) -> int:
        return max(math.ceil((hi - lo) / step), 2)

    if wheel.kind in ("ideal_flat", "rounded_flat"):
        zones = contact_zones(rail, R, step, wheel.flat_half_angle, phase, x0, x1)
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
    rn = np.empty((0, NCOL))
    ends = np.empty((0, NCOL))
    if any(kind == "gap" for kind, _, _ in pieces):
        rn = round_nodes(rail, R, step, x0, x1)
        cuts = np.array(
            [e for kind, c, d in pieces if kind == "gap" for e in (c, d) if e not in zone_ends]
        )
        ends = poly_points(cuts, R, poly.vx, poly.vy) if cuts.size else ends
    # the stretch's rows in order, as parts of the round table ``rn`` (source 0) and of the
    # small rows (source 1: the zones' sweeps and the gaps' exact end nodes), not copied
    small: list[NDArray[np.float64]] = []
    plan: list[tuple[int, int, int]] = []
    n_small = 0

    def take(rows: NDArray[np.float64]) -> None:
        nonlocal n_small
        small.append(rows)
        plan.append((1, n_small, n_small + rows.shape[0]))
        n_small += rows.shape[0]

    ie = 0
    for kind, c, d in pieces:
        if kind == "zone":
            sw = sweep_kernel(
                P, R, poly.vx, poly.vy, poly.slope, phase, c, d, nint(c, d), HERMITE_TOL
            )
            # a zone's end shared with a gap: the gap's side of that node is the round
            # wheel's (the sweep's global solve there sees one side only)
            if c > x0:
                _join_round(sw, 0, rn, R, poly, SL)
            if d < x1:
                _join_round(sw, sw.shape[0] - 1, rn, R, poly, SR)
            take(sw)
            continue
        if c not in zone_ends:
            take(ends[ie : ie + 1])
            ie += 1
        lo_i = int(np.searchsorted(rn[:, X], c, side="right"))
        hi_i = int(np.searchsorted(rn[:, X], d, side="left"))
        if hi_i > lo_i:
            plan.append((0, lo_i, hi_i))
        if d not in zone_ends:
            take(ends[ie : ie + 1])
            ie += 1
    rows = np.concatenate(small) if small else np.empty((0, NCOL))
    return table_from_parts(rn, rows, np.array(plan, dtype=np.int64), 0.0, resolution, step)
