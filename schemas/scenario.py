"""The scenario: one simulation case as JSON (CONTRACT.md, "Scenario").

Field names are fixed by CONTRACT.md; SI units; symbols as in MODEL.md.
Defaults (not in the contract's example, so that a minimal file stays short):
``wheel.phase`` = 0, ``foundation.damping`` = 0, ``initial`` = null (static
equilibrium), ``passes`` = 1, ``curvature_stiffness`` = false,
``constraint`` = ``"exact"``, ``rtol`` = 1e-9.

Worked example: the contract's scenario validates, and a flat longer than the
wheel's diameter is refused with the field named:

    >>> s = Scenario.model_validate_json(EXAMPLE_JSON)
    >>> s.wheel.outline.kind, s.contact, s.expected_samples
    ('round', 'hertz', 20000)
"""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Sequence
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from schemas._base import (
    SCHEMA_VERSION,
    Finite,
    NonNegative,
    Positive,
    StrictModel,
    field_error,
)
from schemas.track import (
    MAX_TRACK_LENGTH,
    Detector,
    DiscreteFoundation,
    SlabFoundation,
    check_track,
)

MAX_SAMPLES = 10_000_000
"""Cap on sample_rate·duration per passage.

The result holds ten series of that length in memory and in its JSON file
(about 200 bytes a sample as JSON): 1e7 samples is already ~2 GB. Longer runs
belong to the streaming service, not to one result file.
"""

MAX_PASSES = 100_000
"""Cap on the number of passes (each pass is a full simulation)."""

TWO_PI = 2.0 * math.pi

MAX_OUTLINE_POINTS = 4096
"""Cap on the points of a sampled wheel outline (a measured tread at 1 point a mm has ~2 900;
tabulating 4 096 takes ~0.3 s, 10^5 took 22 s)."""

# --- wheel outlines -------------------------------------------------------------------------


def first_not_increasing(values: Sequence[float]) -> int | None:
    """The first index whose value is not above the one before (NaN included), or None.

    Pure Python (the schemas need nothing but pydantic), one comparison a pair in C:

    >>> first_not_increasing([0.0, 1.0, 1.0, 2.0]), first_not_increasing([0.0, 0.5])
    (2, None)
    """
    ok = map(operator.lt, values, itertools.islice(values, 1, None))
    if all(ok):
        return None
    return next(i + 1 for i, (a, b) in enumerate(itertools.pairwise(values)) if not a < b)


class RoundOutline(StrictModel):
    """A perfectly round wheel: r(θ) = R."""

    kind: Literal["round"]


class FlatOutline(StrictModel):
    """An ideal (fresh) flat: a chord of ``length`` l < 2R (MODEL.md §2)."""

    kind: Literal["flat"]
    length: Positive = Field(description="chord length l of the flat, m")


class RoundedFlatOutline(StrictModel):
    """A rounded (worn, haversine) flat of ``length`` l and ``depth`` d < R (MODEL.md §2)."""

    kind: Literal["rounded_flat"]
    length: Positive = Field(description="length l of the flat along the tread, m")
    depth: Positive = Field(description="depth d of the flat, m")


class SampledOutline(StrictModel):
    """A measured outline r(θ): ``theta`` strictly increasing, spanning at most one turn.

    θ = 0 is the bottom of the wheel at φ = 0 (CONTRACT.md ``wheel.phase``); the
    outline is periodic, so the samples must lie within one turn (last - first
    < 2π: the last sample joins the first a turn later) and cover most of it
    (the gap closing the turn is no larger than a quarter turn). Radii are
    absolute (m), within 10 % of R.
    """

    kind: Literal["sampled"]
    theta: list[Finite] = Field(
        max_length=MAX_OUTLINE_POINTS,
        description=f"angles, rad, strictly increasing; at most {MAX_OUTLINE_POINTS} points",
    )
    radius: list[Positive] = Field(
        max_length=MAX_OUTLINE_POINTS,
        description=f"radius r(θ) at each angle, m; at most {MAX_OUTLINE_POINTS} points",
    )

    @model_validator(mode="after")
    def _check_samples(self) -> SampledOutline:
        if len(self.theta) != len(self.radius):
            raise field_error(
                "radius",
                f"has {len(self.radius)} values but theta has {len(self.theta)}: "
                "they must be the same length",
            )
        if len(self.theta) < 3:
            raise field_error("theta", f"needs at least 3 samples, got {len(self.theta)}")
        i = first_not_increasing(self.theta)
        if i is not None:
            raise field_error(
                f"theta[{i}]",
                f"must be strictly increasing: {self.theta[i]!r} follows {self.theta[i - 1]!r}",
            )
        span = self.theta[-1] - self.theta[0]
        if span >= TWO_PI:
            raise field_error(
                "theta",
                f"spans {span:.6g} rad: must be less than one turn (2π); the last sample "
                "joins the first one a turn later, so do not repeat it",
            )
        if TWO_PI - span > 0.5 * math.pi:
            raise field_error(
                "theta",
                f"spans only {span:.6g} rad: samples must cover the turn "
                "(last - first >= 1.5π; the outline is periodic)",
            )
        return self


