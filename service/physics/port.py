"""What the twin needs of a physics model of the site (injected, so the twin is testable).

``SitePhysics`` (``service.physics.site_physics``) is the real one, on ``sim_core``;
``StubPhysics`` (``service.physics.stub``) is an instant closed-form stand-in
for plumbing tests and for measuring the service's own overhead.
"""

from __future__ import annotations

from typing import Protocol

from schemas.messages import PassageResult, RailState, WheelPassage


class PassageSimulator(Protocol):
    """Simulates passages one after another over the site's (evolving) rail.

    ``simulate`` is called from one worker thread, in arrival order; it raises
    ``ValueError`` for a passage it cannot simulate. ``rail_state`` may be
    called from any thread and must return a consistent snapshot.
    """

    def simulate(self, passage: WheelPassage) -> PassageResult: ...

    def rail_state(self) -> RailState: ...
