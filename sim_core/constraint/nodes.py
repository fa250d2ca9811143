"""Node rows shared by the tabulators, and the table made from them.

Every compiled tabulator of this package returns *node rows*: one row per node with
the columns ``X`` (wheel position, m), ``V`` (y_C^k, m), ``SL``/``SR`` (slopes left and
right), ``XD`` (contact point, m), ``PL``/``PR``/``GL``/``GR`` (the general search's
contact angle ψ and dψ/dx on both sides) and ``K`` (1 at a kink); a round wheel's rows on a
polyline have the first five and the kink flag only (``ROUND_NCOL``, ``ROUND_K``).
:func:`table_from_nodes` turns them into a :class:`~sim_core.constraint.table.ConstraintTable`.

Worked example: two nodes 1 mm apart, 1 µm up with slope 1e-3 (a straight line) make a
two-node table that is exact in between:

    >>> rows = np.zeros((2, NCOL))
    >>> rows[:, X] = [0.0, 1e-3]
    >>> rows[:, V] = [0.0, 1e-6]
    >>> rows[:, SL] = rows[:, SR] = 1e-3
    >>> t = table_from_nodes(rows, 0.0, 1e-3, 1e-3)
    >>> round(float(t.evaluate(np.array([5e-4]))[0]) * 1e6, 12), t.kinks.size
    (0.5, 0)
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline

MAX_RESOLUTION = 0.01
"""Upper bound of a table's ``resolution`` (m) when the inputs have no finer feature."""

HERMITE_TOL = 1e-13
"""Largest accepted miss (m) of the Hermite interpolant at an interval's midpoint."""

KINK_SLOPE = 1e-7
"""Slope jumps at or below this are treated as round-off: no kink, the mean slope on both sides
(a Hermite error of at most ~h·1e-7/8 m if such a jump were real)."""

X, V, SL, SR, XD, PL, PR, GL, GR, K = range(10)
"""Columns of a node row."""
NCOL = 10
ROUND_NCOL = 6
"""Columns of a round wheel's node rows on a polyline (``round_polyline``): ``X`` to ``XD``,
then the kink flag at ``ROUND_K``, all that a table takes from a row; the ψ-search's four
are left out (a 6 m rail's 31 000 round rows: 1.5 MB instead of 2.5 MB, written once and
read twice by every first wheel). ``table_from_parts`` takes rows of either width.

(The columns keep their numbers: a compiled function of another module that reads them
has them built in, and numba's cache does not see a change here.)"""
ROUND_K = 5
"""The kink flag's column in rows of ``ROUND_NCOL`` columns."""


@numba.njit(cache=True)
def grow(a: NDArray, n: int) -> NDArray:
    """``a`` if it has room for row ``n``, else a copy with twice the rows (any dtype)."""
    if n < a.shape[0]:
        return a
    b = np.empty((2 * a.shape[0] + 64, a.shape[1]), a.dtype)
    b[: a.shape[0]] = a
    return b


@numba.njit(cache=True)
def add_node(
    nodes: NDArray[np.float64],
    nn: int,
    x: float,
    v: float,
    sl: float,
    sr: float,
    xd: float,
    k: float,
) -> NDArray[np.float64]:
    """Row ``nn`` of ``nodes`` (grown if full) set to the node at x: value, slopes left and
    right, contact point, kink flag (the ψ-search's columns 0)."""
    nodes = grow(nodes, nn)
    nodes[nn] = 0.0
    nodes[nn, X] = x
    nodes[nn, V] = v
    nodes[nn, SL] = sl
    nodes[nn, SR] = sr
    nodes[nn, XD] = xd
    nodes[nn, K] = k
    return nodes


MAX_STEPS = 50_000_000
"""Refinement steps at most per table (a guard: real tables take far fewer)."""

SHORTEST = 4e-13
"""Intervals shorter than this (relative to max(1, |x|)) are not refined further."""


@numba.njit(cache=True)
def interval_stack(nn: int) -> tuple[NDArray[np.int64], int]:
    """(stack, size): the refinement stack (rows: left node, right node, tag) holding every
    interval between ``nn`` sorted nodes, the leftmost on top."""
    stack = np.zeros((nn + 64, 3), np.int64)
    for k in range(nn - 1):
        stack[k, 0] = nn - 2 - k
        stack[k, 1] = nn - 1 - k
    return stack, nn - 1


@numba.njit(cache=True, inline="always")
def next_interval(
    stack: NDArray[np.int64], ns: int, nodes: NDArray[np.float64]
) -> tuple[int, int, int, int, float, float, float, float]:
    """(new stack size, left node, right node, tag, x left, x right, length, max(1, |x left|))
    of the next interval on the stack longer than SHORTEST; left node -1 once it is empty."""
    while ns > 0:
        ns -= 1
        ia = stack[ns, 0]
        ib = stack[ns, 1]
        xa = nodes[ia, X]
        xb = nodes[ib, X]
        scale = max(1.0, abs(xa))
        if xb - xa > SHORTEST * scale:
            return ns, ia, ib, stack[ns, 2], xa, xb, xb - xa, scale
    return 0, -1, -1, 0, 0.0, 0.0, 0.0, 1.0


