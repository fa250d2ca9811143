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

import numpy as np
from numpy.typing import NDArray

from sim_core.contact_laws import ContactModel

TRANSITION_KINDS = ("loss", "contact", "yield", "unyield")
"""Names of the transition codes 0..3 the integrator reports."""


@dataclass(frozen=True)
class Foundation:
    """Rigid (``mass``/``stiffness`` unused) or compliant foundation of MODEL.md (6.1)."""

    kind: str = "rigid"
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
                raise ValueError(f"compliant foundation: damping must be >= 0, got {self.damping!r}")

    @classmethod
    def rigid(cls) -> Foundation:
        return cls("rigid")

    @classmethod
    def compliant(cls, mass: float, stiffness: float, damping: float = 0.0) -> Foundation:
        return cls("compliant", mass, stiffness, damping)

    @property
    def is_compliant(self) -> bool:
        return self.kind == "compliant"


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
                raise ValueError(f"initial state: {name} must be finite, got {getattr(self, name)!r}")


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
    foundation: Foundation = field(default_factory=Foundation.rigid)
    initial: InitialState | None = None
    rtol: float = 1e-9
    t0: float = 0.0

    def __post_init__(self) -> None:
        for name in ("mass", "load", "speed", "duration", "sample_rate", "rtol"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"passage: {name} must be a positive finite number, got {v!r}")
        if not math.isfinite(self.t0):
            raise ValueError(f"passage: t0 must be finite, got {self.t0!r}")
        if self.rtol < 1e-14:
            raise ValueError(f"passage: rtol {self.rtol} is below what double precision can honour")


@dataclass(frozen=True)
class Transition:
    """A located change of contact state: ``kind`` in TRANSITION_KINDS, at time ``t``, position ``x``."""

    t: float
    kind: str
    x: float


@dataclass(frozen=True)
class PassageOutput:
    """Samples at ``sample_rate`` plus the exact transition list of one passage.

    ``delta_c``/``delta_c_x``: the largest indentation reached while the
    contact point was at each position (only where it exceeded δ_Y; empty for
    elastic passages) — the input of the dent computation (``sim_core.dents``).
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
    delta_c_x: NDArray[np.float64]
    delta_c: NDArray[np.float64]
    steps: int
    rejected_steps: int
    rhs_evaluations: int
    peak_force: float
    min_force: float
    max_indentation: float
    time_out_of_contact: float
