"""Wheel pieces on a cosine rail cut into cells on which G has at most one local maximum, proved by interval bounds.

The piece sweep (:mod:`sim_core.constraint.wheel_pieces`) maximises, per wheel piece,

    G(ψ) = y_r(x + ρ sin ψ) + ρ cos ψ - R,   ρ = r(ψ + φ),   y_r = a·cos(kx), k = 2π/λ.

On a cosine rail the wheel's part of G'' (W below) and the rail's part change sign
independently (a rounded flat's outline is concave in the middle and convex at its ends),
so a piece need not be unimodal. Differentiating,

    G''  = y_r''·A² + y_r'·A' + W,                        A = x_D' = r' sin ψ + ρ cos ψ
    G''' = y_r'''·A³ + 3y_r''·A·A' + y_r'·A'' + W',       W = (r'' - ρ) cos ψ - 2r' sin ψ

with |y_r^(n)| ≤ |a|kⁿ whatever the wheel position. Over a cell u ∈ [u0, u1] of the wheel angle
and |ψ| ≤ ψ_max, interval arithmetic on these closed forms bounds G'' and G''' for *every*
wheel position x. A cell is certified with one *shape* (the piece table's ``concave`` column):

- ``CONCAVE``: G'' < 0: one maximum (G' = 0, safeguarded Newton) or an end;
- ``CONVEX``: G'' > 0: the maximum is at an end;
- ``RISING`` / ``FALLING``: G''' > 0 / < 0: G'' changes sign at most once, at ψ₂ (its root,
  by Illinois at each x): G is concave on one side of ψ₂ (at most one interior maximum
  there) and convex on the other (its maximum at the cell's end on that side).

Cells that fit none are halved (down to 2⁻¹⁴ of the piece); if one still fits none, it is
``UNCERTIFIED`` (:func:`cell_cover`; :func:`certified_cells` then returns None): the sweep
takes such a case only at the wheel positions where those cells cannot carry the wheel, the
ψ-search the few cm per turn where they can (:mod:`sim_core.constraint.cosine_hybrid`). Adjacent
haversine cells of one shape are merged (each property holds pointwise, so on the union). A
sampled outline's pieces are first tried all at once (one interval for r and one for r' over
the whole outline): on a cosine curved less than about 1/R they are all CONCAVE.

ψ_max: at ψ = 0 the wheel point is at least ``|a| + depth`` below the rail's top, so the
global maximum is at least ``-|a| - depth``; a point with R(1 - cos ψ) > 2|a| + depth +
bulge is below that and never carries the wheel. The certificate covers |ψ| ≤ ψ_max (with
a margin); the sweep clips each cell to it.

What this proves: on every certified cell, at every x, G has at most one interior local
maximum in |ψ| ≤ ψ_max, found exactly; the wheel's global maximum is the best of these and
of the cell ends. Not covered: wheel angles where the rail's bound on G'' exceeds |W| and its
bound on G''' exceeds |W'|, e.g. the centre of a haversine (W' = 0 there) whose concave middle
is curved less than the rail's crests: the 80 mm, l²/16R-deep flat on the paper's a = 0.1 mm,
λ = 5 cm (its middle ±0.035 rad). There G'' = G''' = 0 does occur along the flat, so no cell
around such a point fits a shape however small; there the hollow bridges crests and G has
several local maxima. Those wheel positions go to the ψ-search
(:mod:`sim_core.constraint.cosine_hybrid`).

Worked example: an 80 mm rounded flat (depth l²/16R = 0.87 mm, R = 0.46 m) on the example
site's cosine a = 2 µm, λ = 6 cm (rail curvature at most 0.022 1/m; the flat's middle is
concave, curvature -0.5 1/m) is certified in a few cells: convex in the middle, rising/falling cells near the outline's
inflections (G'' changes sign there at a phase-dependent angle), concave towards the ends
and on the round rest; on the paper's cosine its middle is not:

    >>> from sim_core.constraint.wheel_pieces import wheel_pieces
    >>> from sim_core.rail import RailProfile
    >>> from sim_core.wheel import WheelOutline
    >>> w = WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46))
    >>> cells = certified_cells(w, RailProfile.cosine(2e-6, 0.06), wheel_pieces(w))
    >>> [int(s) for s in cells[:5, 6]]  # the haversine: CONCAVE, RISING, CONVEX, FALLING, CONCAVE
    [0, 2, 1, 3, 0]
    >>> certified_cells(w, RailProfile.cosine(1e-4, 0.05), wheel_pieces(w)) is None
    True
    >>> uncertified_spans(cell_cover(w, RailProfile.cosine(1e-4, 0.05), wheel_pieces(w))).round(3)
    array([[-0.035,  0.035]])
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = [
    "CONCAVE",
    "CONVEX",
    "FALLING",
    "RISING",
    "UNCERTIFIED",
    "cell_cover",
    "certified_cells",
    "contact_angle_bound",
    "offset_range",
    "uncertified_spans",
]

CONCAVE, CONVEX, RISING, FALLING = 0, 1, 2, 3
UNCERTIFIED = 4
"""A cell on which no shape is proved: the piece sweep must not be asked for it (its
wheel positions go to the ψ-search, :mod:`sim_core.constraint.cosine_hybrid`)."""

MAX_HALVINGS = 14
"""How often a piece may be halved before the case counts as not certified."""

MARGIN = 1e-9
"""A bound must clear zero by this much (1/m; G'' is of order R) to certify a sign."""

# piece table columns and kinds (as in wheel_pieces)
_T0, _T1, _KIND, _C0, _C1, _CEN, _CONC = range(7)
_LINEAR, _CHORD, _HAVERSINE, _ARC = 0, 1, 2, 3

Interval = tuple[float, float]


def contact_angle_bound(wheel: WheelOutline, rail: RailProfile) -> float:
    """ψ_max (rad): beyond it no wheel point can carry the wheel (module docstring), with a 1 % margin."""
    R = wheel.nominal_radius
    reach = 2.0 * abs(rail.amplitude) + wheel.max_depth + wheel.max_excess
    return 1.01 * math.acos(max(-1.0, 1.0 - reach / R)) + 1e-9


def _add(p: Interval, q: Interval) -> Interval:
    return p[0] + q[0], p[1] + q[1]


def _mul(p: Interval, q: Interval) -> Interval:
    c = (p[0] * q[0], p[0] * q[1], p[1] * q[0], p[1] * q[1])
    return min(c), max(c)


def _scale(s: float, p: Interval) -> Interval:
    return (s * p[0], s * p[1]) if s >= 0.0 else (s * p[1], s * p[0])


def _cos_range(a: float, b: float) -> Interval:
    """The range of cos over [a, b]."""
    lo = min(math.cos(a), math.cos(b))
    hi = max(math.cos(a), math.cos(b))
    if math.floor(b / TWO_PI) * TWO_PI >= a:
        hi = 1.0
    if math.floor((b - math.pi) / TWO_PI) * TWO_PI + math.pi >= a:
        lo = -1.0
    return lo, hi


def _outline(
    row: NDArray[np.float64], R: float, u0: float, u1: float
) -> tuple[Interval, Interval, Interval, Interval, Interval, Interval, Interval]:
    """Intervals of (ρ, r', r'', r''', r'' - ρ, r''' - 3r', 3r'' - ρ) over the wheel angles [u0, u1]
    of one piece (for the haversine the last three are affine in cos wt or sin wt: exact)."""
    kind = int(row[_KIND])
    zero = (0.0, 0.0)
    if kind == _HAVERSINE:
        w = TWO_PI * R / row[_C1]
        hd = 0.5 * row[_C0]
        t0, t1 = w * (u0 - row[_CEN]), w * (u1 - row[_CEN])
        c = _cos_range(t0, t1)
        s = _cos_range(t0 - 0.5 * math.pi, t1 - 0.5 * math.pi)
        rho = _add((R - hd, R - hd), _scale(-hd, c))
        r1, r2, r3 = _scale(hd * w, s), _scale(hd * w * w, c), _scale(-hd * w**3, s)
        r2_rho = _add(_scale(hd * (w * w + 1.0), c), (hd - R, hd - R))
        r3_r1 = _scale(-hd * w * (w * w + 3.0), s)
        r2_3 = _add(_scale(hd * (3.0 * w * w + 1.0), c), (hd - R, hd - R))
        return rho, r1, r2, r3, r2_rho, r3_r1, r2_3
    if kind == _LINEAR:
        b = row[_C1]
        e0 = R + row[_C0] + b * (u0 - row[_T0])
        e1 = R + row[_C0] + b * (u1 - row[_T0])
        rho = (min(e0, e1), max(e0, e1))
        return rho, (b, b), zero, zero, _scale(-1.0, rho), (-3.0 * b, -3.0 * b), _scale(-1.0, rho)
    if kind == _ARC:
        return (R, R), zero, zero, zero, (-R, -R), zero, (-R, -R)
    raise ValueError(f"cosine cells: no interval bounds for piece kind {kind}")


def _shape(
    row: NDArray[np.float64], R: float, u0: float, u1: float, psi_max: float, ra: float, k: float
) -> int:
    """The certified shape of G on the cell [u0, u1] (module docstring), -1 if none is proved.

    One cell at a time, from the scalar outline bounds (:func:`_outline`): the reference that
    :func:`_shapes` (all of a halving level's cells in one array pass, what :func:`cell_cover`
    runs) is tested against."""
    return int(_shapes_of(_one(_outline(row, R, u0, u1)), psi_max, ra, k)[0])


VInterval = tuple[NDArray[np.float64], NDArray[np.float64]]
"""Many intervals at once: their lower and their upper ends."""


def _v(p: Interval, n: int) -> VInterval:
    return np.full(n, p[0]), np.full(n, p[1])


def _vadd(p: VInterval, q: VInterval) -> VInterval:
    return p[0] + q[0], p[1] + q[1]


def _vmul(p: VInterval, q: VInterval) -> VInterval:
    a, b, c, d = p[0] * q[0], p[0] * q[1], p[1] * q[0], p[1] * q[1]
    return np.minimum(np.minimum(a, b), np.minimum(c, d)), np.maximum(
        np.maximum(a, b), np.maximum(c, d)
    )


def _vscale(s: float, p: VInterval) -> VInterval:
    return (s * p[0], s * p[1]) if s >= 0.0 else (s * p[1], s * p[0])


def _vmag(p: VInterval) -> NDArray[np.float64]:
    return np.maximum(np.abs(p[0]), np.abs(p[1]))


def _vcos_range(a: NDArray[np.float64], b: NDArray[np.float64]) -> VInterval:
    """:func:`_cos_range` of each [a_i, b_i]."""
    ca = np.array([math.cos(v) for v in a.tolist()])
    cb = np.array([math.cos(v) for v in b.tolist()])
    lo = np.minimum(ca, cb)
    hi = np.maximum(ca, cb)
    hi[np.floor(b / TWO_PI) * TWO_PI >= a] = 1.0
    lo[np.floor((b - math.pi) / TWO_PI) * TWO_PI + math.pi >= a] = -1.0
    return lo, hi


def _shapes(
    row: NDArray[np.float64],
    R: float,
    u0: NDArray[np.float64],
    u1: NDArray[np.float64],
    psi_max: float,
    ra: float,
    k: float,
) -> NDArray[np.int64]:
    """:func:`_shape` of each cell [u0_i, u1_i] of one piece, in one pass of array arithmetic
    (the same operations in the same order as :func:`_outline`, so the same shapes); -1 where
    none is proved."""
    return _shapes_of(_outline_many(row, R, u0, u1), psi_max, ra, k)


Outline = tuple[VInterval, VInterval, VInterval, VInterval, VInterval, VInterval, VInterval]
"""The seven intervals of :func:`_outline` (ρ, its derivatives and their sums), for many cells."""


def _one(
    outline: tuple[Interval, Interval, Interval, Interval, Interval, Interval, Interval],
) -> Outline:
    """A scalar outline (:func:`_outline`) as one cell of an :data:`Outline`."""
    rho, r1, r2, r3, r2_rho, r3_r1, r2_3 = (_v(p, 1) for p in outline)
    return rho, r1, r2, r3, r2_rho, r3_r1, r2_3


def _outline_many(
    row: NDArray[np.float64], R: float, u0: NDArray[np.float64], u1: NDArray[np.float64]
) -> Outline:
    """:func:`_outline` of each cell [u0_i, u1_i] of one piece."""
    n = u0.size
    kind = int(row[_KIND])
    zero = _v((0.0, 0.0), n)
    if kind == _HAVERSINE:
        w = TWO_PI * R / row[_C1]
        hd = 0.5 * row[_C0]
        t0, t1 = w * (u0 - row[_CEN]), w * (u1 - row[_CEN])
        c = _vcos_range(t0, t1)
        sn = _vcos_range(t0 - 0.5 * math.pi, t1 - 0.5 * math.pi)
        rho = _vadd(_v((R - hd, R - hd), n), _vscale(-hd, c))
        r1, r2, r3 = _vscale(hd * w, sn), _vscale(hd * w * w, c), _vscale(-hd * w**3, sn)
        r2_rho = _vadd(_vscale(hd * (w * w + 1.0), c), _v((hd - R, hd - R), n))
        r3_r1 = _vscale(-hd * w * (w * w + 3.0), sn)
        r2_3 = _vadd(_vscale(hd * (3.0 * w * w + 1.0), c), _v((hd - R, hd - R), n))
    elif kind == _LINEAR:
        b = row[_C1]
        e0 = R + row[_C0] + b * (u0 - row[_T0])
        e1 = R + row[_C0] + b * (u1 - row[_T0])
        rho = (np.minimum(e0, e1), np.maximum(e0, e1))
        r1, r2, r3 = _v((b, b), n), zero, zero
        r2_rho, r3_r1, r2_3 = _vscale(-1.0, rho), _v((-3.0 * b, -3.0 * b), n), _vscale(-1.0, rho)
    elif kind == _ARC:
        rho, r1, r2, r3 = _v((R, R), n), zero, zero, zero
        r2_rho, r3_r1, r2_3 = _v((-R, -R), n), zero, _v((-R, -R), n)
    else:
        raise ValueError(f"cosine cells: no interval bounds for piece kind {kind}")
    return rho, r1, r2, r3, r2_rho, r3_r1, r2_3


def _shapes_of(outline: Outline, psi_max: float, ra: float, k: float) -> NDArray[np.int64]:
    """The certified shape of G for each cell of ``outline``, -1 where none is proved."""
    rho, r1, r2, r3, r2_rho, r3_r1, r2_3 = outline
    n = rho[0].size
    cp = _v((math.cos(psi_max), 1.0), n)
    sp = _v((-math.sin(psi_max), math.sin(psi_max)), n)
    W = _vadd(_vmul(r2_rho, cp), _vscale(-2.0, _vmul(r1, sp)))
    Wp = _vadd(_vmul(r3_r1, cp), _vscale(-1.0, _vmul(r2_3, sp)))
    A = _vmag(_vadd(_vmul(r1, sp), _vmul(rho, cp)))
    dA = _vmag(
        _vadd(_vadd(_vmul(r2, sp), _vscale(2.0, _vmul(r1, cp))), _vscale(-1.0, _vmul(rho, sp)))
    )
    ddA = _vmag(
        _vadd(
            _vadd(_vmul(r3, sp), _vscale(3.0, _vmul(r2, cp))),
            _vadd(_vscale(-3.0, _vmul(r1, sp)), _vscale(-1.0, _vmul(rho, cp))),
        )
    )
    k1, k2, k3 = abs(ra) * k, abs(ra) * k * k, abs(ra) * k**3
    e2 = k2 * A * A + k1 * dA
    e3 = k3 * A**3 + 3.0 * k2 * A * dA + k1 * ddA
    return np.select(
        [W[1] + e2 < -MARGIN, W[0] - e2 > MARGIN, Wp[0] - e3 > MARGIN, Wp[1] + e3 < -MARGIN],
        [CONCAVE, CONVEX, RISING, FALLING],
        -1,
    ).astype(np.int64)


def _cells(
    row: NDArray[np.float64], R: float, psi_max: float, ra: float, k: float
) -> list[tuple[float, float, int]]:
    """The cells (u0, u1, shape) of one piece in order of u: halved where no shape is proved,
    each level of halving in one pass (:func:`_shapes`), down to ``MAX_HALVINGS``."""
    u0 = np.array([float(row[_T0])])
    u1 = np.array([float(row[_T1])])
    done: list[tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]] = []
    for depth in range(MAX_HALVINGS + 1):
        shape = _shapes(row, R, u0, u1, psi_max, ra, k)
        failed = shape < 0
        if depth == MAX_HALVINGS:
            shape[failed] = UNCERTIFIED
            failed[:] = False
        done.append((u0[~failed], u1[~failed], shape[~failed]))
        if not failed.any():
            break
        a, b = u0[failed], u1[failed]
        um = 0.5 * (a + b)
        u0 = np.concatenate((a, um))
        u1 = np.concatenate((um, b))
    lo = np.concatenate([d[0] for d in done])
    hi = np.concatenate([d[1] for d in done])
    sh = np.concatenate([d[2] for d in done])
    order = np.argsort(lo, kind="stable")
    return list(zip(lo[order].tolist(), hi[order].tolist(), sh[order].tolist(), strict=True))


def certified_cells(
    wheel: WheelOutline, rail: RailProfile, pieces: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """The wheel's piece table ``pieces`` (:func:`~sim_core.constraint.wheel_pieces.wheel_pieces`)
    cut into cells certified on the cosine ``rail`` (shape in column 6), or None if some cell
    is not (:func:`cell_cover` has it marked ``UNCERTIFIED``)."""
    cells = cell_cover(wheel, rail, pieces)
    return None if np.any(cells[:, _CONC] == UNCERTIFIED) else cells


def cell_cover(
    wheel: WheelOutline, rail: RailProfile, pieces: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The wheel's piece table ``pieces`` cut into cells on the cosine ``rail``, the shape of
    each in column 6: certified (``CONCAVE`` .. ``FALLING``) or ``UNCERTIFIED``.

    Ideal-flat chords are kept whole (solved per crest window, :mod:`sim_core.constraint.flat_cosine`)
    and marked ``CONCAVE`` (unused). A cell that fits no shape after ``MAX_HALVINGS`` halvings
    is ``UNCERTIFIED``; adjacent haversine cells of one shape (uncertified ones too) are merged.
    """
    if rail.kind != "cosine":
        raise ValueError(f"cosine cells: the rail must be a cosine, got a {rail.kind!r} rail")
    R = wheel.nominal_radius
    psi_max = contact_angle_bound(wheel, rail)
    ra = float(rail.amplitude)
    k = TWO_PI / rail.wavelength
    linear = pieces[:, _KIND] == _LINEAR
    if linear.any():
        # one bound for all of a sampled outline's pieces at once (r between its extremes, r'
        # between its slopes' extremes): usually enough to prove all CONCAVE without a loop
        rho = (R + float(pieces[linear, _C0].min()), R + float(pieces[linear, _C0].max()))
        b = (float(pieces[linear, _C1].min()), float(pieces[linear, _C1].max()))
        zero = (0.0, 0.0)
        envelope = (rho, b, zero, zero, _scale(-1.0, rho), _scale(-3.0, b), _scale(-1.0, rho))
        if _shapes_of(_one(envelope), psi_max, ra, k)[0] == CONCAVE:
            out = pieces.copy()
            out[linear, _CONC] = float(CONCAVE)
            if linear.all():
                return out
    out_rows: list[list[float]] = []
    for row in pieces:
        kind = int(row[_KIND])
        if kind == _CHORD:
            out_rows.append([*row[:_CONC], float(CONCAVE), *row[_CONC + 1 :]])
            continue
        for u0, u1, shape in _cells(row, R, psi_max, ra, k):
            prev = out_rows[-1] if out_rows else None
            if (
                kind == _HAVERSINE
                and prev is not None
                and prev[_KIND] == _HAVERSINE
                and prev[_CONC] == shape
                and prev[_T1] == u0
            ):
                prev[_T1] = u1  # the same shape on both: on the union too
                continue
            cell = [*row[:_CONC], float(shape), *row[_CONC + 1 :]]
            cell[_T0], cell[_T1] = u0, u1
            if kind == _LINEAR:
                cell[_C0] = row[_C0] + row[_C1] * (u0 - row[_T0])
            out_rows.append(cell)
    return np.array(out_rows, dtype=np.float64)


def uncertified_spans(cells: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rows (u0, u1): the wheel angles (rad, one turn) of :func:`cell_cover`'s ``UNCERTIFIED``
    cells, adjacent ones joined; none (shape (0, 2)) if every cell is certified."""
    spans: list[list[float]] = []
    for u0, u1 in cells[cells[:, _CONC] == UNCERTIFIED][:, [_T0, _T1]]:
        if spans and spans[-1][1] == u0:
            spans[-1][1] = float(u1)
        else:
            spans.append([float(u0), float(u1)])
    return np.array(spans, dtype=np.float64).reshape(-1, 2)


def offset_range(cells: NDArray[np.float64], R: float, a: float, b: float) -> Interval:
    """(min, max) of r - R (m) over the wheel angles [a, b] (rad, any turn, b - a < 2π) of the
    cover ``cells`` (one turn from its first θ0; exact per piece, :func:`_outline`)."""
    start = float(cells[0, _T0])
    m = math.floor((a - start) / TWO_PI)
    a, b = a - TWO_PI * m, b - TWO_PI * m
    lo, hi = math.inf, -math.inf
    t0, t1 = cells[:, _T0], cells[:, _T1]
    for shift in (0.0, TWO_PI):  # [a, b] may run past the turn's end into the next
        # only the cells that meet [a, b] (a strongly curved cosine's cover has ~10^5 cells,
        # and the windows ask for hundreds of slices: a Python pass over all of them took
        # 150 s for one table)
        for i in np.flatnonzero((t0 + shift <= b) & (t1 + shift >= a)).tolist():
            row = cells[i]
            u0, u1 = max(a, row[_T0] + shift), min(b, row[_T1] + shift)
            if u0 <= u1:
                rho = _outline(row, R, u0 - shift, u1 - shift)[0]
                lo, hi = min(lo, rho[0] - R), max(hi, rho[1] - R)
    return lo, hi
