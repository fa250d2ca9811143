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

from collections.abc import Callable
from dataclasses import dataclass

from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.passage import PassageOutput, PassageSpec
from sim_core.rail import RailProfile
from sim_core.rail_pass import ConstraintTables, DentedRail, TableChoice, rail_pass
from sim_core.summary import PassageSummary, summarize
from sim_core.wheel import WheelOutline


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
    how = TableChoice(phase, constraint, curvature_stiffness)
    return ConstraintTables().table(wheel, DentedRail.of(rail, x_start, x_end), x_start, x_end, how)


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
    """Run ``passes`` identical wheels one after another over ``rail`` (``rail_pass`` each).

    ``progress(i, passes, summary)`` is called after each passage.
    """
    if passes < 1:
        raise ValueError(f"passes must be >= 1, got {passes}")
    x_start = spec.speed * spec.t0
    current = DentedRail.of(rail, x_start, x_start + spec.speed * spec.duration)
    tables = ConstraintTables()
    how = TableChoice(phase, constraint, curvature_stiffness)
    summaries: list[PassageSummary] = []
    done = None
    for i in range(passes):
        done = rail_pass(wheel, current, spec, tables, how)
        current = done.rail
        summary = summarize(done.output, done.max_dent)
        summaries.append(summary)
        if progress is not None:
            progress(i + 1, passes, summary)
    assert done is not None
    plastic = spec.contact.law == ContactLaw.HERTZ_PLASTIC
    return MultiPassOutput(
        last=done.output,
        summaries=summaries,
        rail_after=current.profile if plastic else None,
        last_table=done.table,
    )
