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

HISTORY = 1000
"""The online calibration keeps this many of its last updates."""


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


class OnlineStep(StrictModel):
    """One round wheel's update of the online calibration."""

    passage_id: str = Field(max_length=200, description="the wheel's passage")
    timestamp: float = Field(allow_inf_nan=False, description="the passage's timestamp, UNIX s")
    requested: list[float] = Field(
        max_length=5, description="the change of each ln(value) the wheel asked for"
    )
    applied: list[float] = Field(
        max_length=5, description="the change made, within the per-wheel step and the range"
    )
    factors: list[float] = Field(
        max_length=5, description="each value over the site file's after this wheel"
    )
    residual_ratio: float = Field(
        ge=0, allow_inf_nan=False, description="the wheel's residual rms / noise before it"
    )


class OnlineCalibrationState(StrictModel):
    """The twin's online calibration as kept in its state directory
    (``<state>/<site_id>.calibration.json``): where it stands and its history."""

    site_id: str = Field(max_length=200, description="the site")
    start_id: str = Field(
        pattern=CALIBRATION_ID_PATTERN,
        description="fingerprint of the site file's foundation the factors apply to; "
        "another one starts afresh",
    )
    names: list[CalibratedName] = Field(max_length=5, description="the calibrated values")
    start: list[float] = Field(max_length=5, description="the site file's values")
    z: list[float] = Field(max_length=5, description="ln(value / start) now")
    information: list[list[float]] = Field(
        max_length=5, description="the information matrix in ln(value) (prior and wheels)"
    )
    wheels: int = Field(ge=0, description="round wheels that updated it")
    history: list[OnlineStep] = Field(
        default_factory=list,
        max_length=HISTORY,
        description=f"the last {HISTORY} updates, oldest first",
    )


__all__ = [
    "CALIBRATION_ID_PATTERN",
    "HISTORY",
    "CalibratedName",
    "CalibratedParameter",
    "CalibrationRef",
    "CalibrationSource",
    "Identifiable",
    "OnlineCalibrationState",
    "OnlineStep",
    "SiteCalibration",
]
