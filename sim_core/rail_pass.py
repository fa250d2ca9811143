"""One wheel over a rail that keeps its dents: table → passage → dents → the rail after.

The one pass loop of both the scenario runner's multi-pass runs
(``sim_core.multipass``) and the streaming site (``service.physics.site_physics``):

1. the constraint table of the wheel on the rail as it is now
   (:class:`ConstraintTables`: a round wheel's table is kept per radius and
   only re-tabulated where a dent changed the rail);
2. the passage (``simulate_passage``);
3. with the Hertzian–perfectly plastic law, the plastic records pressed into
   the rail's dent overlay (``sim_core.dent_overlay``: the swept envelope).

The rail is a :class:`DentedRail`: the site's base profile, a dent overlay and
the stretch [x_lo, x_hi] it is materialised over (the passage's stretch plus
``RAIL_MARGIN``). Worked example (the paper's Fig. 8 start, two identical
wheels): the first presses ~0.4 mm dents, the second, on the same path, none::

    rail = DentedRail.of(RailProfile.flat(), 0.0, 0.56)
    tables = ConstraintTables()
    first = rail_pass(WheelOutline.round(0.475), rail, spec, tables)       # max_dent ≈ 4e-4
    second = rail_pass(WheelOutline.round(0.475), first.rail, spec, tables)  # max_dent ≈ 0
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint import curvature_stiffness_scale, profile_constraint, tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.dent_overlay import DentOverlay, dented_profile
from sim_core.dents import plastic_records
from sim_core.passage import PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline

__all__ = [
    "RAIL_MARGIN",
    "ConstraintTables",
    "DentedRail",
    "RailPass",
    "TableChoice",
    "rail_pass",
    "splice",
]

RAIL_MARGIN = 0.1
"""Rail kept beyond each end of the passages' stretch (m): more than the reach of a wheel on
a rail with dents up to ~10 mm deep (sqrt(2R·depth)) plus the table's own margin."""

REACH_SLACK = 2e-3
"""Added to the reach sqrt(2R·H) of a rail point (m) when choosing what a dent changes."""

TABLE_CACHE_SIZE = 32
"""Round wheels' tables kept (one per radius and stretch)."""

FLATS = ("ideal_flat", "rounded_flat")
"""Outlines inside the nominal circle everywhere but on a flat: their tables are the round
wheel's but near the flat."""

FLAT_ZONE_MARGIN = 1e-3
"""Added to a flat's angular reach (rad) when choosing where its table differs from round."""

KEPT_CHANGES = 256
"""Revisions whose changed stretch a rail remembers (a table older than that is remade whole)."""
"""Round wheels' tables kept (one per radius and stretch)."""


@dataclass(frozen=True)
class TableChoice:
    """Which constraint a passage runs on: ``"exact"`` (MODEL.md §2, the wheel turned by
    φ0 = ``phase`` at x_C = 0) or ``"profile"`` (the rail profile itself), optionally with
    the curvature-dependent Hertz coefficient."""

    phase: float = 0.0
    constraint: str = "exact"
    curvature_stiffness: bool = False

    def __post_init__(self) -> None:
        if self.constraint not in ("exact", "profile"):
            raise ValueError(f"constraint must be 'exact' or 'profile', got {self.constraint!r}")


EXACT = TableChoice()


