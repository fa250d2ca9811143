"""One wheel passage: the equations of motion of MODEL.md §4 over a tabulated constraint.

The wheel (unsprung mass m, constant load P) rolls at constant speed V, so
x_C = V·t. On a rigid foundation

    m·ÿ_C = -P + F(δ),   δ = -y_C + y_C^k(V·t)

and on a compliant one (effective mass M, stiffness k, damper c)

    M·ÿ_M = -F(δ) - k·y_M - c·ẏ_M,   δ = -y_C + y_C^k(V·t) + y_M.

Worked example (the paper's wheel at rest on a flat rail): started from static
equilibrium it stays there, pressed δ0 = (P/C)^(2/3) = 50.9 µm into the rail,

    >>> from sim_core.materials import Material, derive
    >>> from sim_core.contact_laws import ContactLaw, ContactModel
    >>> from sim_core.constraint import flat_constraint
    >>> d = derive(Material(2.14e11, 0.3), radius=0.475, load=39240.0, mass=400.0)
    >>> spec = PassageSpec(mass=400.0, load=39240.0, speed=20.0, duration=0.01,
    ...                    sample_rate=1e4, contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient))
    >>> out = simulate_passage(flat_constraint(), spec)
    >>> round(float(out.delta.max()) * 1e6, 1), len(out.transitions)
    (50.9, 0)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.integrate.loop import integrate, jump_allowance
from sim_core.integrate.model import curvature_bound
from sim_core.integrate.types import (
    MODE_NAMES,
    S_CONTACT,
    S_DELTA,
    S_FORCE,
    S_T,
    S_VC,
    S_VM,
    S_X,
    S_YC,
    S_YCK,
    S_YM,
    STEP_TOO_SMALL,
    TOO_MANY_STEPS,
    X_MIN_FORCE,
    X_PEAK_DELTA,
    X_PEAK_FORCE,
    X_T_FLIGHT,
    Event,
    Params,
    TransitionKind,
    table_of,
)
from sim_core.track.spec import Crib
from sim_core.under_rail import UnderRail

RESOLUTION_STEP = 3.0
"""A step in contact advances the wheel by at most this many ``table.resolution``: the
12 DOP853 stages leave gaps of at most 0.267 of a step, so every feature of the
inputs (at least two samples wide) is still seen by a stage, and the error estimate
then shortens the step."""

DENT_SPACING = 1e-4
"""Wheel travel (m) between records of the plastic indentation (dents are mm to cm long).

