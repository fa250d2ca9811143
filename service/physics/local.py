"""The physics port in this process: a ``SiteModel`` run on the caller's thread.

``LocalPhysics`` is what ``railtwin serve --in-process`` and the plumbing tests hand the twin
(``LocalPhysics(StubPhysics(site))``): ``submit`` simulates at once and returns a finished
future. The compiled physics holds the GIL while it runs, so a service uses the worker
processes (``service.physics.worker``) instead.

``make_model`` is the one place a ``PhysicsKind`` becomes a ``SiteModel``.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Future
from typing import TYPE_CHECKING

from schemas.diagnosis import MeasuredPassage
from schemas.messages import RailState, WheelPassage
from schemas.site import SiteConfig
from service.physics.port import DiagnosisOutcome, PhysicsKind, Simulated, SiteModel

if TYPE_CHECKING:  # the site's own physics is imported only when it is used
    from service.physics.diagnosis import Diagnoser

DiagnoseFn = Callable[[WheelPassage, MeasuredPassage], DiagnosisOutcome]


def make_model(kind: PhysicsKind, site: SiteConfig) -> SiteModel:
    """The ``SiteModel`` of ``site``: ``sim_core`` (the site's own physics) or ``stub``."""
    if kind == "stub":
        from service.physics.stub import StubPhysics

        return StubPhysics(site)
    from service.physics.site_physics import SitePhysics

    return SitePhysics(site)


def diagnose_with(
    diagnoser: Diagnoser, passage: WheelPassage, measured: MeasuredPassage
) -> DiagnosisOutcome:
    """Run ``Diagnoser.diagnose`` and keep what the twin needs (a ``MeasurementError`` goes
    to the caller as it is)."""
    diag, curves = diagnoser.diagnose(passage, measured)
    impacts_x = curves.impacts_t * curves.estimate.speed
    return DiagnosisOutcome(
        diag,
        curves.t.tolist(),
        curves.measured.tolist(),
        curves.fitted.tolist(),
        curves.x.tolist(),
        impacts_x.tolist(),
    )


class LocalPhysics:
    """Implements ``PhysicsPort`` with one ``SiteModel`` in this process."""

    def __init__(self, model: SiteModel, diagnose: DiagnoseFn | None = None) -> None:
        self.model = model
        self._diagnose = diagnose

    @classmethod
    def of(cls, kind: PhysicsKind, site: SiteConfig) -> LocalPhysics:
        """The ``kind`` model of ``site``; the site's own physics diagnoses too."""
        if kind != "sim_core":
            return cls(make_model(kind, site))
        from service.physics.diagnosis import Diagnoser
        from service.physics.site_physics import SitePhysics

        model = SitePhysics(site)
        diagnoser = Diagnoser(site, physics=model)
        return cls(model, lambda p, m: diagnose_with(diagnoser, p, m))

    @property
    def size(self) -> int:
        return 1

    @property
    def concurrent(self) -> bool:
        return False

    @property
    def diagnoses(self) -> bool:
        return self._diagnose is not None

    def warm_up(self) -> float:
        return self.model.warm_up()

    def submit(self, passage: WheelPassage, light: bool = False) -> Future[Simulated]:
        future: Future[Simulated] = Future()
        try:
            future.set_result(Simulated(self.model.simulate(passage)))
        except Exception as exc:  # the twin reports it, as a worker's would be
            future.set_exception(exc)
        return future

    def diagnose(self, passage: WheelPassage, measured: MeasuredPassage) -> DiagnosisOutcome:
        if self._diagnose is None:
            raise RuntimeError(
                "this physics does not diagnose (it needs the site's own "
                "physics, --physics sim_core)"
            )
        return self._diagnose(passage, measured)

    def already_applied(self, passage_id: str) -> int | None:
        return None  # no state on disk

    def rail_state(self) -> RailState:
        return self.model.rail_state()
