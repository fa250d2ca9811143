"""The site's physics on ``sim_core``: each wheel simulated over the site's current rail.

A passage is the wheel centre rolling from x_C = 0 to the site's length at the
passage's speed (duration = length / speed), from static equilibrium, over
the rigid constraint of the wheel's outline on the rail. With the
Hertzian–perfectly plastic law each passage may dent the rail; the next wheel
sees the dented rail (MODEL.md §5), so passages are simulated in arrival order.

Each wheel is one ``sim_core.rail_pass``: the rail is the site's base profile
plus a dent overlay; round wheels' tables are kept per radius and re-tabulated
only where a new dent changed the rail; out-of-round wheels are tabulated per
passage (their table depends on the outline and the phase).
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np

from schemas.messages import PassageResult, RailState, WheelPassage
from schemas.result import Summary, Transition
from schemas.scenario import FlatOutline
from schemas.site import SiteConfig
from service.physics import inputs as physics_inputs
from service.physics.port import RailSnapshot
from sim_core.constraint import warm_up_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactModel
from sim_core.passage import PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailKind, RailProfile
from sim_core.rail_pass import ConstraintTables, DentedRail, TableChoice, rail_pass
from sim_core.summary import summarize
from sim_core.wheel import WheelOutline

RAIL_STATE_SPACING = 1e-3
"""m between the samples of the published rail state."""


def wheel_outline(p: WheelPassage) -> WheelOutline:
    """The passage's wheel outline (``physics_inputs.wheel_outline``)."""
    return physics_inputs.wheel_outline(p.outline, p.radius)


