"""The forward model of the diagnosis: a wheel with (or without) a flat rolling over the site.

A wheel reaches a real site already rolling steadily: the passage starts a *run-in*
(at least one wheel turn) before the site's start x = 0, so the wheel arrives with the
motion its flat has already excited, not at rest. Times are the site's: t = 0 when the
wheel centre is at x = 0, x_C = V·t.

The flat's angular position φ0 (the contract's ``wheel.phase``, any finite angle taken
modulo 2π) puts its centre under the wheel centre at

    x_k = R·(2πk - φ0),  k integer,        t_k = x_k / V

(the once-per-turn spacing 2πR/V). The constraint is the combined irregularity
(``sim_core.diagnosis.combined``): the flat wheel on an even rail plus the round wheel on
the site's rail.

Worked example: a 50 mm fresh flat (depth 0.68 mm) on a 0.46 m wheel at 100 km/h lifts
off and hits back at several times the static load of 60 kN:

    >>> from sim_core.materials import Material, derive
    >>> from sim_core.contact_laws import ContactLaw, ContactModel
    >>> from sim_core.rail import RailProfile
    >>> d = derive(Material(2.14e11, 0.3), radius=0.46, load=60e3, mass=500.0)
    >>> w = WheelOnSite(500.0, 60e3, 0.46, ContactModel(ContactLaw.HERTZ, d.contact_coefficient))
    >>> flat = Flat.ideal(0.46, 0.05, phase=1.0)
    >>> rails = RailTables(RailProfile.flat())
    >>> out = simulate_passage_run_in(w, 27.78, flat, rails, 0.0, 3.0, 1e4)
    >>> round(flat.depth * 1e3, 2), bool(out.peak_force > 3 * 60e3), bool(out.t[0] < -0.1)
    (0.68, True, True)
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint import tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactModel
from sim_core.diagnosis.combined import add_tables
from sim_core.passage import (
    Foundation,
    InitialState,
    PassageOutput,
    PassageSpec,
    simulate_passage,
)
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = [
    "RUN_IN_TURNS",
    "Flat",
    "FlatKind",
    "MeasuredTread",
    "RailTables",
    "Tread",
    "WheelOnSite",
    "damping_for_ratio",
    "damping_ratio_of",
    "flat_times",
    "simulate_passage_run_in",
    "simulate_window",
    "typical_rounded_depth",
    "wheel_table",
    "with_damping_ratio",
]

FlatKind = Literal["flat", "rounded_flat"]

RUN_IN_TURNS = 1.25
"""Wheel turns simulated before the site's start (the issue asks for at least one)."""

TABLE_MARGIN = 0.02
"""m of constraint tabulated beyond each end of a simulated stretch."""

WORN_TABLE_DX = 0.01
"""m: the starting node spacing of a worn flat's table on a flat rail. The piece sweep
refines to its Hermite tolerance wherever the outline bends, so the default 2 mm grid only
adds nodes on the round part of the turn, where the constraint is level; 10 mm halves the
cost of the fit's tables and moves a template by under 1e-7·P (tests/test_diagnosis.py)."""


def typical_rounded_depth(radius: float, length: float) -> float:
    """d = l²/(16R): the depth of a worn flat as usually assumed (MODEL.md §7), m."""
    return length * length / (16.0 * radius)


def ideal_flat_depth(radius: float, length: float) -> float:
    """d = R - sqrt(R² - l²/4) of a fresh flat (MODEL.md §2), m."""
    half = 0.5 * length
    return half * half / (radius + math.sqrt(radius * radius - half * half))


@dataclass(frozen=True)
class Flat:
    """A flat on the tread: ``kind``, chord/arc ``length`` and ``depth`` (m), ``phase`` φ0 (rad)."""

    kind: FlatKind
    length: float
    depth: float
    phase: float

    def __post_init__(self) -> None:
        if self.kind not in ("flat", "rounded_flat"):
            raise ValueError(f"flat: kind must be 'flat' or 'rounded_flat', got {self.kind!r}")
        for name in ("length", "depth"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"flat: {name} must be positive (m), got {v!r}")
        if not math.isfinite(self.phase):
            raise ValueError(f"flat: phase must be finite (rad), got {self.phase!r}")

    @classmethod
    def ideal(cls, radius: float, length: float, phase: float = 0.0) -> Flat:
        """A fresh (ideal) flat: its depth follows from the chord."""
        return cls("flat", length, ideal_flat_depth(radius, length), phase % TWO_PI)

    @classmethod
    def rounded(
        cls, radius: float, length: float, depth: float | None = None, phase: float = 0.0
    ) -> Flat:
        """A worn (haversine) flat; depth l²/(16R) unless given."""
        d = typical_rounded_depth(radius, length) if depth is None else depth
        return cls("rounded_flat", length, d, phase % TWO_PI)

    def outline(self, radius: float) -> WheelOutline:
        if self.kind == "flat":
            return WheelOutline.ideal_flat(radius, self.length)
        return WheelOutline.rounded_flat(radius, self.length, self.depth)

    def with_phase(self, phase: float) -> Flat:
        return Flat(self.kind, self.length, self.depth, phase % TWO_PI)


@dataclass(frozen=True)
class MeasuredTread:
    """Any outline (e.g. a trolley-measured tread) turned by ``phase``: a ``Tread`` like ``Flat``."""

    wheel_outline: WheelOutline
    phase: float

    def outline(self, radius: float) -> WheelOutline:
        return self.wheel_outline

    def with_phase(self, phase: float) -> MeasuredTread:
        return MeasuredTread(self.wheel_outline, phase % TWO_PI)


