"""The physics port: everything the twin asks of the site's physics, declared once.

Two protocols, one a level:

- ``PhysicsPort`` is what the twin (``service.twin``) calls, and all it knows of physics:
  submit a passage, diagnose a measurement, ask whether a passage id was applied before,
  read the rail. ``PhysicsPool`` (``service.physics.worker``: worker processes) and
  ``LocalPhysics`` (``service.physics.local``: in this process, the test double's way in)
  implement it.
- ``SiteModel`` is one model of the site that simulates passages one after another over
  its (evolving) rail: ``SitePhysics`` (``service.physics.site_physics``, on ``sim_core``)
  and ``StubPhysics`` (``service.physics.stub``, an instant closed-form stand-in for
  plumbing tests and for measuring the service's own overhead). A worker process or
  ``LocalPhysics`` runs one.

The errors a port raises and the values it returns are declared here too, so that the twin
imports this module and no concrete physics.
"""

from __future__ import annotations

from concurrent.futures import Future
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, Protocol

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import PassageResult, RailState, WheelPassage
from service.physics.measurement_error import MeasurementError

if TYPE_CHECKING:
    from sim_core.rail import RailProfile

__all__ = [
    "BudgetExceededError",
    "DiagnosisOutcome",
    "MeasurementError",
    "PhysicsKind",
    "PhysicsPort",
    "RailSnapshot",
    "Series",
    "Simulated",
    "SiteModel",
    "WorkerCrashedError",
]

PhysicsKind = Literal["sim_core", "stub"]
"""Which ``SiteModel``: the site's own physics, or the closed-form stand-in."""

Series = tuple[bytes, bytes]
"""The force and the indentation ``PassageSeries`` of a passage, as JSON (fast pacing)."""

RailSnapshot = tuple["RailProfile", int, int]
"""(profile, revision, passages done): what a restarted model needs to go on."""


class BudgetExceededError(RuntimeError):
    """A call took longer than its wall-time budget; the worker was killed and restarted."""

    def __init__(self, what: str, budget: float) -> None:
        super().__init__(
            f"{what} aborted: it took longer than the wall-time budget of "
            f"{budget:g} s a passage (--passage-budget)"
        )
        self.budget = budget


class WorkerCrashedError(RuntimeError):
    """The worker process died during a call (e.g. killed for memory); it was restarted."""


@dataclass(frozen=True)
class DiagnosisOutcome:
    """A diagnosis and the curves the Rerun recording draws."""

    diagnosis: Diagnosis
    t: list[float]
    measured: list[float]
    fitted: list[float]
    x: list[float]
    impacts_x: list[float]
    calibration: str | None = None
    """The site's online calibration as the diagnosis used it (its drift, one line), when
    the twin calibrates online (``service.physics.online_calibration``)."""


@dataclass(frozen=True)
class Simulated:
    """One simulated passage, as the twin publishes it.

    ``data``: the result's JSON when the physics made it (then ``result`` may come without
    its arrays); ``rail_after``: the rail right after this passage (a plastic site's dents as
    it left them) when known; ``series``: the force and indentation series' JSON when asked
    for (``light``)."""

    result: PassageResult
    data: bytes | None = None
    rail_after: RailState | None = None
    series: Series | None = None


class SiteModel(Protocol):
    """Simulates passages one after another over the site's (evolving) rail.

    ``simulate`` is called from one thread, in arrival order; it raises ``ValueError`` for a
    passage it cannot simulate. ``rail_state`` may be called from any thread and must return
    a consistent snapshot.
    """

    def simulate(self, passage: WheelPassage) -> PassageResult: ...

    def rail_state(self) -> RailState: ...

    def warm_up(self) -> float:
        """Compile and exercise the model once (no effect on the rail); returns seconds."""
        ...

    def rail_snapshot(self) -> RailSnapshot: ...

    def restore_rail(self, profile: RailProfile, revision: int, done: int) -> None:
        """Go on from a ``rail_snapshot`` (of a worker that was stopped, or stored)."""
        ...


class PhysicsPort(Protocol):
    """What the twin calls. ``submit`` and ``diagnose`` are called from the twin's worker
    thread; ``rail_state`` from any thread (it never waits for a simulation)."""

    @property
    def size(self) -> int:
        """How many passages may be simulated at once (the twin keeps 2 x this in flight)."""
        ...

    @property
    def concurrent(self) -> bool:
        """Whether ``submit`` returns before the passage is simulated (then the twin
        publishes the results in the passages' order on a thread of its own)."""
        ...

    @property
    def diagnoses(self) -> bool:
        """Whether ``diagnose`` can diagnose measurements (the site's own physics)."""
        ...

    def submit(self, passage: WheelPassage, light: bool) -> Future[Simulated]:
        """Simulate ``passage`` (in the order submitted over one rail). ``light``: make the
        series' JSON too and send the result without its arrays. The future raises
        ``BudgetExceededError``, ``WorkerCrashedError`` or ``ValueError`` (cannot simulate)."""
        ...

    def diagnose(self, passage: WheelPassage, measured: MeasuredPassage) -> DiagnosisOutcome:
        """Diagnose ``measured`` against its ``passage``; raises ``MeasurementError`` for a
        measurement that cannot be diagnosed (naming the field)."""
        ...

    def already_applied(self, passage_id: str) -> int | None:
        """The rail revision ``passage_id`` was applied at in an earlier run, or None."""
        ...

    def rail_state(self) -> RailState: ...
