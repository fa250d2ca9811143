"""A measuring site: the stretch of track the twin simulates every wheel over (``site.toml``).

The rail profile, material, contact law and foundation use the scenario's
models (CONTRACT.md); a site adds its id, its length and the sample rate of
the series it publishes. A rail may also come from a CSV file of ``x,y``
rows (m), ``{kind = "file", path = "rail.csv"}``, the path relative to the
site file (``service.wire.site`` reads it into a sampled rail).

    >>> s = SiteConfig.model_validate({
    ...     "site_id": "km12", "length": 6.0, "output_sample_rate": 10000.0,
    ...     "rail": {"kind": "flat"}, "contact": "hertz",
    ...     "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3}})
    >>> s.foundation.kind, s.contact
    ('rigid', 'hertz')
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from schemas._base import Positive, StrictModel, field_error
from schemas.calibration import SiteCalibration
from schemas.diagnosis import DiagnosisConfig
from schemas.messages import MESSAGE_SCHEMA_VERSION, Identifier, Version
from schemas.scenario import (
    CompliantFoundation,
    ContactName,
    CosineRail,
    FlatRail,
    Material,
    RigidFoundation,
    SampledRail,
    StepRail,
)
from schemas.track import (
    MAX_TRACK_LENGTH,
    Detector,
    DiscreteFoundation,
    SlabFoundation,
    check_track,
)

MAX_SITE_SAMPLES = 2_000_000
"""Cap on samples per passage (length/speed·sample_rate at 1 m/s): keeps messages sane."""

MAX_RAIL_POINTS = 200_000
"""Cap on the points of a site's sampled (or file) rail: 10^6 points made one passage 9 s."""


class FileRail(StrictModel):
    """A measured rail profile in a CSV file of ``x,y`` rows in metres (header optional)."""

    kind: Literal["file"]
    path: str = Field(description="CSV file, relative to the site file")


SiteRail = Annotated[
    FlatRail | CosineRail | StepRail | SampledRail | FileRail, Field(discriminator="kind")
]
SiteFoundation = Annotated[
    RigidFoundation | CompliantFoundation | DiscreteFoundation | SlabFoundation,
    Field(discriminator="kind"),
]


class SiteConfig(StrictModel):
    """Everything about the site that is the same for every wheel."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier = Field(description="site name; the Zenoh keys are railtwin/<site_id>/...")
    description: str = ""
    length: Positive = Field(
        le=1000.0,
        description="length of the simulated stretch, m; at most MAX_TRACK_LENGTH = "
        f"{MAX_TRACK_LENGTH:g} m on a discrete or slab foundation",
    )
    output_sample_rate: Positive = Field(
        le=1e6, description="samples per second of the published series, Hz"
    )
    rail: SiteRail = Field(
        description="the site's rail profile y_r(x), x from 0 to length; a sampled or file rail "
        f"has at most {MAX_RAIL_POINTS} points",
    )
    material: Material
    contact: ContactName = Field(description="contact law (MODEL.md §3)")
    foundation: SiteFoundation = Field(default_factory=lambda: RigidFoundation(kind="rigid"))
    detector: Detector | None = Field(
        default=None,
        description="shear-bridge channels in the cribs, within [0, length] (needs a discrete "
        "or slab foundation); their signals are each result's channels",
    )
    diagnosis: DiagnosisConfig = Field(
        default_factory=DiagnosisConfig,
        description="wheel-flat diagnosis: measuring chain, line speed, limits",
    )
    calibration: SiteCalibration | None = Field(
        default=None,
        description="where the foundation's values came from (absent: nominal, as drawn); "
        "written by `railtwin calibrate`",
    )
    rtol: float = Field(
        default=1e-8,
        ge=1e-14,
        le=1e-2,
        allow_inf_nan=False,
        description="integrator relative tolerance",
    )

    @model_validator(mode="after")
    def _check(self) -> SiteConfig:
        if isinstance(self.rail, SampledRail) and len(self.rail.x) > MAX_RAIL_POINTS:
            raise field_error(
                "rail.x",
                f"has {len(self.rail.x)} points, more than the {MAX_RAIL_POINTS} a "
                "site's rail may have (resample the profile)",
            )
        if self.contact != "hertz" and self.material.yield_stress is None:
            raise field_error("material.yield_stress", f"is required with contact {self.contact!r}")
        check_track(self.foundation, self.detector, self.length, "length", "length")
        return self
