"""A rail on discrete supports, and a detector (CONTRACT.md, MODEL.md §8).

Two more ``foundation`` kinds for scenarios and site files: ``discrete`` (rail pads,
half-sleeper masses and ballast at every sleeper) and ``slab`` (rail pads on rigid
ground); and a ``detector``: the shear-bridge channels of the cribs between sleepers.

``check_track`` holds the rules that need the foundation, the detector and the simulated
stretch together; the scenario and the site file call it with their own stretch
(``speed·duration``, ``length``). The crib rules are those of ``sim_core.track.spec``
(``check_cribs``), restated here because the contract needs nothing but pydantic.

    >>> f = DiscreteFoundation.model_validate({
    ...     "kind": "discrete", "sleeper_spacing": 0.6, "first_sleeper": 0.1,
    ...     "pad": {"stiffness": 2.0e8, "damping": 3.0e4}, "sleeper_mass": 150.0,
    ...     "ballast": {"stiffness": 1.2e8, "damping": 8.0e4}})
    >>> f.rail.beam, f.rail.mass_per_length
    ('timoshenko', 60.2)
    >>> sleeper_within(f, 1.4, 1.8) is None, round(sleeper_within(f, 1.0, 1.8), 9)
    (True, 1.3)
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from schemas._base import (
    Finite,
    Identifier,
    NonNegative,
    Positive,
    StrictModel,
    field_error,
)

MAX_CRIBS = 32
"""At most this many cribs in one detector (CONTRACT.md; ``sim_core.track.spec.MAX_CRIBS``)."""

MAX_TRACK_LENGTH = 30.0
"""Longest simulated stretch on a discrete or slab foundation, m.

The rail is a beam on supports reduced to its modes up to 12 kHz: their number, and so the
work of every step and the reduction's dense eigen-solves, grows with the stretch (about
800 modes for 30 m of 0.6 m bays; the physics refuses more than
``sim_core.track.modal.MAX_MODES`` = 1 500). 30 m is five times a detector site (a few
metres) with its run-in.
"""

MIN_SLEEPER_SPACING = 0.1
"""Shortest sleeper (support) spacing, m: with ``MAX_TRACK_LENGTH`` it bounds the number of
supports, hence the work, of one passage (real track: 0.6–0.65 m)."""

SLEEPER_TOLERANCE = 1e-9
"""A gauge within this fraction of a sleeper spacing of a sleeper counts as on it."""

BeamKind = Literal["timoshenko", "euler"]


class RailBeam(StrictModel):
    """The rail as a beam (MODEL.md §8): UIC60 by default."""

    youngs_modulus: Positive = Field(default=2.1e11, description="Young's modulus E, Pa")
    second_moment: Positive = Field(default=3.038e-5, description="second moment of area I, m⁴")
    mass_per_length: Positive = Field(default=60.2, description="mass per length ρA, kg/m")
    shear_modulus: Positive = Field(default=8.1e10, description="shear modulus G, Pa")
    area: Positive = Field(default=7.67e-3, description="cross-section area A, m²")
    shear_coefficient: Positive = Field(default=0.4, description="shear coefficient κ")
    beam: BeamKind = Field(
        default="timoshenko",
        description="'timoshenko' (shear and rotary inertia) or 'euler' (Euler–Bernoulli)",
    )


class TrackSupport(StrictModel):
    """A spring and a dashpot in parallel (a rail pad, the ballast)."""

    stiffness: Positive = Field(description="stiffness k, N/m")
    damping: NonNegative = Field(default=0.0, description="viscous damping c, N·s/m")


def _rail() -> RailBeam:
    return RailBeam()


class DiscreteFoundation(StrictModel):
    """Ballasted track: at every sleeper a pad, half a sleeper's mass and the ballast."""

    kind: Literal["discrete"]
    rail: RailBeam = Field(default_factory=_rail, description="the rail; UIC60 if left out")
    sleeper_spacing: Positive = Field(
        ge=MIN_SLEEPER_SPACING,
        description=f"sleeper spacing L_s, m; at least {MIN_SLEEPER_SPACING:g} m",
    )
    first_sleeper: Finite = Field(
        description="x_0, m: sleepers at x_0 + i·L_s for every integer i (the track runs on "
        "beyond the simulated stretch both ways)"
    )
    pad: TrackSupport = Field(description="rail pad k_p, c_p between rail and sleeper")
    sleeper_mass: Positive = Field(
        description="sleeper mass m_s under one rail (half a sleeper), kg"
    )
    ballast: TrackSupport = Field(description="ballast k_b, c_b between sleeper and ground")