@numba.njit(cache=True, inline="always")
def hermite_midpoint(nodes: NDArray[np.float64], ia: int, ib: int, h: float) -> tuple[float, float]:
    """(value, slope) of the cubic Hermite between nodes ``ia`` and ``ib`` (``h`` apart) at their
    midpoint: what the table will give there, for the refinement's check against the exact solve.

    On y = x³ over [0, 1] (values 0, 1; slopes 0, 3) the midpoint gives the exact (0.125, 0.75).
    """
    value = 0.5 * (nodes[ia, V] + nodes[ib, V]) + 0.125 * h * (nodes[ia, SR] - nodes[ib, SL])
    slope = 1.5 * (nodes[ib, V] - nodes[ia, V]) / h - 0.25 * (nodes[ia, SR] + nodes[ib, SL])
    return value, slope


@numba.njit(cache=True)
def push(
    stack: NDArray[np.int64], ns: int, ia: int, ib: int, tag: int
) -> tuple[NDArray[np.int64], int]:
    """Interval (ia, ib) with ``tag`` onto the refinement stack (grown if full); new size."""
    stack = grow(stack, ns)
    stack[ns, 0] = ia
    stack[ns, 1] = ib
    stack[ns, 2] = tag
    return stack, ns + 1


@numba.njit(cache=True)
def split(
    stack: NDArray[np.int64], ns: int, ia: int, ic: int, ib: int
) -> tuple[NDArray[np.int64], int]:
    """Intervals (ia, ic) and (ic, ib) onto the stack, the left one on top."""
    stack, ns = push(stack, ns, ic, ib, 0)
    return push(stack, ns, ia, ic, 0)


def check_range(x_start: float, x_end: float) -> tuple[float, float]:
    """(x_start, x_end) as floats, or an error saying what is wrong with them."""
    a, b = float(x_start), float(x_end)
    if not (math.isfinite(a) and math.isfinite(b)):
        raise ValueError(
            f"constraint: x_start and x_end must be finite, got {x_start!r}, {x_end!r}"
        )
    if not b > a:
        raise ValueError(f"constraint: x_end must exceed x_start, got x_start={a!r}, x_end={b!r}")
    return a, b


RISER = 1e-9
"""A sampled rail's segments shorter than this (m) are a step's riser, not a feature: a
dented step rail's 1e-12 m ramp (:func:`sim_core.dent_overlay.base_samples`)."""


def resolution(wheel: WheelOutline, rail: RailProfile) -> float:
    """The finest input feature (m): rail sampling (risers aside), λ/16, wheel sample arc,
    flat length/16, <= 10 mm.

    A dented 0.1 mm step rail sampled every 0.5 mm has the resolution of a 0.5 mm sampling,
    as its step rail has the wheel's (a resolution of its 1e-12 m riser made tabulation
    grids of 1e11 intervals: out of memory or >600 s)."""
    return min(rail_feature_length(rail), wheel.min_feature_length, MAX_RESOLUTION)


def rail_feature_length(rail: RailProfile) -> float:
    """The rail's finest feature (m), a step's riser (segments under :data:`RISER`) aside."""
    feature = rail.min_feature_length
    if rail.kind == "sampled" and feature < RISER:
        dx = np.diff(rail.x)
        feature = float(dx[dx >= RISER].min(initial=math.inf))
    return feature


def stretch(a: float, b: float, step: float, period: float) -> tuple[float, float, int]:
    """(x0, x1, intervals) a tabulator covers: one period from ``a``, or [a, b] plus a margin
    of 10 mm + 2·step on each side, in steps of at most ``step``."""
    if period > 0:
        x0, x1 = a, a + period
    else:
        margin = 0.01 + 2.0 * step
        x0, x1 = a - margin, b + margin
    return x0, x1, max(math.ceil((x1 - x0) / step), 4 if period > 0 else 2)


def table_from_nodes(
    nodes: NDArray[np.float64], period: float, resolution: float, dx: float
) -> ConstraintTable:
    """The table of node rows, x never decreasing (a ValueError if it does): nodes closer than
    the position round-off merged, round-off slope jumps smoothed."""
    whole = np.array([[0, 0, nodes.shape[0]]], dtype=np.int64)
    return table_from_parts(nodes, _NO_ROWS, whole, period, resolution, dx, sort=False)


_NO_ROWS = np.empty((0, NCOL))


