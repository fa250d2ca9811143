"""A rounded flat's uncertified cells on a cosine, cut in wheel angle *and* rail phase: exact without the ψ-search.

:mod:`sim_core.constraint.cosine_cells` proves a shape of

    G(ψ) = y_r(x + ρ sin ψ) + ρ cos ψ - R,   ρ = r(ψ + φ),   y_r = a·cos(kp),  p = x + ρ sin ψ,

on cells of wheel angle u for *every* wheel position x, bounding the rail's derivatives by
|y_r^(n)| ≤ |a|kⁿ. The middle of an l²/16R-deep haversine on the paper's cosine (a = 0.1 mm,
λ = 5 cm) fits no shape that way: its hollow is curved less than the rail's crests, so G'' changes
sign with the rail's phase under it, and the hollow bridges crests (several local maxima).

Here such a cell is cut into *boxes* [u0, u1] × [q0, q1] of wheel angle and rail phase q = kp
(mod 2π), and the rail's derivatives are bounded over the phase slice (y_r'' = -ak²cos q, ...),
so each box sees the sign of G'' where the rail is at a crest or a trough. With

    G''   = y_r''A² + y_r'A' + W₂
    G'''  = y_r'''A³ + 3y_r''AA' + y_r'A'' + W₃
    G'''' = y_r''''A⁴ + 6y_r'''A²A' + y_r''(3A'² + 4AA'') + y_r'A''' + W₄

(A = dp/dψ = r' sin ψ + ρ cos ψ, W_n = dⁿ(ρ cos ψ)/dψⁿ, interval arithmetic over the box and
|ψ| ≤ ψ_max) a box is certified ``CONCAVE`` / ``CONVEX`` (G''), ``RISING`` / ``FALLING`` (G''':
G'' changes sign at most once) or ``CAP`` / ``CUP`` (G'''' < 0 / > 0: G'' is concave / convex in ψ,
so it changes sign at most twice, around the root of G'''). G'' = G''' = 0 does occur in the
hollow (where the wheel's W₃ cancels the rail's y_r'''A³), which is why the third level is
needed. Boxes that fit none are halved (phase or wheel angle, whichever is wider in the
haversine's own phase units) up to ``MAX_HALVINGS`` times; if one still fits none (or the
cover needs more than ``MAX_BOXES``), :func:`box_cover` returns None and the ψ-search keeps
those windows.

At a wheel position the cell's ψ range (clipped to ψ_max) maps monotonically to the contact
point p (A > 0), so each box and rail period gives one ψ interval, its ends where p reaches the
box's phase edges (Illinois). On each interval G's sign changes of G'' are located (Illinois on
G'' or G''', closed forms for the rest), and each concave part's maximum is the root of G'
(safeguarded Newton) or an end; convex parts give their ends. The best over the boxes, with the
certified cells (the piece sweep's global solve: an uncertified cell there gives its ends
only), is y_C^k: the global solve :mod:`sim_core.constraint.cosine_hybrid` hands the ψ-search's
node tabulator (:func:`~sim_core.constraint.general.tabulate_nodes`) in its windows.

Worked example: the 80 mm, l²/16R-deep haversine (R = 0.46 m) on the paper's cosine: its
uncertified middle ±0.035 rad is certified in 22 boxes, 6 of them needing the G'''' level:

    >>> from sim_core.constraint.cosine_cells import cell_cover
    >>> from sim_core.constraint.wheel_pieces import wheel_pieces
    >>> from sim_core.rail import RailProfile
    >>> from sim_core.wheel import WheelOutline
    >>> w = WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46))
    >>> rail = RailProfile.cosine(1e-4, 0.05)
    >>> b = box_cover(w, rail, cell_cover(w, rail, wheel_pieces(w)))
    >>> b.shape[0], int((b[:, 4] == CAP).sum())
    (22, 6)
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.cosine_cells import (
    CONCAVE,
    CONVEX,
    FALLING,
    MARGIN,
    RISING,
    UNCERTIFIED,
    Interval,
    _add,
    _cos_range,
    _mul,
    _scale,
    contact_angle_bound,
)
from sim_core.constraint.roots import illinois, newton_max
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["CAP", "CUP", "box_cover", "box_max"]

CAP, CUP = 5, 6
"""Box shapes beyond cosine_cells' four: G'''' < 0 (G'' concave in ψ) and G'''' > 0."""

MAX_HALVINGS = 24
"""How often a box may be halved before the cover counts as not certified."""

