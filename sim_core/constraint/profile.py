"""The option "the profile is the constraint" (MODEL.md §6, Fig. 9): y_C^k = y_r(x_C)."""

from __future__ import annotations

import math

import numpy as np

from sim_core.constraint.flat_rail import flat_constraint
from sim_core.constraint.nodes import MAX_RESOLUTION, check_range
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RailProfile

__all__ = ["profile_constraint"]


def profile_constraint(rail: RailProfile, x_start: float, x_end: float) -> ConstraintTable:
    """The option "the profile is the constraint": y_C^k = y_r(x_C), x_D = x_C.

    The wheel's geometric filtering is ignored (MODEL.md §6, Fig. 9). A cosine
    gives a periodic table (512 nodes per wavelength, exact slopes); a sampled
    rail a table on its samples with a kink at every vertex where the slope
    changes; a step cannot be a constraint (it is discontinuous).

    >>> t = profile_constraint(RailProfile.cosine(1e-4, 0.05), 0.0, 1.0)
    >>> round(float(t.evaluate(np.array([0.0125]))[0]) * 1e4, 9), t.period
    (0.0, 0.05)
    """
    a, b = check_range(x_start, x_end)
    res = min(rail.min_feature_length, MAX_RESOLUTION)
    if rail.kind == "flat":
        return flat_constraint(resolution=res)
    if rail.kind == "step":
        raise ValueError(
            "profile constraint: a step rail is discontinuous and cannot itself be the constraint; "
            "use the exact constraint (tabulate_constraint)"
        )
    if rail.kind == "cosine":
        lam, amp = rail.wavelength, rail.amplitude
        x = a + np.linspace(0.0, lam, 513)
        k = 2 * math.pi / lam
        y = amp * np.cos(k * x)
        y[-1] = y[0]
        s = -amp * k * np.sin(k * x)
        s[-1] = s[0]
        return ConstraintTable(
            x=x,
            y=y,
            slope_left=s,
            slope_right=s.copy(),
            contact_x=x.copy(),
            kinks=np.empty(0),
            period=lam,
            resolution=res,
        )
    margin = 0.01
    xs = rail.x
    inside = (xs > a - margin) & (xs < b + margin)
    xn = np.concatenate(
        ([min(a - margin, xs[0]) - 1e-3], xs[inside], [max(b + margin, xs[-1]) + 1e-3])
    )
    yn = rail.height(xn)
    seg = np.diff(yn) / np.diff(xn)
    sl = np.concatenate(([0.0], seg))
    sr = np.concatenate((seg, [0.0]))
    kink = sl != sr
    kink[0] = kink[-1] = False
    return ConstraintTable(
        x=xn,
        y=yn,
        slope_left=sl,
        slope_right=sr,
        contact_x=xn.copy(),
        kinks=xn[kink].copy(),
        period=0.0,
        resolution=res,
    )