Outline = Annotated[
    RoundOutline | FlatOutline | RoundedFlatOutline | SampledOutline,
    Field(discriminator="kind"),
]


class Wheel(StrictModel):
    """The wheel: unsprung mass m, load P (includes its weight), radius R, outline, phase φ0."""

    mass: Positive = Field(description="rolling (unsprung) mass m, kg")
    load: Positive = Field(description="constant vertical load P on m, includes its weight, N")
    radius: Positive = Field(description="wheel radius R (= effective radius R*), m")
    outline: Outline = Field(description="wheel outline r(θ)")
    phase: Finite = Field(
        default=0.0,
        description="initial rotation φ0, rad: φ = φ0 + x_C/R; any finite angle, taken "
        "modulo 2π (CONTRACT.md)",
    )

    @field_validator("phase")
    @classmethod
    def _wrap_phase(cls, v: float) -> float:
        return v % TWO_PI

    @model_validator(mode="after")
    def _check_geometry(self) -> Wheel:
        check_outline_fits(self.outline, self.radius)
        return self


def check_outline_fits(o: Outline, r: float) -> None:
    """Raise a field error when the outline does not fit a wheel of radius ``r`` (MODEL.md §2)."""
    if isinstance(o, FlatOutline) and not o.length < 2.0 * r:
        raise field_error(
            "outline.length",
            f"flat length {o.length!r} m must be < 2·radius = {2.0 * r!r} m "
            "(a chord cannot be longer than the diameter)",
        )
    if isinstance(o, RoundedFlatOutline):
        if not o.depth < r:
            raise field_error("outline.depth", f"depth {o.depth!r} m must be < radius = {r!r} m")
        if not o.length < TWO_PI * r:
            raise field_error(
                "outline.length",
                f"length {o.length!r} m must be < 2π·radius = {TWO_PI * r!r} m (the circumference)",
            )
    if isinstance(o, SampledOutline):
        for i, ri in enumerate(o.radius):
            if abs(ri - r) > 0.1 * r:
                raise field_error(
                    f"outline.radius[{i}]",
                    f"{ri!r} m is more than 10 % away from the wheel radius {r!r} m "
                    "(a sampled outline is an out-of-roundness around R)",
                )


# --- rail profiles --------------------------------------------------------------------------


class FlatRail(StrictModel):
    """An even rail: y_r = 0."""

    kind: Literal["flat"]


class CosineRail(StrictModel):
    """y_r = a·cos(2πx/λ)."""

    kind: Literal["cosine"]
    amplitude: NonNegative = Field(description="amplitude a, m")
    wavelength: Positive = Field(description="wavelength λ, m")


class StepRail(StrictModel):
    """y_r = 0 before ``position``, ``height`` after (a threshold)."""

    kind: Literal["step"]
    height: Finite = Field(description="step height, m (negative: a step down)")
    position: Finite = Field(description="x of the step, m")


class SampledRail(StrictModel):
    """A measured profile, linear between samples, flat at the end values outside them."""

    kind: Literal["sampled"]
    x: list[Finite] = Field(description="positions, m, strictly increasing")
    y: list[Finite] = Field(description="heights y_r(x), m")

    @model_validator(mode="after")
    def _check_samples(self) -> SampledRail:
        if len(self.x) != len(self.y):
            raise field_error(
                "y",
                f"has {len(self.y)} values but x has {len(self.x)}: they must be the same length",
            )
        if len(self.x) < 2:
            raise field_error("x", f"needs at least 2 samples, got {len(self.x)}")
        i = first_not_increasing(self.x)
        if i is not None:
            raise field_error(
                f"x[{i}]",
                f"must be strictly increasing: {self.x[i]!r} follows {self.x[i - 1]!r}",
            )
        return self


Rail = Annotated[
    FlatRail | CosineRail | StepRail | SampledRail,
    Field(discriminator="kind"),
]

# --- material, foundation, initial state ----------------------------------------------------


class Material(StrictModel):
    """Elastic constants of wheel and rail (the same for both) and the rail's yield stress."""

    youngs_modulus: Positive = Field(description="Young's modulus E, Pa")
    poisson_ratio: Finite = Field(gt=-1.0, lt=0.5, description="Poisson's ratio ν in (-1, 0.5)")
    yield_stress: Positive | None = Field(
        default=None,
        description="uniaxial yield stress Y, Pa; required for johnson and hertz_plastic",
    )


class RigidFoundation(StrictModel):
    """The rail does not move."""

    kind: Literal["rigid"]


class CompliantFoundation(StrictModel):
    """Effective mass M on a spring k and damper c (MODEL.md (6.1))."""

    kind: Literal["compliant"]
    mass: Positive = Field(description="effective foundation mass M, kg")
    stiffness: Positive = Field(description="foundation stiffness k, N/m")
    damping: NonNegative = Field(default=0.0, description="viscous damping c, N·s/m")


Foundation = Annotated[
    RigidFoundation | CompliantFoundation | DiscreteFoundation | SlabFoundation,
    Field(discriminator="kind"),
]
"""Rigid, one mass on a spring (MODEL.md (6.1)), or a rail on supports (MODEL.md §8,
``schemas.track``)."""


