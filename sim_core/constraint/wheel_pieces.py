"""Fast exact y_C^k for out-of-round wheels on flat and cosine rails: a sweep over the wheel's pieces.

The wheel outline is cut into *pieces* in θ on which r(θ) is one smooth formula:

- a sampled outline: one piece per sample interval, r = r_i + b_i·(θ - θ_i);
- an ideal flat: the chord r = (R - d)/cos θ and the rest of the circle;
- a rounded (haversine) flat: the haversine cut at its inflections (where the outline's
  curvature r² + 2r'² - r·r'' changes sign) and the rest of the circle.

Each piece is marked convex or concave (the sign of the outline's curvature). On a smooth
rail (flat or cosine) the objective of MODEL.md §2 restricted to one piece,

    G(ψ) = y_r(x + ρ sin ψ) + ρ cos ψ - R,  ρ = r(ψ + φ),

is unimodal on a convex piece (its maximum is where G' = 0, found by safeguarded Newton
with analytic G'', or at an end) and has its maximum at an end on a concave piece. Where
the rail's curvature can flip that (a rounded flat, or a sampled outline on a cosine curved
more than 0.1/R), the pieces are cut into *certified cells*
(:mod:`sim_core.constraint.cosine_cells`): concave, convex, or with G'' changing sign once at
an x-dependent ψ₂ (G concave on one side: the interior feature is that part's maximum, and a
vertex on the convex side stands alone), each clipped to the angles that can carry the wheel.
An ``UNCERTIFIED`` cell gives only its ends (values of G, never above its maximum): the sweep
runs on such a cover only over wheel positions where that cell cannot carry the wheel
(:mod:`sim_core.constraint.cosine_hybrid` takes the others: exactly in boxes of wheel angle and
rail phase, :mod:`sim_core.constraint.cosine_boxes`, or by the ψ-search).
y_C^k(x) is the maximum over the pieces; the winner is a *feature*:

- ``2g``: the interior of piece g (the contact point slides along it; slope by the
  envelope theorem at fixed ψ);
- ``2g + 1``: the vertex between pieces g and g + 1 (the wheel pivots on it; slope at
  fixed θ).

Pieces are numbered g over all turns (piece k of turn m is g = m·n + k), so a feature
identifies the wheel point uniquely along the stretch.

A per-position *global solve* evaluates the pieces around ψ = 0 in order of |ψ| and stops
where the upper bound ``max rail + max bulge - R(1 - cos ψ)`` cannot beat the best so far
(each piece is skipped by the same bound with its own bulge). Between two nodes whose
features differ, the change is located on closed forms: between a piece's interior and its
end vertex by the root of G'(vertex) (tangent handover, C¹: a node without kink), between
anything else by the root of the difference of the two pieces' maxima (a kink, slopes of
both features). A third feature on top at the located point splits the interval. Between
nodes of the same feature, the midpoint is solved globally (a missed feature splits it)
and compared with the cubic Hermite interpolant; misses above ``hermite_tol`` split it.
"""

from __future__ import annotations

import itertools
import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.cosine_cells import (
    CONCAVE,
    CONVEX,
    FALLING,
    RISING,
    UNCERTIFIED,
    cell_cover,
    contact_angle_bound,
)
from sim_core.constraint.flat_cosine import (
    crest_centre,
    crest_contact,
    crest_index,
    supports_flat_cosine,
)
from sim_core.constraint.nodes import (
    HERMITE_TOL,
    MAX_STEPS,
    NCOL,
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
    table_from_nodes,
)
from sim_core.constraint.roots import illinois, newton_max
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RAIL_COSINE, RAIL_FLAT, RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = [
    "PIECE_ARC",
    "PIECE_CHORD",
    "PIECE_HAVERSINE",
    "PIECE_LINEAR",
    "cosine_cover",
    "global_solve",
    "needs_cells",
    "supports",
    "tabulate_pieces",
    "tabulate_wheel_pieces",
    "wheel_pieces",
]

PIECE_LINEAR = 0
PIECE_CHORD = 1
PIECE_HAVERSINE = 2
PIECE_ARC = 3

TIE = 1e-18
"""Values (m) of two features closer than this are a tie (the change is at that end)."""

CREST = 1 << 40
"""Feature code step of a chord's crest window on a cosine: the interior of piece g in the
window of crest j is the feature 2g + CREST·j (:mod:`sim_core.constraint.flat_cosine`)."""


class PiecesCase(NamedTuple):
    """A wheel's piece table on a smooth rail, as the compiled sweep reads it."""

    P: NDArray[np.float64]
    """The piece table (:func:`wheel_pieces`)."""
    n: int
    """Pieces per turn."""
    R: float
    """Nominal radius (m)."""
    rc: int
    """Rail code (flat or cosine)."""
    ra: float
    """Rail amplitude (m)."""
    rl: float
    """Rail wavelength (m)."""
    psi_max: float
    """> 0: the pieces are cells certified for |ψ| ≤ psi_max on a cosine, their shape in the
    ``concave`` column (:mod:`sim_core.constraint.cosine_cells`); 0: plain pieces."""


# columns of the piece table
_T0, _T1, _KIND, _C0, _C1, _CEN, _CONC, _DRMAX = range(8)
_NP = 8


