"""What lies under the rail: one declared interface, four kinds.

The wheel's equation and the contact are the same on every track (MODEL.md §4, §8);
what differs is what the rail rests on, and so how the rail under the wheel moves.
``UnderRail`` is that difference as an interface: each kind simulates a passage of
its own (``simulate``), says whether it can carry a detector (``carries_detector``),
and prepares once what every passage over a stretch would otherwise redo
(``prepare``). The kinds:

- ``sim_core.passage.Foundation("rigid")``: the rail does not move (the paper's (3.4));
- ``sim_core.passage.Foundation("compliant", M, k, c)``: one mass on a spring (6.1);
- ``sim_core.track.TrackSpec("discrete" | "slab", …)``: a Timoshenko rail on supports (§8).

``simulate_passage`` and everything above it (the twin, the diagnosis's forward model,
the scenario runner) call these methods and never ask which kind they hold.

Worked example:

    >>> from sim_core.passage import Foundation
    >>> from sim_core.track import Support, TrackSpec
    >>> kinds = [Foundation.rigid(), Foundation.compliant(150.0, 2e8),
    ...          TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7))]
    >>> [isinstance(k, UnderRail) for k in kinds], [k.carries_detector for k in kinds]
    ([True, True, True], [False, False, True])
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from sim_core.constraint.table import ConstraintTable
    from sim_core.passage import PassageOutput, PassageSpec
    from sim_core.track.spec import Crib


@runtime_checkable
class UnderRail(Protocol):
    """What lies under the rail (see the module's docstring)."""

    @property
    def kind(self) -> str:
        """'rigid', 'compliant', 'discrete' or 'slab'."""
        ...

    @property
    def carries_detector(self) -> bool:
        """Whether the rail is modelled, so that crib channels can be computed on it."""
        ...

    def prepare(self, x0: float, x1: float, cribs: tuple[Crib, ...] = ()) -> None:
        """Do once what every passage of a wheel from x0 to x1 needs (nothing, or a reduction)."""
        ...

    def simulate(
        self,
        table: ConstraintTable,
        spec: PassageSpec,
        *,
        track_dents: bool | None,
        dent_spacing: float,
        max_steps: int,
    ) -> PassageOutput:
        """One passage of ``spec`` over ``table`` on this foundation."""
        ...
