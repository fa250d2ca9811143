"""The combined irregularity: the rigid constraint of an out-of-round wheel on a rough rail
as the sum of two exact tables.

Railway dynamics commonly drives the wheel/rail contact with the *combined* (relative)
irregularity: the wheel's out-of-roundness as seen on an even rail plus the rail's
roughness as seen by a round wheel. Here both parts are exact constraints of MODEL.md §2,

    y_C^k(x) ≈ y_C^k[wheel, even rail](x) + y_C^k[round wheel, rail](x),

each tabulated by its fast exact path (the piece sweep, the closed form on a polyline,
the periodic cosine table). The sum of two piecewise cubic Hermite tables is piecewise
cubic on the union of their nodes, so :func:`add_tables` represents it *exactly* (values
and one-sided slopes at the union of nodes, kinks of both).

What it leaves out: while a flat pivots on its corner the true contact point is
l/2 ahead of or behind the wheel centre, where the rail may be higher or lower than
under a round wheel by about (rail slope)·l/2: for a 2 µm, 6 cm corrugation and a
50 mm flat, up to 5 µm against the flat's 0.68 mm depth. The diagnosis fits the
flat, not the µm, so this is the right trade for a table that costs milliseconds
(``tests/test_diagnosis_forward.py`` bounds the difference against the exact search).

    >>> import numpy as np
    >>> from sim_core.constraint import tabulate_constraint
    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> a = tabulate_constraint(WheelOutline.ideal_flat(0.46, 0.05), RailProfile.flat(), 0.0, 3.0)
    >>> b = tabulate_constraint(WheelOutline.round(0.46), RailProfile.cosine(2e-6, 0.06), 0.0, 3.0)
    >>> s = add_tables(a, b, 0.5, 1.5)
    >>> xq = np.linspace(0.6, 1.4, 7)
    >>> bool(np.allclose(s.evaluate(xq), a.evaluate(xq) + b.evaluate(xq), rtol=0, atol=1e-15))
    True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable

__all__ = ["add_tables"]


def _nodes_in(t: ConstraintTable, x0: float, x1: float) -> NDArray[np.float64]:
    """The table's node positions in [x0, x1], unwrapped for a periodic table."""
    if t.period == 0.0:
        return t.x[(t.x >= x0) & (t.x <= x1)]
    p = t.period
    n0 = int(np.floor((x0 - t.x[0]) / p))
    n1 = int(np.floor((x1 - t.x[0]) / p))
    base = t.x[:-1]
    allx = (base[None, :] + p * np.arange(n0, n1 + 1)[:, None]).ravel()
    return allx[(allx >= x0) & (allx <= x1)]


def _one_sided(
    t: ConstraintTable, xs: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Values and left/right slopes of ``t`` at ``xs`` (kinks of ``t`` get both sides)."""
    y = t.evaluate(xs)
    sr = t.slope(xs)
    sl = sr.copy()
    kinks = t.kinks_between(float(xs[0]) - 1.0, float(xs[-1]) + 1.0)
    if kinks.size:
        i = np.searchsorted(xs, kinks)
        ok = (i < xs.size) & (np.abs(xs[np.minimum(i, xs.size - 1)] - kinks) <= 1e-12)
        for j in i[ok]:
            xw = xs[j]
            if t.period > 0.0:
                xw = t.x[0] + (xw - t.x[0]) % t.period
            k = int(np.argmin(np.abs(t.x - xw)))
            if k == 0 and t.period > 0.0 and abs(t.x[-1] - xw) < abs(t.x[0] - xw):
                k = t.x.size - 1
            sl[j] = t.slope_left[k] if k > 0 or t.period == 0.0 else t.slope_left[-1]
            sr[j] = t.slope_right[k] if k < t.x.size - 1 else t.slope_right[0]
    return y, sl, sr


def add_tables(a: ConstraintTable, b: ConstraintTable, x0: float, x1: float) -> ConstraintTable:
    """y_a + y_b on [x0, x1] as one non-periodic table (contact points from ``a``).

    Exact for the two Hermite tables: every node of either is a node of the sum, and
    every kink of either is a kink of the sum.
    """
    if not x1 > x0:
        raise ValueError(f"add_tables: need x1 > x0, got [{x0!r}, {x1!r}]")
    xs = np.unique(np.concatenate([[x0, x1], _nodes_in(a, x0, x1), _nodes_in(b, x0, x1)]))
    # merge nodes closer than round-off (a shared kink seen through two periods)
    keep = np.concatenate([[True], np.diff(xs) > 1e-12])
    xs = xs[keep]
    ya, sla, sra = _one_sided(a, xs)
    yb, slb, srb = _one_sided(b, xs)
    kinks = np.concatenate([a.kinks_between(x0, x1), b.kinks_between(x0, x1)])
    kinks = np.unique(kinks[(kinks > x0) & (kinks < x1)])
    if kinks.size:
        snapped = xs[np.clip(np.searchsorted(xs, kinks - 1e-12), 0, xs.size - 1)]
        kinks = snapped
    return ConstraintTable(
        x=xs,
        y=ya + yb,
        slope_left=sla + slb,
        slope_right=sra + srb,
        contact_x=a.contact_point(xs),
        kinks=kinks,
        period=0.0,
        resolution=min(a.resolution, b.resolution),
    )
