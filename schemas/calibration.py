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

from pydantic import Field

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


class SiteCalibration(StrictModel):
    """The site file's ``[calibration]`` table: the provenance of its ``foundation`` values."""

    source: CalibrationSource = Field(description="where the foundation's values came from")
    id: str = Field(
        pattern=CALIBRATION_ID_PATTERN,
        description="fingerprint of the calibrated foundation (as CalibrationRef.id)",
    )
    wheels: int = Field(default=0, ge=0, description="round wheels the values were learned from")

    def ref(self) -> CalibrationRef:
        """The reference a diagnosis carries."""
        return CalibrationRef(source=self.source, id=self.id, wheels=self.wheels)


__all__ = [
    "CALIBRATION_ID_PATTERN",
    "CalibrationRef",
    "CalibrationSource",
    "SiteCalibration",
]