_NO_FOUNDATION_STATE = {
    "rigid": "must be 0 with a rigid foundation (there is no foundation mass to move)",
    "discrete": "must be 0 with a discrete foundation: only y_c and v_c may be nonzero (the "
    "track starts from its static equilibrium, at rest)",
    "slab": "must be 0 with a slab foundation: only y_c and v_c may be nonzero (the track "
    "starts from its static equilibrium, at rest)",
}
"""Why ``initial.y_m``/``v_m`` must be 0, by foundation kind (all but compliant)."""


class InitialState(StrictModel):
    """Displacements from static equilibrium (m) and velocities (m/s) at t = 0."""

    y_c: Finite = 0.0
    v_c: Finite = 0.0
    y_m: Finite = 0.0
    v_m: Finite = 0.0


ContactName = Literal["hertz", "johnson", "hertz_plastic"]

# --- the scenario ---------------------------------------------------------------------------


class Scenario(StrictModel):
    """One simulation case (CONTRACT.md)."""

    wheel: Wheel
    rail: Rail
    material: Material
    contact: ContactName = Field(description="contact law F(δ) (MODEL.md §3)")
    foundation: Foundation
    speed: Positive = Field(description="rolling speed V, m/s; x_C = V·t")
    duration: Positive = Field(
        description="simulated time per passage, s; on a discrete or slab foundation the "
        f"simulated stretch speed·duration is at most MAX_TRACK_LENGTH = {MAX_TRACK_LENGTH:g} m"
    )
    sample_rate: Positive = Field(description="output samples per second, Hz")
    initial: InitialState | None = Field(
        default=None,
        description="null: start from static equilibrium; y_m and v_m only with a compliant "
        "foundation",
    )
    passes: int = Field(default=1, ge=1, le=MAX_PASSES, description="wheels run one after another")
    curvature_stiffness: bool = Field(
        default=False, description="Hertz coefficient varying with the profile's curvature"
    )
    constraint: Literal["exact", "profile"] = Field(
        default="exact",
        description="'exact': rigid constraint of MODEL.md §2; 'profile': the rail profile itself",
    )
    rtol: float = Field(
        default=1e-9,
        ge=1e-14,
        le=1e-2,
        allow_inf_nan=False,
        description="integrator relative tolerance",
    )
    detector: Detector | None = Field(
        default=None,
        description="shear-bridge channels in the cribs (needs a discrete or slab foundation); "
        "their signals are the result's series.channels",
    )
    schema_version: str | None = Field(
        default=None, description=f"contract version; this build reads {SCHEMA_VERSION}"
    )

    @property
    def expected_samples(self) -> int:
        """Number of output samples of one passage (sample_rate·duration, rounded)."""
        return round(self.sample_rate * self.duration)

    @model_validator(mode="after")
    def _check_consistency(self) -> Scenario:
        if self.contact != "hertz" and self.material.yield_stress is None:
            raise field_error(
                "material.yield_stress",
                f"is required with contact {self.contact!r} (the plastic range starts at "
                "the yield force derived from it); give a value in Pa, e.g. 6.0e8",
            )
        if self.initial is not None and not isinstance(self.foundation, CompliantFoundation):
            for name in ("y_m", "v_m"):
                if getattr(self.initial, name) != 0.0:
                    raise field_error(f"initial.{name}", _NO_FOUNDATION_STATE[self.foundation.kind])
        check_track(
            self.foundation, self.detector, self.speed * self.duration, "duration", "speed·duration"
        )
        n = self.sample_rate * self.duration
        if n < 1.0:
            raise field_error(
                "sample_rate",
                f"sample_rate·duration = {n:.3g}: the run would have no sample interval; "
                "raise sample_rate or duration",
            )
        if n > MAX_SAMPLES:
            raise field_error(
                "sample_rate",
                f"sample_rate·duration = {n:.3g} samples, more than {MAX_SAMPLES:.0e}: the "
                "result keeps ten series of that length in memory and in its JSON file "
                f"(~{n * 200 / 1e9:.0f} GB); lower sample_rate or duration",
            )
        if self.schema_version is not None:
            major = self.schema_version.split(".")[0]
            if major != SCHEMA_VERSION.split(".")[0]:
                raise field_error(
                    "schema_version",
                    f"{self.schema_version!r} is not compatible with this build's "
                    f"{SCHEMA_VERSION!r} (major versions differ)",
                )
        return self


EXAMPLE_JSON = """{
  "wheel": {
    "mass": 400.0,
    "load": 39240.0,
    "radius": 0.475,
    "outline": {"kind": "round"},
    "phase": 0.0
  },
  "rail": {"kind": "cosine", "amplitude": 1.0e-4, "wavelength": 0.05},
  "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3, "yield_stress": 6.0e8},
  "contact": "hertz",
  "foundation": {"kind": "rigid"},
  "speed": 13.53,
  "duration": 0.2,
  "sample_rate": 100000.0,
  "initial": null,
  "passes": 1
}"""
"""The contract's example scenario, verbatim (CONTRACT.md)."""