class SitePhysics:
    """Implements ``service.physics.port.SiteModel`` with ``sim_core``."""

    def __init__(self, site: SiteConfig) -> None:
        self.site = site
        self.material = physics_inputs.material(site.material)
        self.foundation = physics_inputs.foundation(site.foundation)
        self.cribs = physics_inputs.cribs(site.detector)
        self.base_rail = physics_inputs.rail_profile(site.rail)
        # the rail now (base + dents), swapped as a whole so that readers on other threads
        # see a consistent profile and revision
        self._rail = DentedRail.of(self.base_rail, 0.0, site.length)
        self._tables = ConstraintTables()
        self._done = 0
        self._state_lock = threading.Lock()
        self._state_cache: tuple[int, int, RailState] | None = None

    # --- simulation --------------------------------------------------------------------

    def _table(self, passage: WheelPassage, rail: DentedRail) -> ConstraintTable:
        return self._tables.table(
            wheel_outline(passage), rail, 0.0, self.site.length, TableChoice(passage.phase)
        )

    def contact_model(self, passage: WheelPassage) -> ContactModel:
        model, _ = physics_inputs.contact_model(
            self.site.contact,
            self.material,
            radius=passage.radius,
            load=passage.load,
            mass=passage.mass,
        )
        return model

    def _spec(self, passage: WheelPassage, length: float) -> PassageSpec:
        """The passage over ``length`` m of the site, from static equilibrium, with the
        detector's cribs that lie within it."""
        return PassageSpec(
            mass=passage.mass,
            load=passage.load,
            speed=passage.speed,
            duration=length / passage.speed,
            sample_rate=self.site.output_sample_rate,
            contact=self.contact_model(passage),
            foundation=self.foundation,
            initial=None,
            rtol=self.site.rtol,
            cribs=tuple(c for c in self.cribs if c.x_b <= length),
        )

    def rail_kinds(self) -> tuple[RailKind, ...]:
        """The kinds of rail profile a wheel can meet at this site: the rail's own (its base,
        or a sampled profile once dented) and, where the contact law dents it, ``sampled``
        (a dented rail is a sampled profile)."""
        kinds: set[RailKind] = {self.base_rail.kind, self._rail.profile.kind}
        if self.site.contact == "hertz_plastic":
            kinds.add("sampled")
        return tuple(sorted(kinds))

    def warm_up(self) -> float:
        """Compile and exercise the physics once (no effect on the rail); returns seconds."""
        start = time.perf_counter()
        probe = WheelPassage(
            passage_id="warm-up",
            train_id="warm-up",
            axle_index=0,
            side="right",
            timestamp=0.0,
            speed=40.0,
            load=50000.0,
            mass=600.0,
            radius=0.46,
        )
        # the whole site on a track (its modes are the ones every wheel uses, reduced once
        # and cached), half a metre on a lumped foundation
        on_track = self.site.foundation.kind in ("discrete", "slab")
        stretch = self.site.length if on_track else min(self.site.length, 0.5)
        simulate_passage(self._table(probe, self._rail), self._spec(probe, stretch))
        # every constraint path a wheel may take here, so that no wheel pays for compilation
        warm_up_constraint(rails=self.rail_kinds())
        flat = probe.model_copy(update={"outline": FlatOutline(kind="flat", length=0.03)})
        self._table(flat, self._rail)
        # the dent press (compiled), on a scratch copy of the rail
        DentedRail.of(self.base_rail, 0.0, self.site.length).pressed(
            np.array([0.5 * self.site.length]), np.array([-1e-5]), probe.radius
        )
        # what every wheel over the site needs, once (a rail on supports: its modes)
        self.foundation.prepare(0.0, self.site.length, self.cribs)
        return time.perf_counter() - start

    def simulate(self, passage: WheelPassage) -> PassageResult:
        start = time.perf_counter()
        rail = self._rail
        spec = self._spec(passage, self.site.length)
        done = rail_pass(
            wheel_outline(passage), rail, spec, self._tables, TableChoice(passage.phase)
        )
        self._rail = done.rail
        self._done += 1
        return self._result(
            passage, done.output, done.max_dent, rail.revision, time.perf_counter() - start
        )

    def _result(
        self, p: WheelPassage, out: PassageOutput, max_dent: float, revision: int, wall: float
    ) -> PassageResult:
        s = summary_of(out, max_dent)
        return PassageResult(
            site_id=self.site.site_id,
            passage_id=p.passage_id,
            train_id=p.train_id,
            axle_index=p.axle_index,
            wheel=p.wheel,
            side=p.side,
            timestamp=p.timestamp,
            speed=p.speed,
            sample_rate=self.site.output_sample_rate,
            t_start=float(out.t[0]),
            site_length=self.site.length,
            x=out.x.tolist(),
            force=out.force.tolist(),
            indentation=out.delta.tolist(),
            y_c=out.y_c.tolist(),
            y_ck=out.y_ck.tolist(),
            channels={c.id: out.channels[c.id].tolist() for c in self.cribs} or None,
            transitions=[Transition(t=tr.t, kind=tr.kind, x=tr.x) for tr in out.transitions],
            summary=s,
            rail_revision=revision,
            wall_time=wall,
            steps=out.steps,
        )

    # --- rail state --------------------------------------------------------------------

    def rail_snapshot(self) -> RailSnapshot:
        """(profile, revision, passages done): what a restarted worker needs to go on."""
        rail = self._rail
        return rail.profile, rail.revision, self._done

    def restore_rail(self, profile: RailProfile, revision: int, done: int) -> None:
        """Go on from a ``rail_snapshot`` (of a worker process that was stopped, or stored)."""
        self._rail = DentedRail.restored(self.base_rail, profile, revision, 0.0, self.site.length)
        self._done = done
        self._tables.clear()

    def rail_state(self) -> RailState:
        rail, done = self._rail, self._done
        with self._state_lock:
            cached = self._state_cache
            if cached is not None and cached[0] == rail.revision:
                return cached[2].model_copy(update={"passages_done": done})
            n = max(2, math.ceil(self.site.length / RAIL_STATE_SPACING) + 1)
            x = np.linspace(0.0, self.site.length, n)
            y = rail.profile.height(x)
            dent = np.clip(self.base_rail.height(x) - y, 0.0, None)
            state = RailState(
                site_id=self.site.site_id,
                revision=rail.revision,
                passages_done=done,
                x=x.tolist(),
                y=y.tolist(),
                dent=dent.tolist(),
                max_dent=float(dent.max()) if dent.size else 0.0,
            )
            self._state_cache = (rail.revision, done, state)
            return state


def summary_of(out: PassageOutput, max_dent: float) -> Summary:
    """The contract's summary fields of one passage."""
    s = summarize(out, max_dent)
    return Summary(
        peak_force=s.peak_force,
        min_force=s.min_force,
        contact_losses=s.contact_losses,
        first_loss_time=s.first_loss_time,
        time_out_of_contact=s.time_out_of_contact,
        max_indentation=s.max_indentation,
        max_dent=s.max_dent,
    )