Each record becomes a circle of the wheel pressed into the rail (``sim_core.dent_overlay``);
between two circles Δ apart their envelope stands at most Δ²/8R above the continuous one:
2.6 nm for the paper's R = 0.475 m, the yield switch's own width (``contact_laws.
YIELD_HYSTERESIS``) and 25× below the dent lattice's 66 nm chord error. Against 20 µm
(case (c) of ``benchmarks.core_bench``): dents within 13 nm, the same transitions, a fifth
of the records to take and press."""

TRANSITION_KINDS: tuple[TransitionKind, ...] = tuple(e.label for e in Event)
"""Names of the transition codes 0..3 the integrator reports (``sim_core.integrate.types.Event``)."""


FoundationKind = Literal["rigid", "compliant"]
"""Rigid track, or a mass on a spring and damper (MODEL.md (6.1))."""


@dataclass(frozen=True)
class Foundation:
    """Rigid (``mass``/``stiffness`` unused) or compliant foundation of MODEL.md (6.1)."""

    kind: FoundationKind = "rigid"
    mass: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in ("rigid", "compliant"):
            raise ValueError(f"foundation kind must be 'rigid' or 'compliant', got {self.kind!r}")
        if self.kind == "compliant":
            for name in ("mass", "stiffness"):
                v = getattr(self, name)
                if not (math.isfinite(v) and v > 0):
                    raise ValueError(f"compliant foundation: {name} must be positive, got {v!r}")
            if not (math.isfinite(self.damping) and self.damping >= 0):
                raise ValueError(
                    f"compliant foundation: damping must be >= 0, got {self.damping!r}"
                )

    @classmethod
    def rigid(cls) -> Foundation:
        return cls("rigid")

    @classmethod
    def compliant(cls, mass: float, stiffness: float, damping: float = 0.0) -> Foundation:
        return cls("compliant", mass, stiffness, damping)

    @property
    def is_compliant(self) -> bool:
        return self.kind == "compliant"

    # --- sim_core.under_rail.UnderRail ---

    @property
    def carries_detector(self) -> bool:
        """A lumped foundation has no rail to put gauges on."""
        return False

    def prepare(self, x0: float, x1: float, cribs: tuple[Crib, ...] = ()) -> None:
        """Nothing to prepare: the lumped equations need no precomputation."""

    def simulate(
        self,
        table: ConstraintTable,
        spec: PassageSpec,
        *,
        track_dents: bool | None,
        dent_spacing: float,
        max_steps: int,
    ) -> PassageOutput:
        """The compiled adaptive integrator over the 4-state (wheel, foundation mass) system."""
        return _simulate_lumped(
            table,
            spec,
            self,
            track_dents=track_dents,
            dent_spacing=dent_spacing,
            max_steps=max_steps,
        )


@dataclass(frozen=True)
class InitialState:
    """Initial displacements from static equilibrium (m) and velocities (m/s)."""

    y_c: float = 0.0
    v_c: float = 0.0
    y_m: float = 0.0
    v_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("y_c", "v_c", "y_m", "v_m"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(
                    f"initial state: {name} must be finite, got {getattr(self, name)!r}"
                )


@dataclass(frozen=True)
class PassageSpec:
    """Everything about one passage except the geometry (which the table holds).

    ``rtol`` is the integrator's relative tolerance; absolute tolerances are
    scaled from it by the static indentation and the contact frequency.
    ``t0`` is the time at which x_C = V·t0 (passages start at x_C = 0 by default).
    """

    mass: float
    load: float
    speed: float
    duration: float
    sample_rate: float
    contact: ContactModel
    foundation: UnderRail = field(default_factory=Foundation.rigid)
    """What lies under the rail (``sim_core.under_rail``): rigid, compliant, discrete or slab."""
    initial: InitialState | None = None
    rtol: float = 1e-9
    t0: float = 0.0
    cribs: tuple[Crib, ...] = ()
    """The detector's cribs (a rail on supports only): each gets a channel in the output."""

    def __post_init__(self) -> None:
        for name in ("mass", "load", "speed", "duration", "sample_rate", "rtol"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"passage: {name} must be a positive finite number, got {v!r}")
        if not math.isfinite(self.t0):
            raise ValueError(f"passage: t0 must be finite, got {self.t0!r}")
        if self.rtol < 1e-14:
            raise ValueError(f"passage: rtol {self.rtol} is below what double precision can honour")
        if self.cribs and not self.foundation.carries_detector:
            raise ValueError("passage: cribs need a rail on supports (a discrete or slab track)")


class Transition(NamedTuple):
    """A located change of contact state: ``kind`` in TRANSITION_KINDS, at time ``t``, position ``x``.

    A named tuple, not a frozen dataclass: a passage builds one per transition, and a
    frozen dataclass's ``__init__`` (three ``object.__setattr__``) cost 0.8 µs each,
    64 µs of Fig. 4's 1.5 ms passage with its 83 transitions.
    """

    t: float
    kind: TransitionKind
    x: float


@dataclass(frozen=True)
class PassageOutput:
    """Samples at ``sample_rate`` plus the exact transition list of one passage.

    ``delta_c_t``, ``delta_c_x``, ``delta_c``: the indentation δ recorded at
    the contact point x_D at times t, densely (every ``dent_spacing`` of
    travel) while the contact was plastic; empty for elastic passages. The
    input of the dent computation (``sim_core.dents``).
    """

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    y_c: NDArray[np.float64]
    v_c: NDArray[np.float64]
    y_ck: NDArray[np.float64]
    y_m: NDArray[np.float64]
    v_m: NDArray[np.float64]
    delta: NDArray[np.float64]
    force: NDArray[np.float64]
    in_contact: NDArray[np.bool_]
    transitions: tuple[Transition, ...]
    delta_c_t: NDArray[np.float64]
    delta_c_x: NDArray[np.float64]
    delta_c: NDArray[np.float64]
    steps: int
    rejected_steps: int
    rhs_evaluations: int
    peak_force: float
    min_force: float
    max_indentation: float
    time_out_of_contact: float
    channels: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    """Per crib id, Q(x_a) − Q(x_b) at the samples (N); empty without a detector."""