@dataclass(frozen=True)
class DentedRail:
    """The base profile with the dents of ``revision`` dented passages, over [x_lo, x_hi]."""

    base: RailProfile
    overlay: DentOverlay
    x_lo: float
    x_hi: float
    revision: int = 0
    changes: tuple[tuple[float, float], ...] = ()
    """The stretches whose heights the last ``len(changes)`` revisions changed, oldest first
    (at most ``KEPT_CHANGES``; a restored rail knows none)."""
    _profile: list[RailProfile] = field(default_factory=list, init=False, repr=False, compare=False)

    @classmethod
    def of(cls, base: RailProfile, x_start: float, x_end: float) -> DentedRail:
        """The undented ``base`` for passages over [x_start, x_end]."""
        return cls(base, DentOverlay.empty(), x_start - RAIL_MARGIN, x_end + RAIL_MARGIN)

    @classmethod
    def restored(
        cls, base: RailProfile, stored: RailProfile, revision: int, x_start: float, x_end: float
    ) -> DentedRail:
        """A rail stored as a sampled profile (``profile``) back over ``base``."""
        rail = cls.of(base, x_start, x_end)
        return dataclasses.replace(
            rail, overlay=DentOverlay.from_profile(base, stored), revision=revision
        )

    @property
    def profile(self) -> RailProfile:
        """The rail as one profile (``base`` itself while undented); made once."""
        if not self._profile:
            self._profile.append(dented_profile(self.base, self.overlay, self.x_lo, self.x_hi))
        return self._profile[0]

    @property
    def max_dent(self) -> float:
        return self.overlay.max_depth

    def reach(self, radius: float) -> float:
        """Farthest a rail point can be from a wheel centre it carries (m): sqrt(2R·H)."""
        lo, hi = self.base.height_range
        h = (hi - lo) + self.overlay.max_depth
        return math.sqrt(2.0 * radius * h) + REACH_SLACK

    def pressed(
        self, centres: NDArray[np.float64], bottoms: NDArray[np.float64], radius: float
    ) -> DentedRail:
        """The rail with circles of ``radius`` pressed in (``DentOverlay.pressed``)."""
        overlay, changed = self.overlay.pressed(self.base, centres, bottoms, radius)
        if changed is None:
            return self
        changes = (*self.changes[-KEPT_CHANGES + 1 :], changed)
        return DentedRail(self.base, overlay, self.x_lo, self.x_hi, self.revision + 1, changes)

    def changed_since(self, revision: int, widen: float = 0.0) -> list[tuple[float, float]] | None:
        """The stretches changed after ``revision``, each widened by ``widen`` on both sides,
        merged and sorted; None if not known."""
        n = self.revision - revision
        if n < 0 or n > len(self.changes):
            return None
        merged: list[tuple[float, float]] = []
        for a0, b0 in sorted(self.changes[len(self.changes) - n :]):
            a, b = a0 - widen, b0 + widen
            if merged and a <= merged[-1][1]:
                merged[-1] = (merged[-1][0], max(b, merged[-1][1]))
            else:
                merged.append((a, b))
        return merged


def splice(table: ConstraintTable, window: ConstraintTable, a: float, b: float) -> ConstraintTable:
    """``table`` with its nodes in [a, b] replaced by those of ``window`` (both non-periodic).

    Exact when both tables hold the exact constraint of the same rail near a and b: the
    Hermite piece that spans a (or b) then joins two exact nodes with no change of contact
    piece between them (every such change is a node of one of the tables).
    """
    if table.period or window.period:
        raise ValueError("splice: both tables must be non-periodic")
    lo, hi = table.x < a, table.x > b
    inner = (window.x >= a) & (window.x <= b)

    def cat(name: str) -> NDArray[np.float64]:
        t, w = getattr(table, name), getattr(window, name)
        return np.concatenate((t[lo], w[inner], t[hi]))

    kinks = np.concatenate(
        (
            table.kinks[(table.kinks < a) | (table.kinks > b)],
            window.kinks[(window.kinks >= a) & (window.kinks <= b)],
        )
    )
    return ConstraintTable(
        x=cat("x"),
        y=cat("y"),
        slope_left=cat("slope_left"),
        slope_right=cat("slope_right"),
        contact_x=cat("contact_x"),
        kinks=np.sort(kinks),
        period=0.0,
        resolution=min(table.resolution, window.resolution),
    )