Tread = Flat | MeasuredTread
"""What is on the wheel's tread: a flat the fit can name, or any measured outline."""


@dataclass(frozen=True)
class WheelOnSite:
    """What is known of the wheel and the site: m (kg), P (N), R (m), the contact law,
    the foundation and the integrator's relative tolerance."""

    mass: float
    load: float
    radius: float
    contact: ContactModel
    foundation: Foundation = field(default_factory=Foundation.rigid)
    rtol: float = 1e-8


def damping_for_ratio(foundation: Foundation, zeta: float) -> float:
    """The damper c (N·s/m) that gives a compliant foundation the damping ratio ``zeta``."""
    return 2.0 * zeta * math.sqrt(foundation.stiffness * foundation.mass)


def damping_ratio_of(foundation: Foundation) -> float:
    """The damping ratio c / (2·sqrt(k·M)) of a compliant foundation."""
    return foundation.damping / (2.0 * math.sqrt(foundation.stiffness * foundation.mass))


def with_damping_ratio(wheel: WheelOnSite, zeta: float) -> WheelOnSite:
    """The wheel on its foundation damped to the ratio ``zeta`` (a rigid one as it is)."""
    f = wheel.foundation
    if not f.is_compliant:
        return wheel
    return replace(
        wheel, foundation=Foundation.compliant(f.mass, f.stiffness, damping_for_ratio(f, zeta))
    )


def flat_times(
    radius: float, speed: float, phase: float, t0: float, t1: float
) -> NDArray[np.float64]:
    """Times t_k in [t0, t1] at which the flat's centre is under the wheel centre."""
    period = TWO_PI * radius / speed
    first = radius * (-(phase % TWO_PI)) / speed  # k = 0
    k0 = math.ceil((t0 - first) / period - 1e-12)
    k1 = math.floor((t1 - first) / period + 1e-12)
    return first + period * np.arange(k0, k1 + 1, dtype=np.float64)


class RailTables:
    """The round wheel's constraint on one rail, tabulated once per (radius, stretch) and kept.

    This is the wheel-independent part of the combined irregularity: a site computes it
    once and every candidate flat of every wheel of that radius reuses it.
    """

    def __init__(self, rail: RailProfile, capacity: int = 16) -> None:
        self.rail = rail
        self.capacity = capacity
        self._tables: OrderedDict[tuple[float, float, float], ConstraintTable] = OrderedDict()
        self._lock = threading.Lock()  # a diagnosis may simulate on several threads

    def table(self, radius: float, x0: float, x1: float) -> ConstraintTable:
        """Round-wheel constraint covering at least [x0, x1] (tabulated on a 1 m grid of ends)."""
        a = math.floor(x0) - 1.0
        b = math.ceil(x1) + 1.0
        key = (radius, a, b)
        with self._lock:
            t = self._tables.get(key)
            if t is None:
                t = tabulate_constraint(WheelOutline.round(radius), self.rail, a, b)
                self._tables[key] = t
                while len(self._tables) > self.capacity:
                    self._tables.popitem(last=False)
            else:
                self._tables.move_to_end(key)
            return t


def wheel_table(
    radius: float, flat: Tread | None, rails: RailTables, x0: float, x1: float
) -> ConstraintTable:
    """The combined-irregularity constraint of the wheel (``None``: round) over [x0, x1]."""
    a, b = x0 - TABLE_MARGIN, x1 + TABLE_MARGIN
    rail = rails.table(radius, a, b)
    if flat is None:
        return rail
    dx = WORN_TABLE_DX if isinstance(flat, Flat) and flat.kind == "rounded_flat" else None
    wheel = tabulate_constraint(
        flat.outline(radius), RailProfile.flat(), a, b, phase=flat.phase, dx=dx
    )
    if rails.rail.kind == "flat":
        return wheel
    return add_tables(wheel, rail, a, b)


def simulate_window(
    wheel: WheelOnSite,
    speed: float,
    table: ConstraintTable,
    t0: float,
    t1: float,
    sample_rate: float,
    initial: InitialState | None = None,
) -> PassageOutput:
    """The wheel from static equilibrium at t0 (rolling steadily there) to t1, or from
    ``initial`` (displacements from it and velocities)."""
    spec = PassageSpec(
        mass=wheel.mass,
        load=wheel.load,
        speed=speed,
        duration=t1 - t0,
        sample_rate=sample_rate,
        contact=wheel.contact,
        foundation=wheel.foundation,
        initial=initial,
        rtol=wheel.rtol,
        t0=t0,
    )
    return simulate_passage(table, spec, track_dents=False)


def run_in_length(radius: float) -> float:
    """m of track rolled before the site's start: ``RUN_IN_TURNS`` wheel turns."""
    return RUN_IN_TURNS * TWO_PI * radius


def simulate_passage_run_in(
    wheel: WheelOnSite,
    speed: float,
    flat: Tread | None,
    rails: RailTables,
    x_start: float,
    x_end: float,
    sample_rate: float,
) -> PassageOutput:
    """The wheel rolling from a run-in before ``x_start`` to ``x_end``; samples from the run-in on.

    Samples at t = k/sample_rate (k integer, so t = 0 is a sample) from the start of the
    run-in; callers keep t >= x_start/V.
    """
    x0 = x_start - run_in_length(wheel.radius)
    t0 = math.floor(x0 / speed * sample_rate) / sample_rate
    table = wheel_table(wheel.radius, flat, rails, speed * t0, x_end)
    return simulate_window(wheel, speed, table, t0, x_end / speed, sample_rate)