class SlabFoundation(StrictModel):
    """Slab track: at every sleeper position a pad on rigid ground (no sleeper, no ballast)."""

    kind: Literal["slab"]
    rail: RailBeam = Field(default_factory=_rail, description="the rail; UIC60 if left out")
    sleeper_spacing: Positive = Field(
        ge=MIN_SLEEPER_SPACING,
        description=f"support spacing L_s, m; at least {MIN_SLEEPER_SPACING:g} m",
    )
    first_sleeper: Finite = Field(description="x_0, m: supports at x_0 + i·L_s for every integer i")
    pad: TrackSupport = Field(description="rail pad k_p, c_p between rail and slab")


TrackFoundation = DiscreteFoundation | SlabFoundation
"""A rail on discrete supports (what a detector needs)."""


class Crib(StrictModel):
    """A shear-bridge channel: gauges at ``x_a`` < ``x_b`` in the crib between two sleepers.

    Its channel is Q(x_a) − Q(x_b), N: +P for a static wheel between the gauges.
    """

    id: Identifier = Field(description="the channel's name (its key in series.channels)")
    x_a: Finite = Field(description="position of the first gauge, m")
    x_b: Finite = Field(description="position of the second gauge, m; > x_a")

    @model_validator(mode="after")
    def _ordered(self) -> Crib:
        if not self.x_a < self.x_b:
            raise field_error("x_b", f"must be greater than x_a = {self.x_a:g} m, got {self.x_b:g}")
        return self


class Detector(StrictModel):
    """A wheel-impact-load detector: shear-bridge channels in consecutive cribs."""

    cribs: list[Crib] = Field(
        min_length=1,
        max_length=MAX_CRIBS,
        description=f"1 to {MAX_CRIBS} cribs, ids unique; each between two sleepers and within "
        "the simulated stretch",
    )

    @model_validator(mode="after")
    def _unique_ids(self) -> Detector:
        seen: set[str] = set()
        for i, c in enumerate(self.cribs):
            if c.id in seen:
                raise field_error(f"cribs[{i}].id", f"{c.id!r} is the id of an earlier crib")
            seen.add(c.id)
        return self


def sleeper_within(track: TrackFoundation, x0: float, x1: float) -> float | None:
    """The first sleeper position in [x0, x1], or None (as ``sim_core.track.spec``'s
    ``TrackSpec.sleepers_between``: a gauge within ``SLEEPER_TOLERANCE`` of a spacing from a
    sleeper counts as on it)."""
    spacing = track.sleeper_spacing
    ahead = math.fmod(track.first_sleeper - x0, spacing)  # exact, whatever the magnitudes
    if ahead < 0.0:
        ahead += spacing
    if ahead >= spacing * (1.0 - SLEEPER_TOLERANCE):  # just before x0: on it
        ahead -= spacing
    if ahead <= x1 - x0 + SLEEPER_TOLERANCE * spacing:
        return x0 + ahead
    return None


def check_track(
    foundation: object,
    detector: Detector | None,
    stretch: float,
    stretch_field: str,
    stretch_name: str,
) -> None:
    """Raise a field error unless the foundation and detector fit the stretch [0, ``stretch``].

    ``stretch_field`` names the input the error is reported on (``duration``, ``length``),
    ``stretch_name`` what the stretch is made of (``speed·duration``, ``length``).
    A rail on supports bounds the stretch by ``MAX_TRACK_LENGTH``; a detector needs such
    a rail, and each crib lies within the stretch with no sleeper on or between its gauges.
    """
    on_supports = isinstance(foundation, (DiscreteFoundation, SlabFoundation))
    if on_supports and stretch > MAX_TRACK_LENGTH:
        raise field_error(
            stretch_field,
            f"the simulated stretch {stretch_name} = {stretch:g} m is longer than the "
            f"{MAX_TRACK_LENGTH:g} m (MAX_TRACK_LENGTH) a discrete or slab foundation allows: "
            "the work of a passage grows with the length of rail modelled",
        )
    if detector is None:
        return
    if not isinstance(foundation, (DiscreteFoundation, SlabFoundation)):
        kind = getattr(foundation, "kind", type(foundation).__name__)
        raise field_error(
            "detector",
            f"needs a rail on supports (foundation kind 'discrete' or 'slab'), not {kind!r}: "
            "its gauges measure the rail's shear force between sleepers",
        )
    for i, c in enumerate(detector.cribs):
        name = f"detector.cribs[{i}]"
        if c.x_a < 0.0:
            raise field_error(
                f"{name}.x_a",
                f"{c.x_a:g} m lies before the simulated stretch [0, {stretch:g}] m",
            )
        if c.x_b > stretch:
            raise field_error(
                f"{name}.x_b",
                f"{c.x_b:g} m lies beyond the simulated stretch [0, {stretch:g}] m",
            )
        on = sleeper_within(foundation, c.x_a, c.x_b)
        if on is not None:
            raise field_error(
                name,
                f"a sleeper at x = {on:g} m lies on or between the gauges "
                f"[{c.x_a:g}, {c.x_b:g}] m: a crib lies between two sleepers (sleepers at "
                f"{foundation.first_sleeper:g} + i·{foundation.sleeper_spacing:g} m)",
            )
