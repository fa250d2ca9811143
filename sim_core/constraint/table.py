"""The tabulated rigid constraint y_C^k(x): the form the integrator reads.

The exact constraint of MODEL.md §2 is a maximisation per wheel position and
too costly to solve at every right-hand-side evaluation, so it is solved once
per passage on a grid of wheel positions (``sim_core.constraint``) and stored
here as a piecewise cubic Hermite table: exact values and slopes at the nodes,
C¹ inside each piece, and explicit *kinks* (nodes whose left and right slopes
differ: the contact point jumped, e.g. the wheel rolled onto a flat's corner
or bridged a hollow). The integrator stops exactly at every kink and restarts
there (MODEL.md §7).

The table is C¹ at its other nodes but not C²: each piece has its own second
derivative, and where the exact constraint changes shape (an offset line of a
rail segment meets the arc of the wheel pivoting on a vertex, G'' jumping by
1/R) so does the table's. ``curvature_jumps_between`` lists those nodes with the
size of the jump |ΔG''|; steps in contact stop on the ones whose error over the
step would exceed the tolerance (``sim_core.integrate.loop``), as on kinks but
without restarting the jerk (it is continuous there).

A table may be *periodic* (a round wheel on a cosine rail, any wheel on a
flat rail): it then covers one period [x[0], x[0] + period] and positions wrap.
Outside a non-periodic table the constraint is continued flat at the end
values.

Worked example: a table of y = 0.1·x² on three nodes returns the exact
parabola inside, because cubic Hermite interpolation is exact for it:

    >>> import numpy as np
    >>> x = np.array([0.0, 1.0, 2.0])
    >>> t = ConstraintTable(x=x, y=0.1 * x**2, slope_left=0.2 * x, slope_right=0.2 * x,
    ...                     contact_x=x, kinks=np.empty(0), period=0.0, resolution=1.0)
    >>> round(float(t.evaluate(np.array([1.5]))[0]), 12)
    0.225
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.lookup import locate, wrap

_NONE = np.empty(0)

JUMP_RELATIVE = 0.01
"""A curvature jump is a change of the constraint's shape only above this fraction of the
larger curvature at the node.