def _transitions(rows: NDArray[np.float64], speed: float) -> tuple[Transition, ...]:
    """The integrator's (t, code) rows as ``Transition``s, x = t·speed.

    Built column-wise through ``Transition._make`` (no Python-level ``__new__`` and no
    ``int()`` per row): Fig. 4's 72 transitions at rtol 1e-7 cost 25 µs so, 34 µs row by row.

        >>> _transitions(np.array([[0.5, 1.0], [1.5, 0.0]]), 2.0)[1]
        Transition(t=1.5, kind='loss', x=3.0)
    """
    times = rows[:, 0].tolist()
    kinds = [TRANSITION_KINDS[k] for k in rows[:, 1].astype(np.int64).tolist()]
    xs = (rows[:, 0] * speed).tolist()
    return tuple(map(Transition._make, zip(times, kinds, xs, strict=True)))


def static_indentation(contact: ContactModel, load: float, scale: float = 1.0) -> float:
    """The indentation at which the loading branch carries ``load`` (F(δ) = P).

    Raises ValueError if the law cannot carry it (Hertzian–perfectly plastic with P >= F_Y).
    """
    c = contact.coefficient * scale
    d_hertz = (load / c) ** (2.0 / 3.0)
    if not contact.law.is_plastic or d_hertz <= contact.yield_indentation:
        return d_hertz
    if contact.law == ContactLaw.HERTZ_PLASTIC:
        raise ValueError(
            f"the load {load:g} N exceeds the yield force {contact.yield_force:g} N: "
            "a Hertzian-perfectly plastic contact has no static equilibrium"
        )
    lo, hi = contact.yield_indentation, contact.yield_indentation
    while float(contact.force(hi)[0]) < load:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if float(contact.force(mid)[0]) < load:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


class IntegrationError(RuntimeError):
    """The integrator could not finish the passage (step too small, too many steps)."""


def simulate_passage(
    table: ConstraintTable,
    spec: PassageSpec,
    *,
    track_dents: bool | None = None,
    dent_spacing: float | None = None,
    max_steps: int = 50_000_000,
) -> PassageOutput:
    """Simulate one wheel passage over the tabulated constraint ``table``.

    The wheel centre moves at x_C = V·t for t in [t0, t0 + duration]; samples
    are taken at t0 + i/sample_rate. Transitions (loss/return of contact,
    yield/unyield) are located exactly; peak force and extreme indentations are
    taken from the continuous solution, not from the samples.

    ``track_dents`` (default: on for the Hertzian–perfectly plastic law)
    records the largest indentation at each contact point while plastic, every
    ``dent_spacing`` metres of wheel travel (default ``DENT_SPACING``).
    """
    return spec.foundation.simulate(
        table,
        spec,
        track_dents=track_dents,
        dent_spacing=DENT_SPACING if dent_spacing is None else dent_spacing,
        max_steps=max_steps,
    )