def flat_zones(
    wheel: WheelOutline, phase: float, reach: float, x_lo: float, x_hi: float
) -> list[tuple[float, float]]:
    """Stretches of [x_lo, x_hi] where a flat (|θ| <= its half angle, r <= R) can carry the
    wheel: the wheel angle φ = φ0 + x/R within the half angle plus asin(reach/R) (the
    farthest a contact point on this rail lies from the vertical) of a multiple of 2π.
    Elsewhere the flat, inside the nominal circle, does not touch: the round wheel's table
    holds. A 50 mm flat of a 0.46 m wheel: a 70 mm stretch every 2.89 m on a rail whose
    heights span 30 µm."""
    R = wheel.nominal_radius
    w = R * (wheel.flat_half_angle + math.asin(min(1.0, reach / R)) + FLAT_ZONE_MARGIN)
    two_pi_r = 2.0 * math.pi * R
    first = math.ceil((x_lo - w + phase * R) / two_pi_r)
    zones: list[tuple[float, float]] = []
    k = first
    while (c := k * two_pi_r - phase * R) - w < x_hi:
        a, b = max(c - w, x_lo), min(c + w, x_hi)
        if b > a:
            zones.append((a, b))
        k += 1
    return zones


def _round_on(rail: DentedRail, radius: float, a: float, b: float) -> ConstraintTable:
    """The round wheel's exact table over [a, b] on the rail's samples within reach of it."""
    return tabulate_constraint(WheelOutline.round(radius), _window_rail(rail, radius, a, b), a, b)


