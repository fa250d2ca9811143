"""Compile every tabulation path before the first wheel."""

from __future__ import annotations

import time
from typing import Literal, cast, get_args

import numpy as np

from sim_core.constraint.general import evaluate_exact
from sim_core.constraint.profile import profile_constraint
from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.rail import RailKind, RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["CONSTRAINT_PARTS", "RAIL_KINDS", "ConstraintPart", "warm_up_constraint"]

ConstraintPart = Literal["searches", "sweeps"]
"""The two halves of the tabulation paths, which share few compiled functions:
``searches`` (the general ψ-search for every wheel, the round wheel's own paths, the direct
solve) and ``sweeps`` (the flats' and outlines' piece, polyline and certified-cell paths and
their boxes, the rail's own profile). ``railtwin warm`` compiles them in two processes."""

CONSTRAINT_PARTS: tuple[ConstraintPart, ...] = ("searches", "sweeps")

RAIL_KINDS = cast(tuple[RailKind, ...], get_args(RailKind))
"""Every rail kind (``sim_core.rail.RailKind``): the default warms the paths of all."""


def warm_up_constraint(
    parts: tuple[ConstraintPart, ...] = CONSTRAINT_PARTS,
    rails: tuple[RailKind, ...] = RAIL_KINDS,
) -> float:
    """Compile (or load from numba's cache) and run the tabulation paths on tiny inputs.

    A long-running process (the streaming service) calls this once at start, before the
    first wheel: no wheel then pays for compilation. Every wheel kind (round, ideal flat,
    rounded flat, sampled outline) is tabulated on a rail of each kind in ``rails``: a site
    passes its own rail's kind (and ``"sampled"`` where its contact law dents the rail),
    since no wheel there meets another. ``searches`` runs the general ψ-search and the
    direct solve on those rails, and the round wheel's own paths (offset curve, polyline)
    on every kind: they are cheap to compile, and a site's measurements are generated on
    a rough, sampled rail (``make demo``); ``sweeps`` the flats'
    paths (piece sweep, polyline sweep, certified cells and, on a cosine, a partly
    certified cover whose windows take the boxes' solve), a flat away from the window (the
    round table cut at exact end nodes) and the rail's own profile. Returns the wall time
    it took (s).

    >>> warm_up_constraint(rails=("flat",)) >= 0.0
    True
    >>> warm_up_constraint(("everything",))  # type: ignore[arg-type]
    Traceback (most recent call last):
    ...
    ValueError: warm_up_constraint: unknown part 'everything' (known: searches, sweeps)
    """
    for part in parts:
        if part not in CONSTRAINT_PARTS:
            raise ValueError(
                f"warm_up_constraint: unknown part {part!r} (known: {', '.join(CONSTRAINT_PARTS)})"
            )
    for kind in rails:
        if kind not in RAIL_KINDS:
            raise ValueError(
                f"warm_up_constraint: unknown rail kind {kind!r} (known: {', '.join(RAIL_KINDS)})"
            )
    t0 = time.perf_counter()
    R = 0.46
    th = np.linspace(0.0, TWO_PI, 64, endpoint=False)
    round_wheel = WheelOutline.round(R)
    flats = [
        WheelOutline.ideal_flat(R, 0.02),
        WheelOutline.rounded_flat(R, 0.03, 0.03**2 / (16 * R)),
        WheelOutline.sampled(th, R + 2e-5 * np.cos(3 * th) - 1e-5 * np.cos(7 * th)),
    ]
    xs = np.arange(0.0, 0.06, 5e-4)
    every: dict[RailKind, RailProfile] = {
        "flat": RailProfile.flat(),
        "cosine": RailProfile.cosine(2e-6, 0.06),
        "step": RailProfile.step(1e-5, 0.002),
        "sampled": RailProfile.sampled(
            xs - 0.03, 2e-6 * np.sin(400.0 * xs) + 1e-6 * np.cos(1300.0 * xs)
        ),
    }
    chosen = [every[k] for k in RAIL_KINDS if k in rails]
    xq = np.linspace(-0.002, 0.002, 5)
    if "searches" in parts:
        for rail in chosen:
            for wheel in [round_wheel, *flats]:
                tabulate_constraint(wheel, rail, -0.002, 0.002, method="general").evaluate(xq)
                evaluate_exact(wheel, rail, xq)
        for rail in every.values():  # the round wheel's own paths on every rail, always
            t = tabulate_constraint(round_wheel, rail, -0.002, 0.002)
            t.evaluate(xq)
            t.contact_point(xq)
            tabulate_constraint(round_wheel, rail, -0.002, 0.002, phase=1.0).evaluate(xq)
    if "sweeps" in parts:
        for rail in chosen:
            for wheel in flats:
                tabulate_constraint(wheel, rail, -0.002, 0.002).evaluate(xq)
                tabulate_constraint(wheel, rail, -0.002, 0.002, phase=1.0).evaluate(xq)
            if rail.kind != "step":  # a step is no constraint itself
                profile_constraint(rail, -0.002, 0.002).evaluate(xq)
        if "cosine" in rails:
            # a partly certified cover (the hollow's middle in boxes): the flat's bottom at x = 0
            hollow = WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R))
            tabulate_constraint(hollow, RailProfile.cosine(1e-4, 0.05), -0.002, 0.002).evaluate(xq)
    return time.perf_counter() - t0