MAX_BOXES = 4096
"""More boxes than this (a region where no shape holds, not a point) and the cover counts as not
certified."""

PHASE_SLICES = 16
"""Rail phase slices per period the boxes start from."""

# box table columns
_U0, _U1, _Q0, _Q1, _SHAPE, _HD, _W, _CEN = range(8)

# piece table columns and kinds (as in wheel_pieces)
_T0, _T1, _KIND, _C0, _C1, _CENP, _CONC = range(7)
_HAVERSINE = 2


def _haversine_intervals(
    row: NDArray[np.float64], R: float, u0: float, u1: float
) -> tuple[Interval, Interval, Interval, Interval, Interval]:
    """Exact intervals of (ρ, r', r'', r''', r'''') of a haversine piece over wheel angles [u0, u1]."""
    w = TWO_PI * R / row[_C1]
    hd = 0.5 * row[_C0]
    t0, t1 = w * (u0 - row[_CENP]), w * (u1 - row[_CENP])
    c = _cos_range(t0, t1)
    s = _cos_range(t0 - 0.5 * math.pi, t1 - 0.5 * math.pi)
    rho = _add((R - hd, R - hd), _scale(-hd, c))
    return (
        rho,
        _scale(hd * w, s),
        _scale(hd * w * w, c),
        _scale(-hd * w**3, s),
        _scale(-hd * w**4, c),
    )


def _box_shape(
    row: NDArray[np.float64],
    R: float,
    u0: float,
    u1: float,
    q0: float,
    q1: float,
    psi_max: float,
    ra: float,
    k: float,
) -> int:
    """The certified shape of G on the box (module docstring), -1 if none is proved."""
    rho, r1, r2, r3, r4 = _haversine_intervals(row, R, u0, u1)
    cp = (math.cos(psi_max), 1.0)
    sp = (-math.sin(psi_max), math.sin(psi_max))
    A = _add(_mul(r1, sp), _mul(rho, cp))
    A1 = _add(_add(_mul(r2, sp), _scale(2.0, _mul(r1, cp))), _scale(-1.0, _mul(rho, sp)))
    A2 = _add(
        _add(_mul(r3, sp), _scale(3.0, _mul(r2, cp))),
        _add(_scale(-3.0, _mul(r1, sp)), _scale(-1.0, _mul(rho, cp))),
    )
    A3 = _add(
        _add(_mul(r4, sp), _scale(4.0, _mul(r3, cp))),
        _add(_add(_scale(-6.0, _mul(r2, sp)), _scale(-4.0, _mul(r1, cp))), _mul(rho, sp)),
    )
    W2 = _add(_mul(_add(r2, _scale(-1.0, rho)), cp), _scale(-2.0, _mul(r1, sp)))
    W3 = _add(
        _mul(_add(r3, _scale(-3.0, r1)), cp),
        _scale(-1.0, _mul(_add(_scale(3.0, r2), _scale(-1.0, rho)), sp)),
    )
    W4 = _add(
        _mul(_add(_add(r4, _scale(-6.0, r2)), rho), cp),
        _scale(-4.0, _mul(_add(r3, _scale(-1.0, r1)), sp)),
    )
    c = _cos_range(q0, q1)
    s = _cos_range(q0 - 0.5 * math.pi, q1 - 0.5 * math.pi)
    y1, y2 = _scale(-ra * k, s), _scale(-ra * k * k, c)
    y3, y4 = _scale(ra * k**3, s), _scale(ra * k**4, c)
    AA = _mul(A, A)
    g2 = _add(_add(_mul(y2, AA), _mul(y1, A1)), W2)
    if g2[1] < -MARGIN:
        return CONCAVE
    if g2[0] > MARGIN:
        return CONVEX
    g3 = _add(
        _add(_mul(y3, _mul(AA, A)), _scale(3.0, _mul(y2, _mul(A, A1)))), _add(_mul(y1, A2), W3)
    )
    if g3[0] > MARGIN:
        return RISING
    if g3[1] < -MARGIN:
        return FALLING
    g4 = _add(
        _add(_mul(y4, _mul(AA, AA)), _scale(6.0, _mul(y3, _mul(AA, A1)))),
        _add(
            _add(_mul(y2, _add(_scale(3.0, _mul(A1, A1)), _scale(4.0, _mul(A, A2)))), _mul(y1, A3)),
            W4,
        ),
    )
    if g4[1] < -MARGIN:
        return CAP
    if g4[0] > MARGIN:
        return CUP
    return -1


