"""What lies under the rail when it is a beam on supports (MODEL.md §8): the track and the detector.

Plain frozen dataclasses, checked on construction: every error names the field
(``pad.stiffness``, ``detector.cribs[2].x_b``) so that the contract's validators
and the command line can pass it on as it stands.

Worked example (the ballasted track of MODEL.md §8 and a crib between the
sleepers at 0.6 and 1.2 m):

    >>> t = TrackSpec.discrete(sleeper_spacing=0.6, first_sleeper=0.0,
    ...                        pad=Support(2.0e8, 3.0e4), sleeper_mass=150.0,
    ...                        ballast=Support(1.2e8, 8.0e4))
    >>> t.kind, round(t.rail.rotary_inertia, 5)
    ('discrete', 0.23845)
    >>> check_cribs((Crib("c1", 0.7, 1.1),), t, 0.0, 6.0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:
    from sim_core.constraint.table import ConstraintTable
    from sim_core.passage import PassageOutput, PassageSpec

BeamKind = Literal["timoshenko", "euler"]
"""The rail's beam theory: Timoshenko (shear and rotary inertia) or Euler–Bernoulli."""

TrackKind = Literal["discrete", "slab"]
"""Pads, sleeper masses and ballast at every sleeper; or pads on rigid ground."""

MAX_CRIBS = 32
"""At most this many cribs in one detector (CONTRACT.md)."""


class TrackError(ValueError):
    """An impossible track or detector; ``field`` names the offending input."""

    def __init__(self, field_name: str, message: str) -> None:
        super().__init__(f"{field_name}: {message}")
        self.field = field_name
        self.reason = message


def _positive(name: str, v: float) -> None:
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
        raise TrackError(name, f"must be a positive finite number, got {v!r}")