def _window_rail(rail: DentedRail, radius: float, a: float, b: float) -> RailProfile:
    """The rail's samples within reach of the wheel centres [a, b]."""
    e = rail.reach(radius)
    prof = rail.profile
    # the profile's own samples (no new vertex: the window's resolution, the finest sample
    # spacing, is then the whole rail's there), from the last at or before a - e
    i0 = max(int(np.searchsorted(prof.x, a - e, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(prof.x, b + e, side="left")) + 1, prof.x.size)
    return RailProfile.sampled(prof.x[i0:i1], prof.y[i0:i1])


class ConstraintTables:
    """Constraint tables of wheels on a :class:`DentedRail`.

    A round wheel's table is kept per (radius, stretch) with the rail revision it was made
    for. When the rail has moved on by one revision, only the stretch that revision changed
    (widened by the reach) is re-tabulated and spliced in; otherwise it is tabulated whole.
    Out-of-round wheels are tabulated per passage on the rail's profile (which the rail
    makes once per revision). One instance serves one rail history (revisions are its keys).
    """

    def __init__(self, size: int = TABLE_CACHE_SIZE) -> None:
        self._round: OrderedDict[tuple[float, float, float], tuple[int, ConstraintTable]] = (
            OrderedDict()
        )
        self._size = size
        self.spliced = 0
        self.whole = 0

    def clear(self) -> None:
        self._round.clear()

    def table(
        self,
        wheel: WheelOutline,
        rail: DentedRail,
        x_start: float,
        x_end: float,
        how: TableChoice = EXACT,
    ) -> ConstraintTable:
        """The table a passage over [x_start, x_end] needs: the exact constraint or the profile."""
        phase = how.phase
        if how.constraint == "exact":
            if wheel.kind == "round":
                table = self._round_table(wheel.nominal_radius, rail, x_start, x_end)
            elif wheel.kind in FLATS and not rail.overlay.is_empty:
                table = self._flat_table(wheel, rail, x_start, x_end, phase)
            else:
                table = tabulate_constraint(wheel, rail.profile, x_start, x_end, phase=phase)
        else:
            table = profile_constraint(rail.profile, x_start, x_end)
        if how.curvature_stiffness:
            scale = curvature_stiffness_scale(table, rail.profile, wheel.nominal_radius)
            table = dataclasses.replace(table, stiffness_scale=scale)
        return table

    def _flat_table(
        self, wheel: WheelOutline, rail: DentedRail, x_start: float, x_end: float, phase: float
    ) -> ConstraintTable:
        """A flat wheel's table: the round wheel's (kept, spliced) where the flat cannot be
        the contact, the flat wheel's tabulated on the rail's samples where it can."""
        R = wheel.nominal_radius
        table = self._round_table(R, rail, x_start, x_end)
        for a, b in flat_zones(wheel, phase, rail.reach(R), float(table.x[0]), float(table.x[-1])):
            window = tabulate_constraint(wheel, _window_rail(rail, R, a, b), a, b, phase=phase)
            table = splice(table, window, a, b)
        return table

    def _round_table(
        self, radius: float, rail: DentedRail, x_start: float, x_end: float
    ) -> ConstraintTable:
        key = (float(radius), float(x_start), float(x_end))
        hit = self._round.get(key)
        if hit is not None and hit[0] == rail.revision:
            self._round.move_to_end(key)
            return hit[1]
        if rail.overlay.is_empty:  # the base: a periodic table where it has one
            table = tabulate_constraint(WheelOutline.round(radius), rail.base, x_start, x_end)
        elif (
            hit is not None
            and hit[1].period == 0.0
            and (changes := rail.changed_since(hit[0], rail.reach(radius))) is not None
        ):
            table = hit[1]
            for a, b in changes:
                table = splice(table, _round_on(rail, radius, a, b), a, b)
            self.spliced += 1
        else:
            table = tabulate_constraint(WheelOutline.round(radius), rail.profile, x_start, x_end)
            self.whole += 1
        self._round[key] = (rail.revision, table)
        self._round.move_to_end(key)
        while len(self._round) > self._size:
            self._round.popitem(last=False)
        return table


@dataclass(frozen=True)
class RailPass:
    """One passage: its output, the table it ran on, the rail after it, its deepest new dent."""

    output: PassageOutput
    table: ConstraintTable
    rail: DentedRail
    max_dent: float


def rail_pass(
    wheel: WheelOutline,
    rail: DentedRail,
    spec: PassageSpec,
    tables: ConstraintTables,
    how: TableChoice = EXACT,
) -> RailPass:
    """Simulate ``wheel`` over ``rail`` and press its dents in (module docstring).

    ``max_dent`` is the deepest the rail was lowered by this passage (m).
    """
    x_start = spec.speed * spec.t0
    x_end = x_start + spec.speed * spec.duration
    table = tables.table(wheel, rail, x_start, x_end, how)
    out = simulate_passage(table, spec)
    if spec.contact.law != ContactLaw.HERTZ_PLASTIC:
        return RailPass(out, table, rail, 0.0)
    t, xd, delta = plastic_records(out)
    if t.size == 0:
        return RailPass(out, table, rail, 0.0)
    depth = delta - spec.contact.yield_indentation
    R = wheel.nominal_radius
    # a press shallower than the dent polyline's own chord error h²/8R (66 nm) is below what
    # the rail can hold: the next wheel over a dent meets its chords that much early
    keep = depth > rail.overlay.spacing**2 / (8.0 * R)
    if not np.any(keep):
        return RailPass(out, table, rail, 0.0)
    t, xd, depth = t[keep], xd[keep], depth[keep]
    if wheel.kind == "round" and how.constraint == "exact":
        # the wheel's circle about its centre, where it stood (y_C + δ_Y above y_C^k - δ)
        centres = spec.speed * t
        bottoms = table.evaluate(centres) - depth
    else:  # the point-wise rule at the contact point, with the nominal circle's footprint
        centres = xd
        bottoms = rail.profile.height(xd) - depth
    after = rail.pressed(centres, bottoms, R)
    grown = 0.0
    if after is not rail:
        a, b = after.changes[-1]
        probe = after.overlay.x[(after.overlay.x >= a) & (after.overlay.x <= b)]
        grown = float(np.max(after.overlay.at(probe) - rail.overlay.at(probe), initial=0.0))
    return RailPass(out, table, after, grown)
