"""A closed-form stand-in for the site physics: instant, deterministic, no dents.

The wheel rides at static equilibrium δ0 = (P/C)^(2/3) plus a small damped
ripple; a wheel with a non-round outline gets a force spike once a turn. At a
site with a detector each crib's channel is the force while the wheel centre is
between the crib's gauges and 0 elsewhere (an ideal shear bridge). Only for
exercising the service (tests of the plumbing, overhead benchmarks): the numbers
are not physics.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from schemas.messages import PassageResult, RailState, WheelPassage
from schemas.result import Summary
from schemas.site import SiteConfig
from service.physics.port import RailSnapshot

if TYPE_CHECKING:  # not imported to run: the stub stays free of numba
    from sim_core.rail import RailProfile

C_HERTZ = 1.0805e11


class StubPhysics:
    """Implements ``service.physics.port.SiteModel``: a flat rail that never dents."""

    def __init__(self, site: SiteConfig) -> None:
        self.site = site
        self._done = 0

    def simulate(self, passage: WheelPassage) -> PassageResult:
        start = time.perf_counter()
        site = self.site
        duration = site.length / passage.speed
        n = max(
            2, math.floor(duration * site.output_sample_rate * (1.0 + 1e-12)) + 1
        )  # as sim_core
        t = np.arange(n) / site.output_sample_rate
        x = passage.speed * t
        d0 = (passage.load / C_HERTZ) ** (2.0 / 3.0)
        ripple = 0.02 * d0 * np.sin(2 * np.pi * 270.0 * t) * np.exp(-5.0 * t)
        if passage.outline.kind != "round":
            turn = 2 * np.pi * passage.radius
            ripple -= 0.5 * d0 * np.exp(-((((x % turn) - 0.05) / 0.01) ** 2))
        delta = d0 + ripple
        force = C_HERTZ * np.clip(delta, 0.0, None) ** 1.5
        y_c = -ripple
        y_ck = np.zeros(n)
        cribs = site.detector.cribs if site.detector is not None else []
        channels = {c.id: np.where((x >= c.x_a) & (x <= c.x_b), force, 0.0).tolist() for c in cribs}
        self._done += 1
        return PassageResult(
            site_id=site.site_id,
            passage_id=passage.passage_id,
            train_id=passage.train_id,
            axle_index=passage.axle_index,
            wheel=passage.wheel,
            side=passage.side,
            timestamp=passage.timestamp,
            speed=passage.speed,
            sample_rate=site.output_sample_rate,
            t_start=0.0,
            site_length=site.length,
            x=x.tolist(),
            force=force.tolist(),
            indentation=delta.tolist(),
            y_c=y_c.tolist(),
            y_ck=y_ck.tolist(),
            channels=channels or None,
            transitions=[],
            summary=Summary(
                peak_force=float(force.max()),
                min_force=float(force.min()),
                contact_losses=0,
                first_loss_time=None,
                time_out_of_contact=0.0,
                max_indentation=float(delta.max()),
                max_dent=0.0,
            ),
            rail_revision=0,
            wall_time=time.perf_counter() - start,
            steps=0,
        )

    def rail_state(self) -> RailState:
        n = max(2, math.ceil(self.site.length / 0.01) + 1)
        x = np.linspace(0.0, self.site.length, n)
        return RailState(
            site_id=self.site.site_id,
            revision=0,
            passages_done=self._done,
            x=x.tolist(),
            y=[0.0] * n,
            dent=[0.0] * n,
            max_dent=0.0,
        )

    def warm_up(self) -> float:
        return 0.0  # nothing to compile

    def rail_snapshot(self) -> RailSnapshot:
        from sim_core.rail import RailProfile

        return RailProfile.flat(), 0, self._done

    def restore_rail(self, profile: RailProfile, revision: int, done: int) -> None:
        self._done = done  # the rail never changes
