"""Several wheels in sequence over the same rail (MODEL.md §5).

Each wheel sees the rail as the wheels before it left it: with the
Hertzian–perfectly plastic law every passage presses its dents into the
profile the next one rolls on, which is how repeated passages grow
corrugation (the paper's closing argument).

Worked example: ``simulate_passes(WheelOutline.round(0.475), RailProfile.flat(), spec,
passes=20)`` with an HPP ``spec`` returns the 20 summaries, the last passage's
series and the corrugated rail (``rail_after``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

from sim_core.constraint import curvature_stiffness_scale, profile_constraint, tabulate_constraint
from sim_core.constraint_table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.dents import dent_profile, dented_rail
from sim_core.passage import PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.summary import PassageSummary, summarize
from sim_core.wheel import WheelOutline

RAIL_MARGIN = 0.1
"""Rail kept beyond the passage's ends (m): more than the contact window of any wheel here."""


@dataclass(frozen=True)
class MultiPassOutput:
    """The last passage in full, every passage's summary, and the rail after the last one.

    ``rail_after`` is None unless the law is plastic (Hertzian–perfectly plastic).
    """

    last: PassageOutput
    summaries: list[PassageSummary]
    rail_after: RailProfile | None
    last_table: ConstraintTable


def constraint_for(
    wheel: WheelOutline,
    rail: RailProfile,
    x_start: float,
    x_end: float,
    *,
    phase: float = 0.0,
    constraint: str = "exact",
    curvature_stiffness: bool = False,
) -> ConstraintTable:
    """The table a passage over [x_start, x_end] needs: the exact constraint or the profile."""
    if constraint == "exact":
        table = tabulate_constraint(wheel, rail, x_start, x_end, phase=phase)
    elif constraint == "profile":
        table = profile_constraint(rail, x_start, x_end)
    else:
        raise ValueError(f"constraint must be 'exact' or 'profile', got {constraint!r}")
    if curvature_stiffness:
        scale = curvature_stiffness_scale(table, rail, wheel.nominal_radius)
        table = dataclasses.replace(table, stiffness_scale=scale)
    return table


def simulate_passes(
    wheel: WheelOutline,
    rail: RailProfile,
    spec: PassageSpec,
    passes: int = 1,
    *,
    phase: float = 0.0,
    constraint: str = "exact",
    curvature_stiffness: bool = False,
    progress: Callable[[int, int, PassageSummary], None] | None = None,
) -> MultiPassOutput:
    """Run ``passes`` identical wheels one after another over ``rail``.

    ``progress(i, passes, summary)`` is called after each passage.
    """
    if passes < 1:
        raise ValueError(f"passes must be >= 1, got {passes}")
    x_start = spec.speed * spec.t0
    x_end = x_start + spec.speed * spec.duration
    plastic = spec.contact.law == ContactLaw.HERTZ_PLASTIC
    summaries: list[PassageSummary] = []
    current = rail
    out: PassageOutput | None = None
    table: ConstraintTable | None = None
    for i in range(passes):
        table = constraint_for(
            wheel,
            current,
            x_start,
            x_end,
            phase=phase,
            constraint=constraint,
            curvature_stiffness=curvature_stiffness,
        )
        out = simulate_passage(table, spec)
        max_dent = 0.0
        if plastic:
            dx, depth = dent_profile(out, spec.contact)
            if depth.size:
                max_dent = float(depth.max())
                current = dented_rail(
                    current, dx, depth, x_start - RAIL_MARGIN, x_end + RAIL_MARGIN
                )
        summary = summarize(out, max_dent)
        summaries.append(summary)
        if progress is not None:
            progress(i + 1, passes, summary)
    assert out is not None and table is not None
    return MultiPassOutput(
        last=out, summaries=summaries, rail_after=current if plastic else None, last_table=table
    )
