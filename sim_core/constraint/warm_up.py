"""Compile every tabulation path before the first wheel."""

from __future__ import annotations

import time

import numpy as np

from sim_core.constraint.general import evaluate_exact
from sim_core.constraint.profile import profile_constraint
from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["warm_up_constraint"]


def warm_up_constraint() -> float:
    """Compile (or load from numba's cache) and run every tabulation path on tiny inputs.

    A long-running process (the streaming service) calls this once at start, before the
    first wheel: no wheel then pays for compilation. Covers the round wheel on flat,
    cosine (offset curve and ψ-search), step and sampled rails, the ideal flat on a flat rail, the piece sweep (sampled
    outline on flat and cosine rails, ideal flat on a cosine, rounded flat on a cosine by its
    certified cells; a partly certified cover: the sweep and, in its windows, the boxes' solve),
    the polyline sweep (ideal flat, rounded flat and
    sampled outline on a sampled rail, with the round wheel's cached table), the general
    ψ-search, the direct solve and the table look-up. Returns the wall time it took (s).

    >>> warm_up_constraint() >= 0.0
    True
    """
    t0 = time.perf_counter()
    R = 0.46
    th = np.linspace(0.0, TWO_PI, 64, endpoint=False)
    sampled_wheel = WheelOutline.sampled(th, R + 2e-5 * np.cos(3 * th) - 1e-5 * np.cos(7 * th))
    wheels = [
        WheelOutline.round(R),
        WheelOutline.ideal_flat(R, 0.02),
        WheelOutline.rounded_flat(R, 0.03, 0.03**2 / (16 * R)),
        sampled_wheel,
    ]
    xs = np.arange(0.0, 0.06, 5e-4)
    rails = [
        RailProfile.flat(),
        RailProfile.cosine(2e-6, 0.06),
        RailProfile.step(1e-5, 0.002),
        RailProfile.sampled(xs - 0.03, 2e-6 * np.sin(400.0 * xs) + 1e-6 * np.cos(1300.0 * xs)),
    ]
    xq = np.linspace(-0.002, 0.002, 5)
    for wheel in wheels:
        for rail in rails:
            for method in ("auto", "general"):
                t = tabulate_constraint(wheel, rail, -0.002, 0.002, method=method)
                t.evaluate(xq)
            # a flat away from the window: the round table cut at exact end nodes
            tabulate_constraint(wheel, rail, -0.002, 0.002, phase=1.0).evaluate(xq)
        evaluate_exact(wheel, rails[-1], xq)
    profile_constraint(rails[-1], -0.002, 0.002).evaluate(xq)
    # a partly certified cover (the hollow's middle in boxes): the flat at the bottom at x = 0
    hollow = WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R))
    tabulate_constraint(hollow, RailProfile.cosine(1e-4, 0.05), -0.002, 0.002).evaluate(xq)
    return time.perf_counter() - t0
