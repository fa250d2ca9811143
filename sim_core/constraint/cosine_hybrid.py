"""Wheels whose cells on a cosine are only partly certified: the piece sweep wherever the
uncertified cells cannot carry the wheel; where they can, a rounded flat's uncertified cells
cut into boxes of wheel angle and rail phase (:mod:`sim_core.constraint.cosine_boxes`), else
the ψ-search.

:func:`~sim_core.constraint.cosine_cells.cell_cover` proves at most one local maximum of

    G(ψ) = y_r(x + ρ sin ψ) + ρ cos ψ - R,   ρ = r(ψ + φ),   φ = φ0 + x/R,

on most cells of a wheel's pieces for every wheel position; some (the middle of a rounded flat
whose hollow is curved less than the rail's crests) it cannot, and there G really has several
local maxima: the hollow bridges crests. A span [u0, u1] of such cells (wheel angle) can
carry the wheel only while a point of it is within ψ_max of the bottom
(:func:`~sim_core.constraint.cosine_cells.contact_angle_bound`), φ ∈ [u0 - ψ_max, u1 + ψ_max]
(mod 2π), and only where the most it can lift the centre,

    |a| + max(r - R)·cos ψ - 2R sin²(ψ/2)   (ψ: the least |ψ| of its points),

reaches the least the wheel point under the centre (ψ = 0) gives, -|a| + r(φ) - R, with the
exact ranges of r over slices of φ (:func:`_angle_windows`). These φ are the *windows*.
Outside them the sweep (:mod:`sim_core.constraint.wheel_pieces`) is exact: every cell that
can win is certified, and an uncertified one only contributes its ends, values of G that
cannot win. Inside, the ψ-search's node tabulator
(:func:`~sim_core.constraint.general.tabulate_nodes`) tabulates with an exact global solve:
the certified cells as the sweep solves them, the uncertified ones cut into boxes of wheel
angle and rail phase, each with a certified shape (:mod:`sim_core.constraint.cosine_boxes`;
within ~1e-16 m of brute force); where the boxes do not certify (a sampled outline's cells, or
a region where no shape holds), the general ψ-search (:mod:`sim_core.constraint.general`).
Either way the tabulator finds its own kinks (contact jumps between the hollow's local maxima
and the certified cells' maxima, located by bisection to ~1e-13 m). The stretches share their end nodes: the
value there is exact from both sides, the left slope is the left stretch's, the right slope
the right one's (a kink if they differ).

Worked example: the 80 mm, l²/16R-deep haversine flat (R = 0.46 m, depth 0.87 mm) on the
paper's cosine a = 0.1 mm, λ = 5 cm: its middle ±0.035 rad is not certified; ψ_max (0.069
rad) alone would give windows of 0.208 rad, the lift bound gives ±0.046 rad, 43 mm of each
2.89 m turn. Over a 6 m passage from φ0 = 0 the boxes tabulate 3 windows (the first cut
by the start), about 0.1 m, the sweep the rest:

    >>> from sim_core.rail import RailProfile
    >>> from sim_core.wheel import WheelOutline
    >>> w = WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46))
    >>> wins = contact_windows(w, RailProfile.cosine(1e-4, 0.05), 0.0, 0.0, 6.0)
    >>> [round(float(b - a), 4) for a, b in wins]
    [0.0213, 0.0426, 0.0426]
"""

from __future__ import annotations

import itertools
import math
from typing import Literal

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.cosine_boxes import box_cover, box_max
from sim_core.constraint.cosine_cells import offset_range, uncertified_spans
from sim_core.constraint.general import general_nodes, tabulate_nodes
from sim_core.constraint.nodes import HERMITE_TOL, KINK_SLOPE, SL, SR, K, stretch, table_from_nodes
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import (
    PiecesCase,
    cosine_cover,
    global_solve,
    needs_cells,
    tabulate_pieces_kernel,
)
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["WindowSolve", "contact_windows", "supports_cosine_hybrid", "tabulate_cosine_hybrid"]

WindowSolve = Literal["boxes", "search"]
"""How the windows are solved: ``"boxes"`` (the uncertified cells cut into boxes of wheel angle
and rail phase, :mod:`sim_core.constraint.cosine_boxes`; the ψ-search where they do not
certify) or ``"search"`` (the ψ-search)."""

WINDOW_MARGIN = 1e-7
"""Extra wheel angle (rad) on both sides of a window, against round-off in φ = φ0 + x/R."""


