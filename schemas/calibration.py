"""A site's calibration: the track values learned from the round wheels that pass it.

A site file holds the track's values in ``foundation`` (from the design drawings: nominal,
or from ``railtwin calibrate``: estimated); its optional ``[calibration]`` table says where
they came from. A diagnosis names the calibration it used (``Diagnosis.calibration``), so
that a verdict can be traced to the values of the track behind it.

    >>> ref = CalibrationRef(source="offline", id="0123456789abcdef", wheels=12)
    >>> ref.label
    'offline:0123456789abcdef (12 wheels)'
    >>> SiteCalibration(source="nominal", id="0123456789abcdef").ref().wheels
    0
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from schemas._base import MessageModel, StrictModel

CalibrationSource = Literal["nominal", "offline", "online"]
"""``nominal``: the site file's values as drawn; ``offline``: estimated by ``railtwin
calibrate`` from a directory of round wheels; ``online``: updated by the twin from the round
wheels it has seen."""

CALIBRATION_ID_PATTERN = r"^[0-9a-f]{16}$"


class CalibrationRef(MessageModel):
    """Which calibration of the track a result used (echoed in a ``Diagnosis``)."""

    source: CalibrationSource = Field(description="where the track's values came from")
    id: str = Field(
        pattern=CALIBRATION_ID_PATTERN,
        description="fingerprint of the track values used: the first 16 hex digits of the "
        "SHA-256 of the foundation's canonical JSON",
    )
    wheels: int = Field(
        default=0, ge=0, description="round wheels the values were learned from (0: nominal)"
    )

    @property
    def label(self) -> str:
        """``source:id (n wheels)``, for people."""
        return f"{self.source}:{self.id} ({self.wheels} wheels)"


Identifiable = Literal["yes", "partly", "no"]
"""Whether the round wheels determine a parameter: ``yes`` (the data shrink its prior spread
to less than half), ``partly`` (to less than 0.9 of it: the prior still matters), ``no`` (the
estimate is the nominal's, whatever the data)."""

CalibratedName = Literal[
    "pad.stiffness", "pad.damping", "sleeper_mass", "ballast.stiffness", "ballast.damping"
]
"""The foundation's calibrated values, in the site file's names."""


class CalibratedParameter(StrictModel):
    """One calibrated value of the foundation: the nominal, the estimate, its 95 % interval."""

    name: CalibratedName = Field(description="the foundation's value (site file name)")
    nominal: float = Field(gt=0, allow_inf_nan=False, description="the value before calibration")
    estimate: float = Field(gt=0, allow_inf_nan=False, description="the calibrated value")
    low: float = Field(gt=0, allow_inf_nan=False, description="95 % interval, lower end")
    high: float = Field(gt=0, allow_inf_nan=False, description="95 % interval, upper end")
    identifiable: Identifiable = Field(description="whether the data determine it")

    @model_validator(mode="after")
    def _ordered(self) -> CalibratedParameter:
        if not self.low <= self.estimate <= self.high:
            raise ValueError(
                f"{self.name}: the interval [{self.low:g}, {self.high:g}] must hold the "
                f"estimate {self.estimate:g}"
            )
        return self


class SiteCalibration(StrictModel):
    """The site file's ``[calibration]`` table: the provenance of its ``foundation`` values.

    ``parameters`` and ``unresolved`` are written by ``railtwin calibrate`` and the twin's
    online calibration (optional: a hand-written table may leave them out)."""

    source: CalibrationSource = Field(description="where the foundation's values came from")
    id: str = Field(
        pattern=CALIBRATION_ID_PATTERN,
        description="fingerprint of the calibrated foundation (as CalibrationRef.id)",
    )
    wheels: int = Field(default=0, ge=0, description="round wheels the values were learned from")
    parameters: list[CalibratedParameter] | None = Field(
        default=None,
        max_length=5,
        description="each calibrated value with its nominal, 95 % interval and identifiability",
    )
    unresolved: list[str] | None = Field(
        default=None,
        max_length=5,
        description="combinations of the values the wheels cannot tell apart, as products of "
        "powers (e.g. 'pad.damping', 'sleeper_mass^-0.6·ballast.stiffness')",
    )
    residual_ratio: float | None = Field(
        default=None,
        gt=0,
        allow_inf_nan=False,
        description="largest residual rms / noise σ over the wheels, on the calibrated track",
    )

    def ref(self) -> CalibrationRef:
        """The reference a diagnosis carries."""
        return CalibrationRef(source=self.source, id=self.id, wheels=self.wheels)


__all__ = [
    "CALIBRATION_ID_PATTERN",
    "CalibratedName",
    "CalibratedParameter",
    "CalibrationRef",
    "CalibrationSource",
    "Identifiable",
    "SiteCalibration",
]