Where the exact constraint is C² the Hermite pieces still disagree on G'' at a node, by
their interpolation error: measured at most 6e-4 of |G''| for the round wheel on Fig. 4's
cosine (16 nodes per feature). Where its shape changes the jump is the curvature itself:
an offset line (G'' = 0) meeting an arc (1/R) jumps by 100 % of it, as every one of the
site rail's 12 000 does, and a flat's end likewise. Stopping on the interpolation's own
jumps would solve the table more accurately than it represents the constraint, at one
step per node (3x Fig. 4's steps)."""


@dataclass(frozen=True)
class ConstraintTable:
    """y_C^k on nodes ``x`` (strictly increasing), with slopes and contact points.

    Attributes:
        x: node positions of the wheel centre x_C (m), strictly increasing.
        y: y_C^k at the nodes (m), relative to a round wheel on a flat rail at 0.
        slope_left, slope_right: dy_C^k/dx_C just left and right of each node;
            they differ only at kinks.
        contact_x: the contact point x_D at each node (m).
        kinks: positions (a subset of ``x``) where the slope jumps.
        period: 0 for a table over a finite stretch; else the table covers
            exactly one period [x[0], x[0] + period] and ``y[-1] == y[0]``.
        resolution: the length of the finest feature in the inputs (rail
            sampling, wavelength/16, ...): steps in contact advance the wheel
            by at most this much so no feature is stepped over.
        stiffness_scale: empty, or per node the factor C(x)/C of the
            curvature-dependent Hertz coefficient (MODEL.md §3, optional);
            interpolated linearly between nodes.
    """

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    slope_left: NDArray[np.float64]
    slope_right: NDArray[np.float64]
    contact_x: NDArray[np.float64]
    kinks: NDArray[np.float64]
    period: float
    resolution: float
    stiffness_scale: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    meta: dict[str, float] = field(default_factory=dict, compare=False)
    kink_jump: NDArray[np.float64] = field(default_factory=lambda: np.empty(0), compare=False)
    """Empty, or per kink (``kinks`` increasing) |slope_right - slope_left| at its node, as the
    tabulator found it (``nodes.table_from_parts``): ``kink_jumps_between`` then slices it
    instead of looking each kink's node up. A ``dataclasses.replace`` that changes the slopes
    or the kinks must pass ``kink_jump=np.empty(0)`` (it is not checked against them)."""

    def __post_init__(self) -> None:
        n = self.x.size
        if n < 2:
            raise ValueError(f"a constraint table needs at least 2 nodes, got {n}")
        for name in ("y", "slope_left", "slope_right", "contact_x"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise ValueError(f"constraint table: {name} has shape {arr.shape}, expected ({n},)")
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"constraint table: {name} has non-finite values")
        if not np.all(np.diff(self.x) > 0):
            raise ValueError("constraint table: node positions x must be strictly increasing")
        if self.period < 0 or (
            self.period > 0
            and abs(self.x[-1] - self.x[0] - self.period) > 1e-12 * max(1.0, self.period)
        ):
            raise ValueError("constraint table: a periodic table must span exactly one period")
        if self.stiffness_scale.size not in (0, n) or not np.all(self.stiffness_scale > 0):
            raise ValueError("constraint table: stiffness_scale must be empty or positive per node")
        if self.kink_jump.size and self.kink_jump.shape != self.kinks.shape:
            raise ValueError(
                f"constraint table: kink_jump has shape {self.kink_jump.shape}, expected "
                f"{self.kinks.shape} (one per kink) or empty"
            )
        if not self.resolution > 0:
            raise ValueError(
                f"constraint table: resolution must be positive, got {self.resolution}"
            )

    def evaluate(self, xq: NDArray[np.float64]) -> NDArray[np.float64]:
        """y_C^k at the positions ``xq`` (vectorised)."""
        return self._look_up(xq, slope=False)

    def slope(self, xq: NDArray[np.float64]) -> NDArray[np.float64]:
        """dy_C^k/dx at ``xq`` (right-sided at kinks)."""
        return self._look_up(xq, slope=True)

    def _look_up(self, xq: NDArray[np.float64], *, slope: bool) -> NDArray[np.float64]:
        xq = np.asarray(xq, dtype=np.float64)
        out = np.empty(xq.shape)
        values, slopes = (_NONE, out.ravel()) if slope else (out.ravel(), _NONE)
        _evaluate_many(
            self.x,
            self.y,
            self.slope_left,
            self.slope_right,
            self.period,
            xq.ravel(),
            values,
            slopes,
        )
        return out

    def contact_point(self, xq: NDArray[np.float64]) -> NDArray[np.float64]:
        """The contact point x_D for wheel positions ``xq`` (linear between nodes, unwrapped)."""
        xq = np.asarray(xq, dtype=np.float64)
        out = np.empty(xq.shape)
        contact_many(self.x, self.contact_x, self.period, xq.ravel(), out.ravel())
        return out

    def curvature_jumps_between(
        self, x0: float, x1: float, least: float = 0.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(positions, |ΔG''|) of the nodes in (x0, x1] where G'' jumps by more than ``least``.

        Kinks are not listed (their slope jumps: ``kinks_between``). Unwrapped for a
        periodic table, sorted. A jump below about 1e-9 of the table's curvatures is
        round-off of the Hermite pieces, not a change of shape: pass ``least`` above it.
        """
        if x1 <= x0:
            return np.empty(0), np.empty(0)
        if self.period == 0.0:
            # the nodes are sorted: one compiled pass over those inside
            i0 = int(np.searchsorted(self.x, x0, side="right"))
            i1 = int(np.searchsorted(self.x, x1, side="right"))
            return _jumps_in(self.x, self.y, self.slope_left, self.slope_right, i0, i1, least)
        jumps = curvature_jumps(self.x, self.y, self.slope_left, self.slope_right, self.period)
        keep = jumps[:-1] > least  # node n-1 is node 0 one period on
        xs, js = self.x[:-1][keep], jumps[:-1][keep]
        shifts = self._period_shifts(x0, x1)[:, None]
        xs = (xs[None, :] + shifts).ravel()
        js = np.broadcast_to(js, (shifts.size, js.size)).ravel()
        inside = (xs > x0) & (xs <= x1)
        return xs[inside], js[inside]

    def kinks_between(self, x0: float, x1: float) -> NDArray[np.float64]:
        """Kink positions in (x0, x1], unwrapped for a periodic table, sorted."""
        if self.kinks.size == 0 or x1 <= x0:
            return np.empty(0)
        if self.period == 0.0:
            k = self.kinks
            return np.sort(k[(k > x0) & (k <= x1)])
        allk = (self.kinks[None, :] + self._period_shifts(x0, x1)[:, None]).ravel()
        return np.unique(allk[(allk > x0) & (allk <= x1)])

    def kink_jumps_between(
        self, x0: float, x1: float
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(positions, |slope jump|) of the kinks in (x0, x1], as ``kinks_between`` lists them;
        each jump read at the node nearest the kink (a periodic table's at its node in the
        one period kept). A non-periodic table's are sliced from ``kink_jump`` when the
        tabulator kept them, else found in one compiled pass over the nodes (a rough 6 m
        rail's ~10 000 kinks cost 0.3 ms through ``np.searchsorted``)."""
        if self.period == 0.0 and self.kink_jump.size and x1 > x0:
            lo, hi = np.searchsorted(self.kinks, [x0, x1], side="right")
            return self.kinks[lo:hi].copy(), self.kink_jump[lo:hi].copy()
        if self.period == 0.0 and self.kinks.size and x1 > x0:
            return _kink_jumps(self.x, self.slope_left, self.slope_right, self.kinks, x0, x1)
        kinks = self.kinks_between(x0, x1)
        if kinks.size == 0:
            return kinks, np.empty(0)
        xk = kinks if self.period <= 0.0 else self.x[0] + np.mod(kinks - self.x[0], self.period)
        at = np.clip(np.searchsorted(self.x, xk), 1, self.x.size - 1)
        at = np.where(np.abs(self.x[at - 1] - xk) < np.abs(self.x[at] - xk), at - 1, at)
        return kinks, np.abs(self.slope_right[at] - self.slope_left[at])

    def _period_shifts(self, x0: float, x1: float) -> NDArray[np.float64]:
        """Multiples of the period that carry the table's one period over [x0, x1] (and one more
        each side)."""
        p = self.period
        n0 = int(np.floor((x0 - self.x[0]) / p)) - 1
        n1 = int(np.floor((x1 - self.x[0]) / p)) + 1
        return p * np.arange(n0, n1 + 1, dtype=np.float64)


@numba.njit(cache=True)
def _kink_jumps(
    x: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    kinks: NDArray[np.float64],
    x0: float,
    x1: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:meth:`ConstraintTable.kink_jumps_between` of a non-periodic table: the kinks in
    (x0, x1] in order, and |sr - sl| at the node nearest each: the first node at or above the
    kink (its index clipped to 1..n-1, as ``np.searchsorted``'s was), or the one before it if
    that is nearer. Walks the nodes once (the kinks are in node order; sorted first if not)."""
    n = x.size
    ordered = True
    for m in range(1, kinks.size):
        if not kinks[m] >= kinks[m - 1]:  # a NaN is out of order too
            ordered = False
            break
    order = np.arange(kinks.size) if ordered else np.argsort(kinks, kind="mergesort")
    pos = np.empty(kinks.size)
    size = np.empty(kinks.size)
    k = 0
    j = 0
    for m in range(kinks.size):
        xk = kinks[order[m]]
        if not (x0 < xk <= x1):
            continue
        while j < n and x[j] < xk:
            j += 1
        at = min(max(j, 1), n - 1)
        if abs(x[at - 1] - xk) < abs(x[at] - xk):
            at -= 1
        pos[k] = xk
        size[k] = abs(sr[at] - sl[at])
        k += 1
    return pos[:k], size[:k]


@numba.njit(cache=True, inline="always")
def table_eval(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    period: float,
    xv: float,
    hint: int,
) -> tuple[float, float, int]:
    """(y_C^k, slope, index) at position ``xv``; ``hint`` speeds up nearby look-ups.

    The one Hermite look-up. Inlined: a caller that drops the slope does not
    pay for it (the compiler removes it), so the right-hand side uses it too.
    """
    xw, _ = wrap(xv, x[0], period)
    n = x.size
    if xw <= x[0]:
        if period > 0.0:
            return y[0], sr[0], 0
        return y[0], 0.0, 0
    if xw >= x[n - 1]:
        if period > 0.0:
            return y[n - 1], sl[n - 1], n - 2
        return y[n - 1], 0.0, n - 2
    i = locate(x, xw, hint)
    h = x[i + 1] - x[i]
    t = (xw - x[i]) / h
    u = 1.0 - t
    m0 = sr[i] * h
    m1 = sl[i + 1] * h
    # Hermite basis in factored form
    val = u * u * ((1.0 + 2.0 * t) * y[i] + t * m0) + t * t * ((3.0 - 2.0 * t) * y[i + 1] - u * m1)
    der = (
        6.0 * t * u * (y[i + 1] - y[i]) + u * (1.0 - 3.0 * t) * m0 + t * (3.0 * t - 2.0) * m1
    ) / h
    return val, der, i


@numba.njit(cache=True, inline="always")
def _second_derivatives(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    i: int,
) -> tuple[float, float]:
    """G'' at the left and right ends of Hermite piece i (it is linear in between)."""
    r = 1.0 / (x[i + 1] - x[i])
    d = (y[i + 1] - y[i]) * r
    return (6.0 * d - 4.0 * sr[i] - 2.0 * sl[i + 1]) * r, (
        -6.0 * d + 2.0 * sr[i] + 4.0 * sl[i + 1]
    ) * r


@numba.njit(cache=True)
def _jumps_in(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    i0: int,
    i1: int,
    least: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(positions, |ΔG''|) of the interior non-kink nodes i0 <= i < i1 with a jump above ``least``."""
    n = x.size
    lo = max(i0, 1)
    hi = min(i1, n - 1)
    pos = np.empty(max(hi - lo, 0))
    size = np.empty(max(hi - lo, 0))
    k = 0
    if lo < hi:
        _, before = _second_derivatives(x, y, sl, sr, lo - 1)
        for i in range(lo, hi):
            after, end = _second_derivatives(x, y, sl, sr, i)
            jump = _real_jump(after, before)
            if sl[i] == sr[i] and jump > least:
                pos[k] = x[i]
                size[k] = jump
                k += 1
            before = end
    return pos[:k], size[:k]


@numba.njit(cache=True)
def curvature_jumps(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    period: float,
) -> NDArray[np.float64]:
    """|G''(x_i+) - G''(x_i-)| at every node from the Hermite pieces on both sides (1/m).

    0 at kinks (the slope jumps there: a stop of its own), where the jump is within
    ``JUMP_RELATIVE`` of the curvature (the interpolation's own) and at the ends of a
    non-periodic table; node 0 and node n-1 of a periodic table are one point.
    On a piece of length h with values y0, y1 and slopes m0, m1 the second
    derivative runs linearly from (6·Δ - 4·m0 - 2·m1)/h to (-6·Δ + 2·m0 + 4·m1)/h,
    Δ = (y1 - y0)/h. For a line (G'' = 0) meeting an arc of radius 0.46 m the
    jump is 1/0.46 = 2.17 /m.
    """
    n = x.size
    left_end = np.empty(n - 1)  # G'' at each piece's left end
    right_end = np.empty(n - 1)  # ... and at its right end
    for i in range(n - 1):
        left_end[i], right_end[i] = _second_derivatives(x, y, sl, sr, i)
    out = np.zeros(n)
    for i in range(1, n - 1):
        if sl[i] == sr[i]:
            out[i] = _real_jump(left_end[i], right_end[i - 1])
    if period > 0.0 and n > 2 and sl[0] == sr[0] and sl[n - 1] == sr[n - 1]:
        out[0] = _real_jump(left_end[0], right_end[n - 2])
        out[n - 1] = out[0]
    return out


@numba.njit(cache=True, inline="always")
def _real_jump(after: float, before: float) -> float:
    """|after - before|, or 0 within ``JUMP_RELATIVE`` of the larger curvature."""
    jump = abs(after - before)
    return jump if jump > JUMP_RELATIVE * max(abs(after), abs(before)) else 0.0


@numba.njit(cache=True)
def _evaluate_many(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    sl: NDArray[np.float64],
    sr: NDArray[np.float64],
    period: float,
    xq: NDArray[np.float64],
    values: NDArray[np.float64],
    slopes: NDArray[np.float64],
) -> None:
    """y_C^k and its slope at every ``xq`` (either output may be empty: not wanted)."""
    hint = 0
    for k in range(xq.size):
        v, d, hint = table_eval(x, y, sl, sr, period, xq[k], hint)
        if values.size:
            values[k] = v
        if slopes.size:
            slopes[k] = d


@numba.njit(cache=True, inline="always")
def linear_at(
    x: NDArray[np.float64],
    v: NDArray[np.float64],
    period: float,
    xv: float,
    hint: int,
    follow: bool,
) -> tuple[float, float, float, int]:
    """(value, slope, shift, index) of node values ``v`` interpolated linearly at ``xv``.

    The one look-up of per-node quantities (the stiffness scale, the contact
    point). ``xv`` wraps into a periodic table; ``shift`` is what the wrap took
    off (add it back to a position). Outside the nodes the value is held
    (``follow`` False, slope 0) or continued with slope 1 (``follow`` True: the
    contact point follows the wheel).
    """
    xw, shift = wrap(xv, x[0], period)
    n = x.size
    if xw <= x[0]:
        if follow:
            return v[0] + (xw - x[0]), 1.0, shift, 0
        return v[0], 0.0, shift, 0
    if xw >= x[n - 1]:
        if follow:
            return v[n - 1] + (xw - x[n - 1]), 1.0, shift, n - 2
        return v[n - 1], 0.0, shift, n - 2
    i = locate(x, xw, hint)
    dx = x[i + 1] - x[i]
    u = (xw - x[i]) / dx
    dv = v[i + 1] - v[i]
    return v[i] + u * dv, dv / dx, shift, i


@numba.njit(cache=True)
def contact_many(
    x: NDArray[np.float64],
    cx: NDArray[np.float64],
    period: float,
    xq: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    """Contact points at ``xq``: linear between nodes (a wheel pivoting on a corner keeps
    x_D fixed, which the nodes on either side share), following the wheel outside."""
    hint = 0
    for k in range(xq.size):
        xd, _, shift, hint = linear_at(x, cx, period, xq[k], hint, True)
        out[k] = xd + shift