def supports_cosine_hybrid(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True if the wheel takes cells on this cosine and some of them are not certified."""
    if not needs_cells(wheel, rail):
        return False
    return uncertified_spans(cosine_cover(wheel, rail)[0]).shape[0] > 0


SLICES = 256
"""Slices of wheel angle per uncertified span in which :func:`_angle_windows` bounds its reach."""

_WINDOWS: dict[int, tuple[NDArray[np.float64], list[tuple[float, float]]]] = {}
"""Angle windows per cover (keyed by the cached cover's id, the cover kept with them)."""


def _angle_windows(wheel: WheelOutline, rail: RailProfile) -> list[tuple[float, float]]:
    """Wheel angles φ (rad, one turn) at which an uncertified cell can carry the wheel.

    A span [u0, u1] of uncertified cells can only where |u - φ| ≤ ψ_max for one of its u, and
    only where the highest it can lift the centre, |a| + max(r - R)·cos ψ - 2R sin²(ψ/2) at the
    least |ψ| it has, reaches the lowest the point under the centre (ψ = 0) can,
    -|a| + (r(φ) - R). Checked on ``SLICES`` slices of φ with the exact ranges of r - R on each.
    """
    cells, psi_max = cosine_cover(wheel, rail)
    got = _WINDOWS.get(id(cells))
    if got is not None and got[0] is cells:
        return got[1]
    R = wheel.nominal_radius
    amp = abs(float(rail.amplitude))
    out: list[tuple[float, float]] = []
    for u0, u1 in uncertified_spans(cells):
        top = offset_range(cells, R, u0, u1)[1]
        lift = amp + (top if top >= 0.0 else top * math.cos(psi_max))
        edges = np.linspace(u0 - psi_max, u1 + psi_max, SLICES + 1)
        for pa, pb in itertools.pairwise(edges.tolist()):
            near = max(0.0, pa - u1, u0 - pb)
            ub = lift - 2.0 * R * math.sin(0.5 * near) ** 2
            lb = -amp + offset_range(cells, R, pa, pb)[0]
            if ub < lb - 1e-12:
                continue
            if out and out[-1][1] >= pa:
                out[-1] = (out[-1][0], pb)
            else:
                out.append((pa, pb))
    if len(_WINDOWS) >= 64:
        _WINDOWS.clear()
    _WINDOWS[id(cells)] = (cells, out)
    return out


_BOXES: dict[int, tuple[NDArray[np.float64], NDArray[np.float64] | None]] = {}
"""Box cover per cell cover (keyed by the cached cover's id, the cover kept with it)."""


def _boxes(wheel: WheelOutline, rail: RailProfile) -> NDArray[np.float64] | None:
    """:func:`~sim_core.constraint.cosine_boxes.box_cover` of the wheel's cover, kept."""
    cells, _ = cosine_cover(wheel, rail)
    got = _BOXES.get(id(cells))
    if got is not None and got[0] is cells:
        return got[1]
    boxes = box_cover(wheel, rail, cells)
    if len(_BOXES) >= 64:
        _BOXES.clear()
    _BOXES[id(cells)] = (cells, boxes)
    return boxes


@numba.njit(cache=True)
def _window_solve(
    x: float, args: tuple[PiecesCase, float, float, NDArray[np.float64]]
) -> tuple[float, float, float]:
    """(y_C^k, ψ, x_D) at x: the certified cells (an uncertified one gives its ends) and the
    boxes. ψ is asin((x_D - x)/R), continuous along a contact branch and across the hand-over
    between a box and a cell (the node tabulator reads contact jumps from it)."""
    pc, phase, drg, B = args
    R = pc.R
    phi = phase + x / R
    hint = pc.n * math.floor((phi - pc.P[0, 0]) / (2.0 * math.pi))
    v, _, _, xd, _ = global_solve(pc, phase, drg, x, hint)
    vb, xb = box_max(B, R, pc.ra, pc.rl, pc.psi_max, x, phi)
    if vb > v:
        v, xd = vb, xb
    return v, math.asin(min(1.0, max(-1.0, (xd - x) / R))), xd


@numba.njit(cache=True)
def _window_nodes(
    x0: float, x1: float, nint: int, args: tuple[PiecesCase, float, float, NDArray[np.float64]]
) -> NDArray[np.float64]:
    """Node rows over [x0, x1] of :func:`_window_solve` (the ψ-search's node tabulator)."""
    return tabulate_nodes(_window_solve, x0, x1, nint, False, args)


def contact_windows(
    wheel: WheelOutline, rail: RailProfile, phase: float, x0: float, x1: float
) -> list[tuple[float, float]]:
    """The wheel positions in [x0, x1] (disjoint, sorted (a, b) pairs, m) where an uncertified
    cell can carry the wheel (:func:`_angle_windows`, φ = phase + x/R)."""
    R = wheel.nominal_radius
    out: list[tuple[float, float]] = []
    for p0, p1 in _angle_windows(wheel, rail):
        p0, p1 = p0 - WINDOW_MARGIN, p1 + WINDOW_MARGIN
        # turns m with phase + x/R in [p0, p1] + 2πm for some x in [x0, x1]
        m0 = math.floor((phase + x0 / R - p1) / TWO_PI)
        m1 = math.ceil((phase + x1 / R - p0) / TWO_PI)
        for m in range(m0, m1 + 1):
            a = max(R * (p0 + TWO_PI * m - phase), x0)
            b = min(R * (p1 + TWO_PI * m - phase), x1)
            if a < b:
                out.append((a, b))
    out.sort()
    merged: list[tuple[float, float]] = []
    for a, b in out:
        if merged and a <= merged[-1][1]:
            merged[-1] = (merged[-1][0], max(merged[-1][1], b))
        else:
            merged.append((a, b))
    return merged


def _join(parts: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Node rows of consecutive stretches (each sorted, each ending where the next starts)
    as one: the shared node keeps the left stretch's left slope and the right one's right
    slope, contact point and ψ columns; a kink if either says so or the slopes differ."""
    rows = [parts[0]]
    for nxt in parts[1:]:
        left = rows[-1]
        shared = nxt[0].copy()
        shared[SL] = left[-1, SL]
        shared[K] = max(left[-1, K], nxt[0, K], float(abs(shared[SL] - shared[SR]) > KINK_SLOPE))
        rows[-1] = left[:-1]
        rows.append(shared[None, :])
        rows.append(nxt[1:])
    return np.concatenate(rows)


def tabulate_cosine_hybrid(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    phase: float,
    dx: float | None,
    resolution: float,
    windows: WindowSolve = "boxes",
) -> ConstraintTable:
    """The table of the wheel on a cosine over [a, b]: the sweep on the cover's cells outside
    :func:`contact_windows`, inside the boxes' exact solve (``windows="boxes"``, if the
    uncertified cells are certified as boxes) or the ψ-search (node spacing ``dx``, default
    the resolution capped at 2 mm for the sweep and half of that in the windows, as each alone
    uses)."""
    if windows not in ("boxes", "search"):
        raise ValueError(f"cosine hybrid: windows must be 'boxes' or 'search', got {windows!r}")
    if not supports_cosine_hybrid(wheel, rail):
        raise ValueError(
            f"cosine hybrid: a {wheel.kind!r} wheel on a {rail.kind!r} rail has no uncertified cells"
        )
    R = wheel.nominal_radius
    step = float(dx) if dx is not None else min(resolution, 2e-3)
    step_search = float(dx) if dx is not None else min(0.5 * resolution, 2e-3)
    x0, x1, _ = stretch(a, b, step, 0.0)
    cells, psi_max = cosine_cover(wheel, rail)
    rc, ra, rl, _, _ = rail.compiled_args()
    boxes = _boxes(wheel, rail) if windows == "boxes" else None
    pc = PiecesCase(cells, cells.shape[0], R, rc, ra, rl, psi_max)
    drg = float(cells[:, 7].max())
    edges = [x0]
    kinds = []
    for wa, wb in contact_windows(wheel, rail, phase, x0, x1):
        if wa > edges[-1]:
            edges.append(wa)
            kinds.append(False)
        edges[-1] = wa
        edges.append(wb)
        kinds.append(True)
    if edges[-1] < x1:
        edges.append(x1)
        kinds.append(False)
    parts: list[NDArray[np.float64]] = []
    for (xa, xb), searched in zip(itertools.pairwise(edges), kinds, strict=True):
        if searched:
            nint = max(math.ceil((xb - xa) / step_search), 2)
            if boxes is not None:
                parts.append(_window_nodes(xa, xb, nint, (pc, float(phase), drg, boxes)))
            else:
                parts.append(general_nodes(wheel, rail, phase, xa, xb, nint))
        else:
            nint = max(math.ceil((xb - xa) / step), 2)
            parts.append(
                tabulate_pieces_kernel(
                    cells, R, rc, ra, rl, float(phase), xa, xb, nint, HERMITE_TOL, psi_max
                )
            )
    return table_from_nodes(_join(parts), 0.0, resolution, step)