def _plain(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True if the wheel's own pieces are unimodal (or crest-windowed) on this rail."""
    if rail.kind == "flat" or supports_flat_cosine(wheel, rail):
        return True
    if rail.kind == "cosine" and wheel.kind == "sampled":
        k = TWO_PI / rail.wavelength
        return abs(rail.amplitude) * k * k <= 0.1 / wheel.nominal_radius
    return False


_CELLS: dict[tuple[object, ...], tuple[NDArray[np.float64], float]] = {}
"""Cell cover and ψ_max per wheel and cosine (a passage's wheel meets its rail many times)."""


def cosine_cover(wheel: WheelOutline, rail: RailProfile) -> tuple[NDArray[np.float64], float]:
    """(cells, ψ_max) of the wheel on a cosine rail (:func:`~sim_core.constraint.cosine_cells.cell_cover`:
    some may be ``UNCERTIFIED``); kept for up to 64 pairs (read-only: do not modify)."""
    key = (
        wheel.kind,
        wheel.radius,
        wheel.flat_length,
        wheel.flat_depth,
        wheel.theta.tobytes(),
        wheel.offsets.tobytes(),
        rail.amplitude,
        rail.wavelength,
    )
    try:
        return _CELLS[key]
    except KeyError:
        pass
    got = (cell_cover(wheel, rail, wheel_pieces(wheel)), contact_angle_bound(wheel, rail))
    if len(_CELLS) >= 64:  # (one dict operation each: safe between the service's threads)
        _CELLS.clear()
    _CELLS[key] = got
    return got


def _certified(wheel: WheelOutline, rail: RailProfile) -> tuple[NDArray[np.float64], float] | None:
    """:func:`cosine_cover` if every cell is certified, else None."""
    cells, psi_max = cosine_cover(wheel, rail)
    return None if np.any(cells[:, _CONC] == UNCERTIFIED) else (cells, psi_max)


def needs_cells(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True if the wheel's own pieces are not enough on this rail: a rounded flat or a sampled
    outline on a cosine the plain sweep does not cover (it takes :func:`cosine_cover`'s cells)."""
    return (
        rail.kind == "cosine"
        and wheel.kind in ("rounded_flat", "sampled")
        and not _plain(wheel, rail)
    )


def supports(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True if the piece sweep alone applies (G has at most one interior maximum on every piece or cell).

    Any out-of-round wheel on a flat rail; a sampled wheel (pieces curved like the
    wheel, 1/R) on a cosine whose curvature a(2π/λ)² is at most ``0.1/R``; an ideal flat
    on a cosine (:func:`~sim_core.constraint.flat_cosine.supports_flat_cosine`: the chord
    is cut into crest windows, each solved in closed form). A rounded flat (its G'' changes
    sign near the haversine's inflections at a phase-dependent angle) or a sampled wheel on
    any other cosine: if its pieces cut into certified cells
    (:func:`~sim_core.constraint.cosine_cells.certified_cells`). If only some cells are
    certified, the sweep still takes every wheel position the others cannot reach
    (:mod:`sim_core.constraint.cosine_hybrid`).
    """
    if wheel.kind == "round":
        return False
    if _plain(wheel, rail):
        return True
    if needs_cells(wheel, rail):
        return _certified(wheel, rail) is not None
    return False


def _haversine_inflections(R: float, ln: float, d: float) -> list[float]:
    """θ > 0 inside the haversine where the outline's curvature r² + 2r'² - r·r'' changes sign."""
    w = TWO_PI * R / ln
    half = 0.5 * ln / R

    def curv(t: float) -> float:
        r = R - 0.5 * d * (1.0 + math.cos(w * t))
        r1 = 0.5 * d * w * math.sin(w * t)
        r2 = 0.5 * d * w * w * math.cos(w * t)
        return r * r + 2.0 * r1 * r1 - r * r2

    ts = np.linspace(0.0, half, 2049)
    r = R - 0.5 * d * (1.0 + np.cos(w * ts))
    r1 = 0.5 * d * w * np.sin(w * ts)
    r2 = 0.5 * d * w * w * np.cos(w * ts)
    cs = (r * r + 2.0 * r1 * r1 - r * r2).tolist()  # curv() on the grid, vectorised
    out = []
    for i in range(ts.size - 1):
        if (cs[i] < 0.0) != (cs[i + 1] < 0.0):
            lo, hi = float(ts[i]), float(ts[i + 1])
            for _ in range(200):
                m = 0.5 * (lo + hi)
                if m <= lo or m >= hi:
                    break
                if (curv(m) < 0.0) == (cs[i] < 0.0):
                    lo = m
                else:
                    hi = m
            out.append(0.5 * (lo + hi))
    return out


def wheel_pieces(wheel: WheelOutline) -> NDArray[np.float64]:
    """The piece table (rows: θ0, θ1, kind, c0, c1, centre, concave, max r - R) of one turn.

    The pieces are contiguous and cover exactly one turn from the first θ0.
    """
    R = wheel.nominal_radius
    rows: list[list[float]] = []
    if wheel.kind == "sampled":
        th = np.append(wheel.theta, wheel.theta[0] + TWO_PI)
        dr = np.append(wheel.offsets, wheel.offsets[0])
        b = np.diff(dr) / np.diff(th)
        for i in range(th.size - 1):
            rows.append(
                [th[i], th[i + 1], PIECE_LINEAR, dr[i], b[i], 0.0, 0.0, max(dr[i], dr[i + 1])]
            )
    elif wheel.kind == "ideal_flat":
        t0 = wheel.flat_half_angle
        rows.append([-t0, t0, PIECE_CHORD, wheel.flat_depth, 0.0, 0.0, 0.0, 0.0])
        rows.append([t0, TWO_PI - t0, PIECE_ARC, 0.0, 0.0, 0.0, 0.0, 0.0])
    elif wheel.kind == "rounded_flat":
        ln, d = wheel.flat_length, wheel.flat_depth
        half = 0.5 * ln / R
        cuts = sorted(
            {-half, half, *(s * t for t in _haversine_inflections(R, ln, d) for s in (-1.0, 1.0))}
        )
        w = TWO_PI * R / ln
        for a, c in itertools.pairwise(cuts):
            m = 0.5 * (a + c)
            r = R - 0.5 * d * (1.0 + math.cos(w * m))
            r1 = 0.5 * d * w * math.sin(w * m)
            r2 = 0.5 * d * w * w * math.cos(w * m)
            conc = 1.0 if r * r + 2.0 * r1 * r1 - r * r2 < 0.0 else 0.0
            rows.append([a, c, PIECE_HAVERSINE, d, ln, 0.0, conc, 0.0])
        rows.append([half, TWO_PI - half, PIECE_ARC, 0.0, 0.0, 0.0, 0.0, 0.0])
    else:
        raise ValueError(f"constraint pieces: no pieces for a {wheel.kind!r} wheel")
    # the round part turns by almost 2π: cut it into arcs of at most π/4 (G is unimodal on each)
    out: list[list[float]] = []
    for row in rows:
        if row[2] == PIECE_ARC:
            m = math.ceil((row[1] - row[0]) / (0.25 * math.pi))
            edges = np.linspace(row[0], row[1], m + 1)
            for a, c in itertools.pairwise(edges):
                out.append([float(a), float(c), *row[2:]])
        else:
            out.append(row)
    return np.array(out, dtype=np.float64)


# ======================================================================================
# compiled kernels
# ======================================================================================
@numba.njit(cache=True, inline="always")
def _shift(g: int, n: int) -> tuple[int, float]:
    m = g // n
    return g - m * n, TWO_PI * m


@numba.njit(cache=True)
def _rho(P: NDArray[np.float64], k: int, R: float, u: float) -> tuple[float, float, float]:
    """(r - R, r', r'') of piece k at the wheel angle u (within the base turn)."""
    kind = int(P[k, _KIND])
    if kind == PIECE_LINEAR:
        return P[k, _C0] + P[k, _C1] * (u - P[k, _T0]), P[k, _C1], 0.0
    if kind == PIECE_CHORD:
        t = u - P[k, _CEN]
        s = math.sin(0.5 * t)
        c = math.cos(t)
        dr = (2.0 * R * s * s - P[k, _C0]) / c
        tn = math.tan(t)
        rho = R + dr
        return dr, rho * tn, rho * (1.0 + 2.0 * tn * tn)
    if kind == PIECE_HAVERSINE:
        t = u - P[k, _CEN]
        w = TWO_PI * R / P[k, _C1]
        hd = 0.5 * P[k, _C0]
        return -hd * (1.0 + math.cos(w * t)), hd * w * math.sin(w * t), hd * w * w * math.cos(w * t)
    return 0.0, 0.0, 0.0


@numba.njit(cache=True, inline="always")
def _rail(rc: int, ra: float, rl: float, x: float) -> tuple[float, float, float]:
    if rc == RAIL_COSINE:
        k = TWO_PI / rl
        c = math.cos(k * x)
        s = math.sin(k * x)
        return ra * c, -ra * k * s, -ra * k * k * c
    return 0.0, 0.0, 0.0


@numba.njit(cache=True)
def _obj(
    P: NDArray[np.float64],
    k: int,
    R: float,
    rc: int,
    ra: float,
    rl: float,
    x: float,
    psi: float,
    u: float,
) -> tuple[float, float, float, float, float, float, float]:
    """(G, G', G'', x_D, r - R, r', y_r') of piece k at angle ψ, wheel angle u = ψ + φ (base turn)."""
    dr, r1, r2 = _rho(P, k, R, u)
    rho = R + dr
    sp = math.sin(psi)
    cp = math.cos(psi)
    sh = math.sin(0.5 * psi)
    xd = x + rho * sp
    if rc == RAIL_FLAT:
        g = dr * cp - 2.0 * R * sh * sh
        gp = r1 * cp - rho * sp
        gpp = r2 * cp - 2.0 * r1 * sp - rho * cp
        return g, gp, gpp, xd, dr, r1, 0.0
    y, y1, y2 = _rail(rc, ra, rl, xd)
    a = r1 * sp + rho * cp
    da = r2 * sp + 2.0 * r1 * cp - rho * sp
    g = y + dr * cp - 2.0 * R * sh * sh
    gp = y1 * a + r1 * cp - rho * sp
    gpp = y2 * a * a + y1 * da + r2 * cp - 2.0 * r1 * sp - rho * cp
    return g, gp, gpp, xd, dr, r1, y1


@numba.njit(cache=True)
def _obj_at(
    psi: float, args: tuple[NDArray[np.float64], int, float, int, float, float, float, float, float]
) -> tuple[float, float, float, float, float, float, float]:
    """:func:`_obj` at ψ for args = (P, k, R, rc, ra, rl, x, φ, turn shift), for the solvers."""
    P, k, R, rc, ra, rl, x, phi, sh = args
    return _obj(P, k, R, rc, ra, rl, x, psi, psi + phi - sh)


@numba.njit(cache=True, inline="always")
def _slope_interior(R: float, psi: float, r1: float, y1: float) -> float:
    return y1 * (1.0 + r1 * math.sin(psi) / R) + r1 * math.cos(psi) / R


@numba.njit(cache=True, inline="always")
def _slope_vertex(R: float, psi: float, dr: float, y1: float) -> float:
    rho = R + dr
    return y1 * (1.0 - rho * math.cos(psi) / R) + rho * math.sin(psi) / R


@numba.njit(cache=True, inline="always")
def _decode(f: int) -> tuple[int, int]:
    """(feature without its crest, crest j) of a feature code."""
    j = (f + CREST // 2) // CREST
    return f - j * CREST, j


@numba.njit(cache=True, inline="always")
def _windowed(pc: PiecesCase, g: int) -> bool:
    """True if piece g is a chord on a cosine (solved per crest window)."""
    k, _ = _shift(g, pc.n)
    return pc.rc == RAIL_COSINE and int(pc.P[k, _KIND]) == PIECE_CHORD


@numba.njit(cache=True)
def _vertex(
    pc: PiecesCase,
    v: int,
    x: float,
    phi: float,
) -> tuple[float, float, float]:
    """(value, slope, x_D) of vertex feature v = 2g + 1 (the hi end of piece g) at x.

    A chord's corner on a cosine is taken on the arc's side (r = R exactly), as the arc
    evaluates it: the two sides of a tie then compare equal."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    g = (v - 1) // 2
    if _windowed(pc, g):
        k, sh = _shift(g + 1, n)
        u = P[k, _T0]
        psi = u + sh - phi
        G, _, _, xd, dr, _, y1 = _obj(P, k, R, rc, ra, rl, x, psi, u)
        return G, _slope_vertex(R, psi, dr, y1), xd
    k, sh = _shift(g, n)
    u = P[k, _T1]
    psi = u + sh - phi
    G, _, _, xd, dr, _, y1 = _obj(P, k, R, rc, ra, rl, x, psi, u)
    return G, _slope_vertex(R, psi, dr, y1), xd


@numba.njit(cache=True)
def _interior(
    pc: PiecesCase,
    g: int,
    x: float,
    phi: float,
    lo: float,
    hi: float,
) -> tuple[float, float, float, float]:
    """(value, slope, x_D, ψ) at the root of G' of piece g in (lo, hi) (G'(lo) > 0 > G'(hi)); safeguarded Newton."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    k, sh = _shift(g, n)
    # Newton steps to 1e-16 relative (the outline is nearly round: G'' ≈ -R)
    psi, out = newton_max(_obj_at, lo, hi, (P, k, R, rc, ra, rl, x, phi, sh), 1e-16, 1e-16, False)
    G, _, _, xd, _, r1, y1 = out
    return G, _slope_interior(R, psi, r1, y1), xd, psi


@numba.njit(cache=True)
def _chord_window(
    pc: PiecesCase,
    g: int,
    j: int,
    x: float,
    phi: float,
) -> tuple[float, int, float, float]:
    """(max over the chord g inside crest j's concave window, feature, slope, x_D) at x; -inf
    if the chord does not reach the window. G is concave there: the maximum is at a corner
    (vertex feature), at the crest's contact (interior feature 2g + CREST·j) or at a rail
    inflection (same code: never the wheel's contact, G rises beyond it)."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    k, sh = _shift(g, n)
    lo = P[k, _T0] + sh - phi
    hi = P[k, _T1] + sh - phi
    G0, s0, xd0 = _vertex(pc, 2 * g - 1, x, phi)
    G1, s1, xd1 = _vertex(pc, 2 * g + 1, x, phi)
    d0 = R * math.cos(lo)
    m = (R * math.cos(hi) - d0) / (xd1 - xd0)
    c = crest_centre(ra, rl, j)
    wa = max(xd0, c - 0.25 * rl)
    wb = min(xd1, c + 0.25 * rl)
    fi = 2 * g + CREST * j
    best, bf, bs, bx = -math.inf, fi, 0.0, 0.0
    if wa >= wb:
        return best, bf, bs, bx
    u = crest_contact(m, ra, rl)
    for i in range(3):
        if i == 0:
            xw = wa
        elif i == 1:
            xw = wb
        else:
            xw = c + u
            if not (wa < xw < wb):  # false for nan
                continue
        if i < 2 and xw == (xd0 if i == 0 else xd1):
            v, f, s = (G0, 2 * g - 1, s0) if i == 0 else (G1, 2 * g + 1, s1)
        else:
            psi = math.atan2(xw - x, d0 + m * (xw - xd0))
            v, _, _, xw, _, r1, y1 = _obj(P, k, R, rc, ra, rl, x, psi, psi + phi - sh)
            f, s = fi, _slope_interior(R, psi, r1, y1)
        if v > best:
            best, bf, bs, bx = v, f, s, xw
    return best, bf, bs, bx


@numba.njit(cache=True)
def _gpp_at(
    psi: float, args: tuple[NDArray[np.float64], int, float, int, float, float, float, float, float]
) -> float:
    """G'' of :func:`_obj_at` (its root splits a RISING or FALLING cell)."""
    return _obj_at(psi, args)[2]


@numba.njit(cache=True)
def _concave_span(pc: PiecesCase, g: int, x: float, phi: float) -> tuple[float, float]:
    """(a, b): the ψ range of certified cell g within |ψ| ≤ ψ_max where G is concave at x.

    a == b: none, the point where it would start (the concave side's end: the part's maximum
    stays continuous in x); nan if the cell is convex or outside |ψ| ≤ ψ_max."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    k, sh = _shift(g, n)
    a = max(P[k, _T0] + sh - phi, -pc.psi_max)
    b = min(P[k, _T1] + sh - phi, pc.psi_max)
    shape = int(P[k, _CONC])
    if a >= b or shape in (CONVEX, UNCERTIFIED):
        # (an UNCERTIFIED cell gives its ends only: values of G that never exceed its maximum,
        # for callers that take it only where it cannot carry the wheel)
        return math.nan, math.nan
    if shape == CONCAVE:
        return a, b
    args = (P, k, R, rc, ra, rl, x, phi, sh)
    ga = _gpp_at(a, args)
    gb = _gpp_at(b, args)
    if shape == RISING:  # concave left of the root
        if ga >= 0.0:
            return a, a
        if gb <= 0.0:
            return a, b
        return a, illinois(_gpp_at, a, b, args)
    if gb >= 0.0:  # FALLING: concave right of the root
        return b, b
    if ga <= 0.0:
        return a, b
    return illinois(_gpp_at, a, b, args), b


@numba.njit(cache=True)
def _concave_max(
    pc: PiecesCase, g: int, x: float, phi: float, a: float, b: float
) -> tuple[float, int, float, float]:
    """(max of G over [a, b] where it is concave, feature, slope, x_D) on cell g at x: an
    end or the root of G' (safeguarded Newton); a cell end is its vertex feature."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    k, sh = _shift(g, n)
    lo = P[k, _T0] + sh - phi
    hi = P[k, _T1] + sh - phi
    args = (P, k, R, rc, ra, rl, x, phi, sh)
    # a cell end at its exact wheel angle (as its vertex evaluates it: ties compare equal)
    oa = _obj(P, k, R, rc, ra, rl, x, a, P[k, _T0] if a == lo else a + phi - sh)
    psi, out = a, oa
    if b > a and oa[1] > 0.0:
        ob = _obj(P, k, R, rc, ra, rl, x, b, P[k, _T1] if b == hi else b + phi - sh)
        if ob[1] >= 0.0:
            psi, out = b, ob
        else:
            psi, out = newton_max(_obj_at, a, b, args, 1e-16, 1e-16, False)
    G, _, _, xd, dr, r1, y1 = out
    if psi == lo:
        return G, 2 * g - 1, _slope_vertex(R, psi, dr, y1), xd
    if psi == hi:
        return G, 2 * g + 1, _slope_vertex(R, psi, dr, y1), xd
    return G, 2 * g, _slope_interior(R, psi, r1, y1), xd


@numba.njit(cache=True)
def _cell_max(pc: PiecesCase, g: int, x: float, phi: float) -> tuple[float, int, float, float]:
    """(max over certified cell g, feature, slope, x_D) at x: its concave part's maximum or an
    end (a convex part's maximum is at its ends: a cell end, the concave part's end, or a
    point beyond ψ_max, which cannot carry the wheel and is skipped)."""
    a, b = _concave_span(pc, g, x, phi)
    if math.isnan(a):  # convex, or beyond ψ_max: the ends
        G0, s0, xd0 = _vertex(pc, 2 * g - 1, x, phi)
        G1, s1, xd1 = _vertex(pc, 2 * g + 1, x, phi)
        if G0 >= G1:
            return G0, 2 * g - 1, s0, xd0
        return G1, 2 * g + 1, s1, xd1
    best, bf, bs, bx = _concave_max(pc, g, x, phi, a, b)
    k, sh = _shift(g, pc.n)
    lo = pc.P[k, _T0] + sh - phi
    hi = pc.P[k, _T1] + sh - phi
    if b < hi <= pc.psi_max:  # a convex part up to the cell's hi end
        v, s, xd = _vertex(pc, 2 * g + 1, x, phi)
        if v > best:
            best, bf, bs, bx = v, 2 * g + 1, s, xd
    if -pc.psi_max <= lo < a:  # a convex part from the cell's lo end
        v, s, xd = _vertex(pc, 2 * g - 1, x, phi)
        if v > best:
            best, bf, bs, bx = v, 2 * g - 1, s, xd
    return best, bf, bs, bx


@numba.njit(cache=True)
def _cell_group(
    pc: PiecesCase, g: int, f: int, x: float, phi: float
) -> tuple[float, int, float, float]:
    """Feature f's share of certified cell g at x, continuous in x: the interior 2g is the concave
    part's maximum; a vertex of g is that too if the concave part reaches it (a CONCAVE cell, the
    lo end of a RISING, the hi end of a FALLING one), else the vertex alone."""
    a, b = _concave_span(pc, g, x, phi)
    k, _ = _shift(g, pc.n)
    shape = int(pc.P[k, _CONC])
    if f == 2 * g:
        if math.isnan(a):
            return _cell_max(pc, g, x, phi)
        return _concave_max(pc, g, x, phi, a, b)
    lo_end = f == 2 * g - 1
    attached = shape == CONCAVE or (shape == RISING and lo_end) or (shape == FALLING and not lo_end)
    if attached and not math.isnan(a):
        return _concave_max(pc, g, x, phi, a, b)
    v, s, xd = _vertex(pc, f, x, phi)
    return v, f, s, xd


@numba.njit(cache=True)
def _pmax(
    pc: PiecesCase,
    g: int,
    x: float,
    phi: float,
) -> tuple[float, int, float, float]:
    """(max over piece g, feature, slope, x_D) at x."""
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    k, sh = _shift(g, n)
    u0 = P[k, _T0]
    u1 = P[k, _T1]
    lo = u0 + sh - phi
    hi = u1 + sh - phi
    if rc == RAIL_COSINE and int(P[k, _KIND]) == PIECE_CHORD:
        # the corners (G is convex between the crests' concave windows), then each window
        # in closed form
        G0, s0, xa = _vertex(pc, 2 * g - 1, x, phi)
        G1, s1, xb = _vertex(pc, 2 * g + 1, x, phi)
        best, bf, bs, bx = G0, 2 * g - 1, s0, xa
        if best < G1:
            best, bf, bs, bx = G1, 2 * g + 1, s1, xb
        for j in range(crest_index(ra, rl, xa), crest_index(ra, rl, xb) + 1):
            v, f, s, xd = _chord_window(pc, g, j, x, phi)
            if v > best:
                best, bf, bs, bx = v, f, s, xd
        return best, bf, bs, bx
    if pc.psi_max > 0.0:
        return _cell_max(pc, g, x, phi)
    if rc == RAIL_FLAT and int(P[k, _KIND]) == PIECE_LINEAR:
        # G' = b cos ψ - ρ sin ψ: the maximum is at tan ψ = b/ρ(ψ + φ) (a contraction, factor
        # (b/ρ)² ~ 1e-5) clamped to the piece (G is unimodal on it)
        b = P[k, _C1]
        c0 = P[k, _C0] - b * u0
        psi = 0.0
        for _ in range(3):
            psi = math.atan2(b, R + c0 + b * (psi + phi - sh))
        if psi <= lo:
            psi = lo
            f = 2 * g - 1
        elif psi >= hi:
            psi = hi
            f = 2 * g + 1
        else:
            f = 2 * g
        dr = c0 + b * (psi + phi - sh) if f == 2 * g else (P[k, _C0] if f < 2 * g else c0 + b * u1)
        sp = math.sin(psi)
        s2 = math.sin(0.5 * psi)
        cp = 1.0 - 2.0 * s2 * s2
        G = dr * cp - 2.0 * R * s2 * s2
        if f == 2 * g:
            return G, f, b * cp / R, x + (R + dr) * sp
        return G, f, (R + dr) * sp / R, x + (R + dr) * sp
    G0, gp0, _, xd0, dr0, _, y10 = _obj(P, k, R, rc, ra, rl, x, lo, u0)
    G1, gp1, _, xd1, dr1, _, y11 = _obj(P, k, R, rc, ra, rl, x, hi, u1)
    if P[k, _CONC] > 0.0 or gp0 <= 0.0 or gp1 >= 0.0:
        if G0 >= G1:
            return G0, 2 * g - 1, _slope_vertex(R, lo, dr0, y10), xd0
        return G1, 2 * g + 1, _slope_vertex(R, hi, dr1, y11), xd1
    G, s, xd, _ = _interior(pc, g, x, phi, lo, hi)
    return G, 2 * g, s, xd


@numba.njit(cache=True)
def _piece_of(P: NDArray[np.float64], n: int, theta: float, hint: int) -> int:
    """The global piece g whose θ range holds θ (walking from ``hint``)."""
    g = hint
    for _ in range(4 * n + 8):
        k, sh = _shift(g, n)
        if P[k, _T0] + sh > theta:
            g -= 1
        elif P[k, _T1] + sh <= theta:
            g += 1
        else:
            return g
    return g


@numba.njit(cache=True, inline="always")
def _drop(psi: float, R: float) -> float:
    """A lower bound of R(1 - cos ψ)."""
    p2 = psi * psi
    return R * p2 * (0.5 - p2 / 24.0)


@numba.njit(cache=True)
def _global(
    pc: PiecesCase,
    phase: float,
    drg: float,
    x: float,
    hint: int,
) -> tuple[float, int, float, float, int]:
    """(y_C^k, feature, slope, x_D, piece under the centre) at x: all pieces that can win."""
    P, n, R, rc, ra = pc.P, pc.n, pc.R, pc.rc, pc.ra
    phi = phase + x / R
    g0 = _piece_of(P, n, phi, hint)
    ymax = abs(ra) if rc == RAIL_COSINE else 0.0
    best, bf, bs, bx = _pmax(pc, g0, x, phi)
    for direction in (1, -1):
        g = g0 + direction
        for _ in range(n):
            k, sh = _shift(g, n)
            pm = P[k, _T0] + sh - phi if direction > 0 else phi - P[k, _T1] - sh
            if pm > 1.5:
                break
            dp = _drop(pm, R)
            if ymax + drg - dp < best:
                break
            dm = P[k, _DRMAX]
            top = dm if dm >= 0.0 else 0.5 * dm
            if ymax + top - dp >= best:
                v, f, s, xd = _pmax(pc, g, x, phi)
                if v > best:
                    best, bf, bs, bx = v, f, s, xd
            g += direction
    return best, bf, bs, bx, g0


global_solve = _global
"""The per-position global solve (y_C^k, feature, slope, x_D, piece under the centre) for
other tabulators (:mod:`sim_core.constraint.cosine_hybrid`)."""


@numba.njit(cache=True)
def _feature(
    pc: PiecesCase,
    phase: float,
    f: int,
    x: float,
) -> tuple[float, float, float, int]:
    """(value, slope, x_D, feature actually taken) of feature f's piece group at x.

    A vertex's group is its two pieces, an interior's group its piece: the maximum over the
    group (continuous and piecewise smooth in x), with the feature that attains it. A chord on
    a cosine counts by crest windows: an interior's group is its window, and a vertex's group
    has the vertex itself in place of the chord.
    """
    R = pc.R
    phi = phase + x / R
    base, j = _decode(f)
    if base % 2 == 0:
        if _windowed(pc, base // 2):
            v, ff, s, xd = _chord_window(pc, base // 2, j, x, phi)
        elif pc.psi_max > 0.0:
            v, ff, s, xd = _cell_group(pc, base // 2, base, x, phi)
        else:
            v, ff, s, xd = _pmax(pc, base // 2, x, phi)
        return v, s, xd, ff
    g = (base - 1) // 2
    best, bf, bs, bx = -math.inf, f, 0.0, 0.0
    for gg in (g, g + 1):
        if _windowed(pc, gg):
            v, s, xd = _vertex(pc, base, x, phi)
            ff = base
        elif pc.psi_max > 0.0:
            v, ff, s, xd = _cell_group(pc, gg, base, x, phi)
        else:
            v, ff, s, xd = _pmax(pc, gg, x, phi)
        if v > best:
            best, bf, bs, bx = v, ff, s, xd
    return best, bs, bx, bf


@numba.njit(cache=True)
def _edge_dg(x: float, args: tuple[PiecesCase, float, int, bool]) -> float:
    """G' of piece g at its end (hi or lo) at x, args = (pieces, phase, g, hi end): the
    interior ↔ end vertex handover is its root."""
    pc, phase, g, hi_end = args
    P, n, R, rc, ra, rl = pc.P, pc.n, pc.R, pc.rc, pc.ra, pc.rl
    phi = phase + x / R
    k, sh = _shift(g, n)
    u = P[k, _T1] if hi_end else P[k, _T0]
    _, gp, _, _, _, _, _ = _obj(P, k, R, rc, ra, rl, x, u + sh - phi, u)
    return gp


@numba.njit(cache=True)
def _root_edge(
    pc: PiecesCase,
    phase: float,
    g: int,
    hi_end: bool,
    xa: float,
    xb: float,
) -> float:
    """Root of :func:`_edge_dg` in [xa, xb] (closed form on a flat rail, else Illinois); nan if no sign change."""
    P, n, R, rc = pc.P, pc.n, pc.R, pc.rc
    k, sh = _shift(g, n)
    if rc == RAIL_FLAT and int(P[k, _KIND]) == PIECE_LINEAR:
        # G' = b cos ψ - ρ sin ψ = 0: ψ = atan(b/ρ) at the vertex, φ = θ_v - ψ
        u = P[k, _T1] if hi_end else P[k, _T0]
        dr = P[k, _C0] + P[k, _C1] * (u - P[k, _T0])
        xt = R * (u + sh - math.atan2(P[k, _C1], R + dr) - phase)
        if xa <= xt <= xb:
            return xt
    return illinois(_edge_dg, xa, xb, (pc, phase, g, hi_end))


@numba.njit(cache=True)
def _root_cross(
    pc: PiecesCase,
    phase: float,
    fA: int,
    fB: int,
    xa: float,
    xb: float,
) -> float:
    """Where feature group B overtakes group A in [xa, xb]; nan if the difference keeps its sign."""
    va = _feature(pc, phase, fA, xa)[0] - _feature(pc, phase, fB, xa)[0]
    vb = _feature(pc, phase, fA, xb)[0] - _feature(pc, phase, fB, xb)[0]
    if va <= TIE:
        return xa if va >= -TIE else math.nan
    if vb >= -TIE:
        return xb if vb <= TIE else math.nan
    a, b = xa, xb
    m = (a * vb - b * va) / (vb - va)
    for _ in range(100):
        if not (a < m < b):
            m = 0.5 * (a + b)
        fa_ = _feature(pc, phase, fA, m)
        fb_ = _feature(pc, phase, fB, m)
        vm = fa_[0] - fb_[0]
        if vm == 0.0:
            return m
        if vm > 0.0:
            a = m
        else:
            b = m
        if b - a <= 2e-16 * max(1.0, abs(a)):
            break
        dm = fa_[1] - fb_[1]
        step = -vm / dm if dm != 0.0 else math.inf
        nxt = m + step
        if abs(step) <= 1e-16 * max(1.0, abs(m)):
            return nxt if a <= nxt <= b else m
        m = nxt
    return 0.5 * (a + b)


@numba.njit(cache=True, nogil=True)
def tabulate_pieces_kernel(
    P: NDArray[np.float64],
    R: float,
    rc: int,
    ra: float,
    rl: float,
    phase: float,
    x0: float,
    x1: float,
    nint: int,
    hermite_tol: float,
    psi_max: float,
) -> NDArray[np.float64]:
    """Node rows (:mod:`sim_core.constraint.nodes`) over [x0, x1], sorted by x (``psi_max``:
    :attr:`PiecesCase.psi_max`)."""
    n = P.shape[0]
    pc = PiecesCase(P, n, R, rc, ra, rl, psi_max)
    drg = P[:, _DRMAX].max()
    nodes = np.zeros((4 * nint + 64, NCOL))
    feats = np.empty((4 * nint + 64, 3), np.int64)  # feature left, feature right, piece hint
    nn = 0
    h0 = (x1 - x0) / nint
    hint = _piece_of(P, n, phase + x0 / R, 0 if phase + x0 / R >= P[0, _T0] else -1)
    # ---------------------------------------------------------------- grid
    for i in range(nint + 1):
        xv = x0 + i * h0 if i < nint else x1
        v, f, s, xd, g0 = _global(pc, phase, drg, xv, hint)
        hint = g0
        nodes = add_node(nodes, nn, xv, v, s, s, xd, 0.0)
        feats[nn, 0] = f
        feats[nn, 1] = f
        feats[nn, 2] = g0
        nn += 1
    # ---------------------------------------------------------------- intervals
    stack, ns = interval_stack(nn)
    for _ in range(MAX_STEPS):
        ns, ia, ib, retry, xa, xb, h, scale = next_interval(stack, ns, nodes)
        if ia < 0:
            break
        fA = feats[ia, 1]
        fB = feats[ib, 0]
        hint = feats[ia, 2]
        # the new node: x, value, slopes, x_D, features, kink
        xn = math.nan
        vn = sl = sr = xdn = kn = 0.0
        fl = fr = 0
        if fA != fB:
            xt = math.nan
            bA, bB = _decode(fA)[0], _decode(fB)[0]
            if abs(bA - bB) == 1:
                # tangent handover between a piece's interior and its end vertex
                g = bA // 2 if bA % 2 == 0 else bB // 2
                vtx = bB if bA % 2 == 0 else bA
                xt = _root_edge(pc, phase, g, vtx == 2 * g + 1, xa, xb)
                if not math.isnan(xt):
                    vv, ss, xdv = _vertex(pc, vtx, xt, phase + xt / R)
                    vg, fg, sg, xdg, g0 = _global(pc, phase, drg, xt, hint)
                    if vg <= vv + 1e-15:
                        xn, vn, sl, sr, xdn, fl, fr = xt, vv, ss, ss, xdv, fA, fB
                    elif fg != fA and fg != fB:
                        xn, vn, sl, sr, xdn, fl, fr = xt, vg, sg, sg, xdg, fg, fg
                    # else G' = 0 at a vertex that does not carry the wheel (a chord's corner
                    # outside its crest window on a cosine): the change is a jump, found below
                    hint = g0
            if math.isnan(xn):
                xt = _root_cross(pc, phase, fA, fB, xa, xb)
                if not math.isnan(xt):
                    va, sa, _, ffa = _feature(pc, phase, fA, xt)
                    vb, sb, xdb, ffb = _feature(pc, phase, fB, xt)
                    vg, fg, sg, xdg, g0 = _global(pc, phase, drg, xt, hint)
                    hint = g0
                    top = max(va, vb)
                    if fg != ffa and fg != ffb and vg > top + 1e-15:
                        xn, vn, sl, sr, xdn, fl, fr = xt, vg, sg, sg, xdg, fg, fg
                    else:
                        xn, vn, sl, sr, xdn, fl, fr = xt, top, sa, sb, xdb, ffa, ffb
                        kn = 1.0
            if not math.isnan(xn) and xn <= xa and fr != fA and retry < 4:
                # the change is at xa itself: it becomes the right side of node ia
                if kn > 0.0:
                    nodes[ia, SR] = sr
                    nodes[ia, K] = 1.0
                nodes[ia, XD] = xdn
                feats[ia, 1] = fr
                stack, ns = push(stack, ns, ia, ib, retry + 1)
                continue
            if not math.isnan(xn) and xn >= xb and fl != fB and retry < 4:
                if kn > 0.0:
                    nodes[ib, SL] = sl
                    nodes[ib, K] = 1.0
                feats[ib, 0] = fl
                stack, ns = push(stack, ns, ia, ib, retry + 1)
                continue
            if math.isnan(xn) or not (xa < xn < xb):
                if h <= 1e-12 * scale:
                    continue
                # no closed-form change found: split at the midpoint
                xn = 0.5 * (xa + xb)
                vg, fg, sg, xdg, g0 = _global(pc, phase, drg, xn, hint)
                vn, sl, sr, xdn, fl, fr, kn, hint = vg, sg, sg, xdg, fg, fg, 0.0, g0
        elif h > 4.0 * 4e-13 * scale:
            m = 0.5 * (xa + xb)
            vg, fg, sg, xdg, g0 = _global(pc, phase, drg, m, hint)
            # the Hermite slope at m too: an error odd about m (the contact sliding fast near a
            # nearly conforming trough) is 0 there in value, but ~h/8 times its slope miss beside
            hm, dm = hermite_midpoint(nodes, ia, ib, h)
            if fg != fA or abs(vg - hm) > hermite_tol or 0.125 * h * abs(sg - dm) > hermite_tol:
                xn, vn, sl, sr, xdn, fl, fr, hint = m, vg, sg, sg, xdg, fg, fg, g0
            else:
                continue
        else:
            continue
        nodes = add_node(nodes, nn, xn, vn, sl, sr, xdn, kn)
        feats = grow(feats, nn)
        feats[nn, 0] = fl
        feats[nn, 1] = fr
        feats[nn, 2] = hint
        ic = nn
        nn += 1
        stack, ns = split(stack, ns, ia, ic, ib)
    out = nodes[:nn]
    order = np.argsort(out[:, X], kind="mergesort")
    return out[order]


def tabulate_pieces(
    wheel: WheelOutline,
    rail: RailProfile,
    x0: float,
    x1: float,
    nint: int,
    phase: float,
    hermite_tol: float,
) -> NDArray[np.float64]:
    """Node rows (:mod:`sim_core.constraint.nodes`) of y_C^k over [x0, x1] by the piece sweep.

    ``nint`` grid intervals to start from (refined where needed).
    """
    if not supports(wheel, rail):
        raise ValueError(
            f"constraint pieces: not for a {wheel.kind!r} wheel on a {rail.kind!r} rail"
        )
    if _plain(wheel, rail):
        P, psi_max = wheel_pieces(wheel), 0.0
    else:
        cells = _certified(wheel, rail)
        if cells is None:
            raise ValueError(
                f"constraint pieces: the {wheel.kind!r} wheel's pieces are not certified on this cosine"
            )
        P, psi_max = cells
    rc, ra, rl, _, _ = rail.compiled_args()
    return tabulate_pieces_kernel(
        P,
        wheel.nominal_radius,
        rc,
        ra,
        rl,
        float(phase),
        float(x0),
        float(x1),
        int(nint),
        float(hermite_tol),
        psi_max,
    )


def tabulate_wheel_pieces(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
) -> ConstraintTable:
    """The table of an out-of-round wheel on a flat or cosine rail over [a, b] by the piece
    sweep (node spacing ``dx``, default the resolution capped at 2 mm; one turn on a flat rail)."""
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(resolution, 2e-3)
    periodic = TWO_PI * R if rail.kind == "flat" else 0.0
    x0, x1, _ = stretch(a, b, step, periodic)
    nint = max(math.ceil((x1 - x0) / step), 4)
    nodes = tabulate_pieces(wheel, rail, x0, x1, nint, phase, HERMITE_TOL)
    if periodic > 0:
        # both ends are the same point: the left slope comes from the last node, the right from the first
        nodes[0, SL] = nodes[-1, SL]
        nodes[-1, SR] = nodes[0, SR]
        nodes[0, K] = max(nodes[0, K], nodes[-1, K])
    return table_from_nodes(nodes, periodic, resolution, step)