def box_cover(
    wheel: WheelOutline, rail: RailProfile, cells: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """Boxes (rows: u0, u1, q0, q1, shape, d/2, 2πR/l, centre) covering the ``UNCERTIFIED``
    cells of :func:`~sim_core.constraint.cosine_cells.cell_cover`'s ``cells`` of a rounded
    flat on the cosine ``rail``; None if some box fits no shape (or a cell is not a haversine's)."""
    if rail.kind != "cosine":
        raise ValueError(f"cosine boxes: the rail must be a cosine, got a {rail.kind!r} rail")
    R = wheel.nominal_radius
    psi_max = contact_angle_bound(wheel, rail)
    ra = float(rail.amplitude)
    k = TWO_PI / rail.wavelength
    out: list[list[float]] = []
    bad = cells[cells[:, _CONC] == UNCERTIFIED]
    if np.any(bad[:, _KIND] != _HAVERSINE):
        return None
    for row in bad:
        w = TWO_PI * R / row[_C1]
        dq = TWO_PI / PHASE_SLICES
        stack = [
            (float(row[_T0]), float(row[_T1]), i * dq, (i + 1) * dq, 0)
            for i in reversed(range(PHASE_SLICES))
        ]
        while stack:
            u0, u1, q0, q1, depth = stack.pop()
            shape = _box_shape(row, R, u0, u1, q0, q1, psi_max, ra, k)
            if shape >= 0:
                out.append([u0, u1, q0, q1, float(shape), 0.5 * row[_C0], w, row[_CENP]])
                continue
            if depth >= MAX_HALVINGS or len(out) + len(stack) >= MAX_BOXES:
                return None
            if q1 - q0 >= w * (u1 - u0):
                qm = 0.5 * (q0 + q1)
                stack.append((u0, u1, qm, q1, depth + 1))
                stack.append((u0, u1, q0, qm, depth + 1))
            else:
                um = 0.5 * (u0 + u1)
                stack.append((um, u1, q0, q1, depth + 1))
                stack.append((u0, um, q0, q1, depth + 1))
    return np.array(out, dtype=np.float64).reshape(-1, 8)


# ======================================================================================
# compiled: the maximum over the boxes at one wheel position
# ======================================================================================
@numba.njit(cache=True)
def _g(
    psi: float, args: tuple[float, float, float, float, float, float, float, float]
) -> tuple[float, float, float, float, float]:
    """(G, G', G'', G''', x_D) of the haversine at ψ, args = (x, φ (base turn), R, d/2, w, centre, a, k)."""
    x, phi, R, hd, w, cen, ra, k = args
    t = w * (psi + phi - cen)
    ct, st = math.cos(t), math.sin(t)
    dr = -hd * (1.0 + ct)
    rho = R + dr
    r1, r2, r3 = hd * w * st, hd * w * w * ct, -hd * w**3 * st
    s, c = math.sin(psi), math.cos(psi)
    sh = math.sin(0.5 * psi)
    p = x + rho * s
    A = r1 * s + rho * c
    A1 = r2 * s + 2.0 * r1 * c - rho * s
    A2 = r3 * s + 3.0 * r2 * c - 3.0 * r1 * s - rho * c
    cq, sq = math.cos(k * p), math.sin(k * p)
    y0, y1, y2, y3 = ra * cq, -ra * k * sq, -ra * k * k * cq, ra * k**3 * sq
    g = y0 + dr * c - 2.0 * R * sh * sh
    g1 = y1 * A + r1 * c - rho * s
    g2 = y2 * A * A + y1 * A1 + (r2 - rho) * c - 2.0 * r1 * s
    g3 = y3 * A**3 + 3.0 * y2 * A * A1 + y1 * A2 + (r3 - 3.0 * r1) * c - (3.0 * r2 - rho) * s
    return g, g1, g2, g3, p


@numba.njit(cache=True)
def _g2(psi: float, args: Any) -> float:
    return _g(psi, args)[2]


@numba.njit(cache=True)
def _g3(psi: float, args: Any) -> float:
    return _g(psi, args)[3]


@numba.njit(cache=True)
def _p_at(psi: float, args: Any) -> float:
    base, target = args
    return _g(psi, base)[4] - target


@numba.njit(cache=True)
def _concave_max(args: Any, lo: float, hi: float) -> tuple[float, float]:
    """(max of G, x_D) over [lo, hi] where G is concave: an end or the root of G' (Newton)."""
    ga = _g(lo, args)
    if hi <= lo or ga[1] <= 0.0:
        return ga[0], ga[4]
    gb = _g(hi, args)
    if gb[1] >= 0.0:
        return gb[0], gb[4]
    _, out = newton_max(_g, lo, hi, args, 1e-16, 1e-16, False)
    return out[0], out[4]


@numba.njit(cache=True)
def _interval_max(args: Any, lo: float, hi: float, shape: int) -> tuple[float, float]:
    """(max of G, x_D) over [lo, hi] inside one box of the given shape."""
    ga = _g(lo, args)
    gb = _g(hi, args)
    best, bx = (ga[0], ga[4]) if ga[0] >= gb[0] else (gb[0], gb[4])
    if shape == CONVEX:
        return best, bx
    if shape == CONCAVE:
        return _concave_max(args, lo, hi)
    if shape in (RISING, FALLING):
        # G'' changes sign at most once: concave on the side where it is negative
        if ga[2] <= 0.0 and gb[2] <= 0.0:
            return _concave_max(args, lo, hi)
        if ga[2] >= 0.0 and gb[2] >= 0.0:
            return best, bx
        r = illinois(_g2, lo, hi, args)
        v, xd = _concave_max(args, lo, r) if ga[2] < 0.0 else _concave_max(args, r, hi)
        return (v, xd) if v > best else (best, bx)
    # CAP / CUP: G'' concave / convex in ψ, its extremum at the root of G'''
    if (ga[3] > 0.0) == (gb[3] > 0.0) or ga[3] == 0.0 or gb[3] == 0.0:
        m = lo if (ga[3] <= 0.0) == (shape == CAP) else hi
    else:
        m = illinois(_g3, lo, hi, args)
    gm2 = _g2(m, args)
    if shape == CAP:
        if gm2 <= 0.0:  # G'' <= 0 throughout
            return _concave_max(args, lo, hi)
        # concave on [lo, r1] and [r2, hi], convex between
        r1 = illinois(_g2, lo, m, args) if ga[2] < 0.0 else lo
        r2 = illinois(_g2, m, hi, args) if gb[2] < 0.0 else hi
        v1, x1 = _concave_max(args, lo, r1)
        v2, x2 = _concave_max(args, r2, hi)
        if v1 > best:
            best, bx = v1, x1
        if v2 > best:
            best, bx = v2, x2
        return best, bx
    if gm2 >= 0.0:  # CUP with G'' >= 0 throughout: convex
        return best, bx
    # concave on [r1, r2], convex outside
    r1 = illinois(_g2, lo, m, args) if ga[2] > 0.0 else lo
    r2 = illinois(_g2, m, hi, args) if gb[2] > 0.0 else hi
    v, xd = _concave_max(args, r1, r2)
    return (v, xd) if v > best else (best, bx)


@numba.njit(cache=True)
def box_max(
    B: NDArray[np.float64], R: float, ra: float, rl: float, psi_max: float, x: float, phi: float
) -> tuple[float, float]:
    """(max of G over the boxes ``B`` within |ψ| ≤ ψ_max, x_D) at wheel position x, wheel
    angle φ (any turn); (-inf, nan) if no box is within reach."""
    sh = TWO_PI * math.floor(phi / TWO_PI + 0.5)
    ph = phi - sh
    k = TWO_PI / rl
    best, bx = -math.inf, math.nan
    for i in range(B.shape[0]):
        a = max(B[i, _U0] - ph, -psi_max)
        b = min(B[i, _U1] - ph, psi_max)
        if a >= b:
            continue
        args = (x, ph, R, B[i, _HD], B[i, _W], B[i, _CEN], ra, k)
        pa = _g(a, args)[4]
        pb = _g(b, args)[4]
        q0, q1 = B[i, _Q0], B[i, _Q1]
        j0 = math.floor((k * pa - q1) / TWO_PI)
        j1 = math.ceil((k * pb - q0) / TWO_PI)
        for j in range(j0, j1 + 1):
            ta = (q0 + TWO_PI * j) / k
            tb = (q1 + TWO_PI * j) / k
            if tb <= pa or ta >= pb:
                continue
            sa = a if ta <= pa else illinois(_p_at, a, b, (args, ta))
            sb = b if tb >= pb else illinois(_p_at, a, b, (args, tb))
            if math.isnan(sa):  # p reaches the edge at a within round-off
                sa = a
            if math.isnan(sb):
                sb = b
            if sb > sa:
                v, xd = _interval_max(args, sa, sb, int(B[i, _SHAPE]))
                if v > best:
                    best, bx = v, xd
    return best, bx