def _simulate_lumped(
    table: ConstraintTable,
    spec: PassageSpec,
    foundation: Foundation,
    *,
    track_dents: bool | None,
    dent_spacing: float,
    max_steps: int,
) -> PassageOutput:
    """``simulate_passage`` on a rigid or compliant foundation (``Foundation.simulate``)."""
    law = spec.contact.law
    if track_dents is None:
        track_dents = law == ContactLaw.HERTZ_PLASTIC
    v = spec.speed
    t0 = spec.t0
    t1 = t0 + spec.duration
    compliant = foundation.is_compliant
    scale0 = 1.0
    if table.stiffness_scale.size:
        scale0 = float(np.interp(v * t0, table.x, table.stiffness_scale))
    d0 = static_indentation(spec.contact, spec.load, scale0)
    k_lin = 1.5 * spec.contact.coefficient * scale0 * math.sqrt(d0)
    omega0 = math.sqrt(k_lin / spec.mass)
    ck0 = float(table.evaluate(np.array([v * t0]))[0])
    ym0 = -spec.load / foundation.stiffness if compliant else 0.0
    init = spec.initial or InitialState()
    y0 = np.array(
        [
            ck0 + ym0 - d0 + init.y_c,
            init.v_c,
            (ym0 + init.y_m) if compliant else 0.0,
            init.v_m if compliant else 0.0,
        ]
    )
    if not compliant and (init.y_m != 0.0 or init.v_m != 0.0):
        raise ValueError("initial y_m/v_m given for a rigid foundation")
    tab = table_of(table)
    par = Params.build(
        law=int(law),
        c=spec.contact.coefficient,
        f_y=spec.contact.yield_force,
        d_y=spec.contact.yield_indentation,
        theta=spec.contact.johnson_coefficient,
        hyst=spec.contact.switch_width,
        mass=spec.mass,
        load=spec.load,
        speed=v,
        compliant=compliant,
        f_mass=foundation.mass if compliant else 1.0,
        f_stiff=foundation.stiffness if compliant else 0.0,
        f_damp=foundation.damping if compliant else 0.0,
        rtol=spec.rtol,
        atol_y=spec.rtol * d0,
        atol_v=spec.rtol * d0 * omega0,
        hmax_contact=RESOLUTION_STEP * table.resolution / v,
        c2max=curvature_bound(tab),
        track_dents=track_dents,
        dent_dx=dent_spacing,
    )
    n_samples = math.floor(spec.duration * spec.sample_rate * (1 + 1e-12)) + 1
    # the last sample may round past t1 by an ulp: it is t1 (else the integrator, which stops
    # at t1, would leave it unfilled as a row of zeros)
    sample_t = np.minimum(t0 + np.arange(n_samples) / spec.sample_rate, t1)
    x0, x1 = v * t0 - 1e-12, v * t1 + table.resolution
    kinks = table.kinks_between(x0, x1)
    # curvature jumps no contact step (at most hmax_contact) could be hurt by are left out
    jumps, jump_sizes = table.curvature_jumps_between(
        x0, x1, jump_allowance(par) / par.hmax_contact**3
    )
    res = integrate(
        tab,
        np.ascontiguousarray(kinks, dtype=np.float64),
        np.ascontiguousarray(jumps, dtype=np.float64),
        np.ascontiguousarray(jump_sizes, dtype=np.float64),
        par,
        float(t0),
        float(t1),
        y0,
        sample_t,
        int(max_steps),
    )
    if res.status == STEP_TOO_SMALL:
        raise IntegrationError(
            f"the step size fell below 1e-15 s at t = {res.t_end:.9g} s (x = {v * res.t_end:.6g} m, "
            f"mode {MODE_NAMES[res.mode_end]}): the solution is not resolvable there"
        )
    if res.status == TOO_MANY_STEPS:
        raise IntegrationError(f"more than {max_steps} steps: raise max_steps or relax rtol")
    ext = res.extrema
    peak_delta = float(ext[X_PEAK_DELTA])
    t_flight = float(ext[X_T_FLIGHT])
    peak_force, least_force = float(ext[X_PEAK_FORCE]), float(ext[X_MIN_FORCE])
    transitions = _transitions(res.transitions, v)
    ever_lost = any(tr.kind == "loss" for tr in transitions) or t_flight > 0.0
    min_force = 0.0 if ever_lost else least_force
    dents = res.dents
    if dents.shape[0] and law == ContactLaw.HERTZ_PLASTIC:
        dent_t, dent_x, dent_d = dents[:, 0], dents[:, 1], dents[:, 2]
    else:
        dent_t = dent_x = dent_d = np.empty(0)
    s = res.samples
    return PassageOutput(
        t=s[:, S_T],
        x=s[:, S_X],
        y_c=s[:, S_YC],
        v_c=s[:, S_VC],
        y_ck=s[:, S_YCK],
        y_m=s[:, S_YM],
        v_m=s[:, S_VM],
        delta=s[:, S_DELTA],
        force=s[:, S_FORCE],
        in_contact=s[:, S_CONTACT] > 0.5,
        transitions=transitions,
        delta_c_t=dent_t,
        delta_c_x=dent_x,
        delta_c=dent_d,
        steps=int(res.steps),
        rejected_steps=int(res.rejected),
        rhs_evaluations=int(res.rhs_evaluations),
        peak_force=peak_force,
        min_force=min_force,
        max_indentation=peak_delta,
        time_out_of_contact=t_flight,
    )
