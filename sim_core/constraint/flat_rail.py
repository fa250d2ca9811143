"""Closed forms on a flat rail: the round wheel (y_C^k ≡ 0) and the ideal flat.

Both are periodic in one wheel turn 2πR.

Worked example: an ideal flat of 61.6 mm (R = 0.475 m) drops the centre by
R(1 - cos θ0) = 1.0 mm when it lies flat on the rail:

    >>> from sim_core.wheel import WheelOutline
    >>> t = ideal_flat_on_flat(WheelOutline.ideal_flat(0.475, 0.0616), 0.0, 0.0, 1e-3, 1e-3)
    >>> round(float(t.y.min()) * 1e3, 4), t.kinks.tolist()
    (-0.9996, [0.0])
"""

from __future__ import annotations

import math

import numpy as np

from sim_core.constraint.nodes import MAX_RESOLUTION
from sim_core.constraint.table import ConstraintTable
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["flat_constraint", "ideal_flat_on_flat"]


def flat_constraint(period: float = 1.0, resolution: float = MAX_RESOLUTION) -> ConstraintTable:
    """y_C^k ≡ 0: a round wheel on a flat rail (periodic, contact point under the centre).

    >>> t = flat_constraint()
    >>> float(t.evaluate(np.array([123.4]))[0]), t.kinks.size
    (0.0, 0)
    """
    x = np.array([0.0, float(period)])
    z = np.zeros(2)
    return ConstraintTable(
        x=x,
        y=z,
        slope_left=z.copy(),
        slope_right=z.copy(),
        contact_x=x.copy(),
        kinks=np.empty(0),
        period=float(period),
        resolution=float(resolution),
    )


def ideal_flat_on_flat(
    wheel: WheelOutline, x0: float, phase: float, step: float, resolution: float
) -> ConstraintTable:
    """Closed form for an ideal flat on a flat rail, over one turn from x0.

    With φ wrapped to [-π, π): y_C^k = R·cos(θ0 - |φ|) - R = -2R·sin²((θ0 - |φ|)/2)
    for |φ| < θ0 (the wheel rests on the flat's corner nearer the bottom), else 0.
    """
    R = wheel.nominal_radius
    th0 = wheel.flat_half_angle
    P = TWO_PI * R
    n = max(math.ceil(P / step), 8)
    special = []
    for phi_s in (0.0, -th0, th0):  # kink at the centre, C² breaks at the corners
        xs = R * (phi_s - phase)
        xs = x0 + ((xs - x0) % P)
        special.append(xs)
    x = np.unique(np.concatenate((x0 + P * np.arange(n) / n, special)))
    x = x[x < x0 + P]
    x = x[np.concatenate(([True], np.diff(x) > 1e-12))]
    x = np.append(x, x0 + P)
    phi = phase + x / R
    phw = phi - TWO_PI * np.floor((phi + math.pi) / TWO_PI)
    # snap the special points onto their exact phase (x carries round-off)
    kink_i = int(np.argmin(np.abs(np.minimum(np.abs(x - special[0]), np.abs(x - special[0] - P)))))
    on = np.abs(phw) < th0
    u = th0 - np.abs(phw)
    su = np.sin(0.5 * u)
    y = np.where(on, -2.0 * R * su * su, 0.0)
    sgn = np.sign(phw)
    slope = np.where(on, sgn * np.sin(u), 0.0)
    xd = np.where(on, x + sgn * R * np.sin(u), x)
    sl = slope.copy()
    sr = slope.copy()
    y[kink_i] = -2.0 * R * math.sin(0.5 * th0) ** 2
    sl[kink_i] = -math.sin(th0)
    sr[kink_i] = math.sin(th0)
    xd[kink_i] = x[kink_i] + R * math.sin(th0)
    y[-1], sl[-1], sr[-1] = y[0], sl[0], sr[0]
    xd[-1] = xd[0] + P
    return ConstraintTable(
        x=x,
        y=y,
        slope_left=sl,
        slope_right=sr,
        contact_x=xd,
        kinks=np.array([x[kink_i] if kink_i < x.size - 1 else x[0]]),
        period=P,
        resolution=resolution,
        meta={"dx": float(step), "nodes": float(x.size)},
    )