def table_from_parts(
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    parts: NDArray[np.int64],
    period: float,
    resolution: float,
    dx: float,
    *,
    sort: bool = True,
) -> ConstraintTable:
    """The table of node rows taken in the order of ``parts``: row p = (source, first, end)
    takes rows first..end-1 of ``a`` (source 0) or ``b`` (source 1). What
    :func:`table_from_nodes` makes of the rows concatenated, without the concatenation (a
    6 m rail's 31 000 round-wheel rows with a flat's few hundred: 2.5 MB copied and read
    twice, ~0.4 ms of a 4 ms table). Rows out of order (a later x below an earlier one)
    are concatenated and sorted first with ``sort``, refused without it."""
    parts = np.asarray(parts, dtype=np.int64).reshape(-1, 3)
    for src, lo, hi in parts.tolist():
        rows = (a, b)[src].shape[0] if src in (0, 1) else -1
        if rows < 0 or not 0 <= lo <= hi <= rows:
            raise ValueError(
                f"constraint table: part ({src}, {lo}, {hi}) is not a row range of a or b"
            )
    cols = _table_columns(a, b, parts, float(period))
    if cols is None and not sort:
        raise ValueError("constraint table: node positions x must be increasing")
    if cols is None:
        rows = np.concatenate(
            [_full((a if src == 0 else b)[lo:hi]) for src, lo, hi in parts.tolist()]
        )
        rows = rows[np.argsort(rows[:, X], kind="mergesort")]
        whole = np.array([[0, 0, rows.shape[0]]], dtype=np.int64)
        cols = _table_columns(rows, _NO_ROWS, whole, float(period))
        assert cols is not None  # sorted
    x, y, sl, sr, xd, kinks, jumps = cols
    return ConstraintTable(
        x=x,
        y=y,
        slope_left=sl,
        slope_right=sr,
        contact_x=xd,
        kinks=kinks,
        period=float(period),
        resolution=float(resolution),
        meta={"dx": float(dx), "nodes": float(x.size)},
        kink_jump=jumps,
    )


def _full(rows: NDArray[np.float64]) -> NDArray[np.float64]:
    """``rows`` in ``NCOL`` columns (rows of ``ROUND_NCOL`` widened, the kink flag moved)."""
    if rows.shape[1] == NCOL:
        return rows
    out = np.zeros((rows.shape[0], NCOL))
    out[:, :ROUND_K] = rows[:, :ROUND_K]
    out[:, K] = rows[:, ROUND_K]
    return out


@numba.njit(cache=True)
def _table_columns(
    a: NDArray[np.float64], b: NDArray[np.float64], parts: NDArray[np.int64], period: float
) -> (
    tuple[
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
        NDArray[np.float64],
    ]
    | None
):
    """(x, y, slope left, slope right, x_D, kinks, |slope jump| at each kink) of the rows of
    ``parts`` (see :func:`table_from_parts`), or None if a row's x lies below the one before: nodes
    closer than the position round-off (1e-13·|x|) merged (the left slope of the first, the
    right slope and contact point of the last, a kink if any was one), a slope jump at or
    below KINK_SLOPE made smooth (the mean slope on both sides: round-off, not a kink), a
    periodic table's last node one period after the first (never a kink). One pass over
    the rows, straight into the columns."""
    rows = 0
    for p in range(parts.shape[0]):
        rows += parts[p, 2] - parts[p, 1]
    k_a = ROUND_K if a.shape[1] == ROUND_NCOL else K  # each source's kink column
    k_b = ROUND_K if b.shape[1] == ROUND_NCOL else K
    x = np.empty(rows)
    y = np.empty(rows)
    sl = np.empty(rows)
    sr = np.empty(rows)
    xd = np.empty(rows)
    kk = np.empty(rows)
    m = 0
    prev = 0.0
    for p in range(parts.shape[0]):
        src = a if parts[p, 0] == 0 else b
        kc = k_a if parts[p, 0] == 0 else k_b
        for i in range(parts[p, 1], parts[p, 2]):
            xi = src[i, X]
            if m > 0:
                if xi < prev:
                    return None
                if xi - prev <= 1e-13 * max(1.0, abs(xi)):
                    sr[m - 1] = src[i, SR]
                    xd[m - 1] = src[i, XD]
                    kk[m - 1] = max(kk[m - 1], src[i, kc])
                    prev = xi
                    continue
            x[m] = xi
            y[m] = src[i, V]
            sl[m] = src[i, SL]
            sr[m] = src[i, SR]
            xd[m] = src[i, XD]
            kk[m] = src[i, kc]
            m += 1
            prev = xi
    n = m
    kinks = np.empty(n)
    jumps = np.empty(n)
    nk = 0
    for i in range(n):
        u = sl[i]
        v = sr[i]
        tiny = abs(u - v) <= KINK_SLOPE
        if tiny:
            sl[i] = sr[i] = 0.5 * (u + v)
        if kk[i] > 0 and not tiny and not (period > 0 and i == n - 1):
            kinks[nk] = x[i]
            jumps[nk] = abs(v - u)
            nk += 1
    if period > 0:
        x[n - 1] = x[0] + period
    if n < rows:  # merged rows: columns of their own size
        return (
            x[:n].copy(),
            y[:n].copy(),
            sl[:n].copy(),
            sr[:n].copy(),
            xd[:n].copy(),
            kinks[:nk].copy(),
            jumps[:nk].copy(),
        )
    return x, y, sl, sr, xd, kinks[:nk].copy(), jumps[:nk].copy()