def _non_negative(name: str, v: float) -> None:
    if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
        raise TrackError(name, f"must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True)
class RailSection:
    """The rail as a beam: UIC60 by default (MODEL.md §8)."""

    youngs_modulus: float = 2.1e11
    second_moment: float = 3.038e-5
    mass_per_length: float = 60.2
    shear_modulus: float = 8.1e10
    area: float = 7.67e-3
    shear_coefficient: float = 0.4
    beam: BeamKind = "timoshenko"

    def __post_init__(self) -> None:
        for name in (
            "youngs_modulus",
            "second_moment",
            "mass_per_length",
            "shear_modulus",
            "area",
            "shear_coefficient",
        ):
            _positive(f"rail.{name}", getattr(self, name))
        if self.beam not in ("timoshenko", "euler"):
            raise TrackError("rail.beam", f"must be 'timoshenko' or 'euler', got {self.beam!r}")

    @property
    def bending_stiffness(self) -> float:
        """EI, N·m²."""
        return self.youngs_modulus * self.second_moment

    @property
    def shear_stiffness(self) -> float:
        """κGA, N (infinite for Euler–Bernoulli)."""
        if self.beam == "euler":
            return math.inf
        return self.shear_coefficient * self.shear_modulus * self.area

    @property
    def rotary_inertia(self) -> float:
        """ρI = ρA·I/A, kg·m (0 for Euler–Bernoulli)."""
        if self.beam == "euler":
            return 0.0
        return self.mass_per_length * self.second_moment / self.area


@dataclass(frozen=True)
class Support:
    """A spring and a dashpot in parallel (a rail pad, the ballast)."""

    stiffness: float
    damping: float = 0.0


@dataclass(frozen=True)
class TrackSpec:
    """A rail on supports every ``sleeper_spacing``, the first (any) at ``first_sleeper``.

    Sleepers lie at ``first_sleeper + i·sleeper_spacing`` for every integer i: the
    track continues beyond the simulated stretch both ways.
    """

    kind: TrackKind
    sleeper_spacing: float
    first_sleeper: float
    pad: Support
    rail: RailSection = field(default_factory=RailSection)
    sleeper_mass: float = 0.0
    ballast: Support | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("discrete", "slab"):
            raise TrackError("kind", f"must be 'discrete' or 'slab', got {self.kind!r}")
        _positive("sleeper_spacing", self.sleeper_spacing)
        if not math.isfinite(self.first_sleeper):
            raise TrackError("first_sleeper", f"must be finite, got {self.first_sleeper!r}")
        _positive("pad.stiffness", self.pad.stiffness)
        _non_negative("pad.damping", self.pad.damping)
        if self.kind == "discrete":
            _positive("sleeper_mass", self.sleeper_mass)
            if self.ballast is None:
                raise TrackError("ballast", "is required on a discrete track")
            _positive("ballast.stiffness", self.ballast.stiffness)
            _non_negative("ballast.damping", self.ballast.damping)
        elif self.ballast is not None or self.sleeper_mass != 0.0:
            raise TrackError(
                "ballast", "a slab track has pads on rigid ground: no sleeper mass, no ballast"
            )

    @classmethod
    def discrete(
        cls,
        *,
        sleeper_spacing: float,
        first_sleeper: float,
        pad: Support,
        sleeper_mass: float,
        ballast: Support,
        rail: RailSection | None = None,
    ) -> TrackSpec:
        return cls(
            "discrete",
            sleeper_spacing,
            first_sleeper,
            pad,
            rail or RailSection(),
            sleeper_mass,
            ballast,
        )

    @classmethod
    def slab(
        cls,
        *,
        sleeper_spacing: float,
        first_sleeper: float,
        pad: Support,
        rail: RailSection | None = None,
    ) -> TrackSpec:
        return cls("slab", sleeper_spacing, first_sleeper, pad, rail or RailSection())

    # --- sim_core.under_rail.UnderRail ---

    @property
    def carries_detector(self) -> bool:
        """The rail is modelled: crib channels can be read off it."""
        return True

    def prepare(self, x0: float, x1: float, cribs: tuple[Crib, ...] = ()) -> None:
        """Reduce the track of a wheel from x0 to x1 with ``cribs`` to its modes (kept in memory
        and on disk): seconds the first passage would otherwise wait."""
        from sim_core.track.modal import reduce_track

        reduce_track(self, x0, x1, cribs)

    def simulate(
        self,
        table: ConstraintTable,
        spec: PassageSpec,
        *,
        track_dents: bool | None,
        dent_spacing: float,
        max_steps: int,
    ) -> PassageOutput:
        """The exact-mode stepper over the reduced track (``sim_core.track.passage``)."""
        from sim_core.track.passage import simulate_on_track

        return simulate_on_track(
            table, spec, self, track_dents=track_dents, dent_spacing=dent_spacing
        )

    def sleepers_between(self, x0: float, x1: float) -> list[float]:
        """Sleeper positions in [x0, x1]."""
        i0 = math.ceil((x0 - self.first_sleeper) / self.sleeper_spacing - 1e-9)
        i1 = math.floor((x1 - self.first_sleeper) / self.sleeper_spacing + 1e-9)
        return [self.first_sleeper + i * self.sleeper_spacing for i in range(i0, i1 + 1)]


@dataclass(frozen=True)
class Crib:
    """A shear-bridge channel: gauges at ``x_a`` < ``x_b`` in one crib (MODEL.md §8)."""

    id: str
    x_a: float
    x_b: float


def check_cribs(
    cribs: tuple[Crib, ...], track: TrackSpec, x0: float, x1: float, where: str = "detector"
) -> None:
    """Raise ``TrackError`` naming the field unless every crib is possible on ``track`` in [x0, x1].

    A crib needs x_a < x_b, both within the simulated stretch [x0, x1], and no
    sleeper between or on its gauges; ids are unique; 1 to ``MAX_CRIBS`` cribs.
    """
    if not 1 <= len(cribs) <= MAX_CRIBS:
        raise TrackError(f"{where}.cribs", f"must hold 1 to {MAX_CRIBS} cribs, got {len(cribs)}")
    seen: set[str] = set()
    for i, c in enumerate(cribs):
        name = f"{where}.cribs[{i}]"
        if c.id in seen:
            raise TrackError(f"{name}.id", f"{c.id!r} is used by an earlier crib")
        seen.add(c.id)
        for attr in ("x_a", "x_b"):
            v = getattr(c, attr)
            if not math.isfinite(v):
                raise TrackError(f"{name}.{attr}", f"must be finite, got {v!r}")
        if not c.x_a < c.x_b:
            raise TrackError(f"{name}.x_b", f"must be greater than x_a = {c.x_a:g}, got {c.x_b:g}")
        if c.x_a < x0 or c.x_b > x1:
            raise TrackError(
                f"{name}",
                f"gauges [{c.x_a:g}, {c.x_b:g}] m lie outside the simulated stretch [{x0:g}, {x1:g}] m",
            )
        on = track.sleepers_between(c.x_a, c.x_b)
        if on:
            raise TrackError(
                f"{name}",
                f"a sleeper at x = {on[0]:g} m lies on or between the gauges [{c.x_a:g}, {c.x_b:g}] m: "
                "a crib lies between two sleepers",
            )
