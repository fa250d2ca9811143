"""One stored diagnosis: the columns the fleet keeps of a ``Diagnosis``.

A Diagnosis is validated with the ``schemas`` model (any 1.x version; unknown fields
ignored) and must carry the passage's ``timestamp``; one without a ``wheel`` is kept
(it counts for its site) but belongs to no wheel's history.

Distance run: no railtwin message carries an odometer reading, so ``distance_run`` is
stored as NULL (docs/fleet.md) and the history plots against time only.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, replace
from typing import Any

from pydantic import ValidationError

from schemas.diagnosis import Diagnosis
from service.fleet.trend import MIN_LENGTH_SIGMA, Z95


class EntryError(ValueError):
    """A payload that cannot be stored, with the reason in one line."""


@dataclass(frozen=True)
class Entry:
    """A diagnosis as stored: id (site_id, passage_id), wheel, time and findings."""

    site_id: str
    passage_id: str
    wheel_id: str | None
    vehicle_id: str | None
    wheelset: int | None
    side: str | None
    timestamp: float
    verdict: str
    flat_kind: str | None
    flat_length: float | None
    flat_length_low: float | None
    flat_length_high: float | None
    peak_force_measured: float
    peak_force_at_line_speed: float | None
    speed: float | None
    distance_run: float | None
    received_at: float
    body: str

    @property
    def diagnosis_id(self) -> str:
        """``<site_id>/<passage_id>``: the diagnosis's id in the fleet."""
        return f"{self.site_id}/{self.passage_id}"

    @property
    def length_sigma(self) -> float | None:
        """σ of the flat length from its 95 % interval (at least MIN_LENGTH_SIGMA)."""
        if (
            self.flat_length is None
            or self.flat_length_low is None
            or self.flat_length_high is None
        ):
            return None
        return max((self.flat_length_high - self.flat_length_low) / (2 * Z95), MIN_LENGTH_SIGMA)

    def history_json(self) -> dict[str, Any]:
        """The entry as the wheel queryable lists it (``flat`` as in Diagnosis)."""
        body = json.loads(self.body)
        return {
            "site_id": self.site_id,
            "passage_id": self.passage_id,
            "timestamp": self.timestamp,
            "verdict": self.verdict,
            "flat": body.get("flat"),
            "reasons": body.get("reasons", []),
            "peak_force_measured": self.peak_force_measured,
            "peak_force_at_line_speed": self.peak_force_at_line_speed,
            "speed": self.speed,
            "distance_run": self.distance_run,
        }

    def with_speed(self, speed: float | None) -> Entry:
        return self if speed is None else replace(self, speed=speed)


def entry_from_payload(payload: bytes | str, received_at: float) -> Entry:
    """The Entry of a Diagnosis JSON payload; EntryError says why not."""
    try:
        diag = Diagnosis.model_validate_json(payload)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(whole message)"
        raise EntryError(f"not a valid Diagnosis: {where}: {first['msg']}") from None
    return entry_from_diagnosis(diag, received_at)


def entry_from_diagnosis(diag: Diagnosis, received_at: float) -> Entry:
    timestamp = diag.timestamp
    if timestamp is None or not math.isfinite(timestamp):
        raise EntryError(
            f"diagnosis {diag.site_id}/{diag.passage_id} has no timestamp (a "
            "1.0 message): the fleet cannot place it in a wheel's history"
        )
    wheel = diag.wheel
    flat = diag.flat
    return Entry(
        site_id=diag.site_id,
        passage_id=diag.passage_id,
        wheel_id=wheel.id if wheel is not None else None,
        vehicle_id=wheel.vehicle_id if wheel is not None else None,
        wheelset=wheel.wheelset if wheel is not None else None,
        side=wheel.side if wheel is not None else None,
        timestamp=float(timestamp),
        verdict=diag.verdict,
        flat_kind=flat.kind if flat is not None else None,
        flat_length=flat.length if flat is not None else None,
        flat_length_low=flat.length_low if flat is not None else None,
        flat_length_high=flat.length_high if flat is not None else None,
        peak_force_measured=diag.peak_force_measured,
        peak_force_at_line_speed=diag.peak_force_at_line_speed,
        speed=None,
        distance_run=None,
        received_at=received_at,
        body=diag.model_dump_json(),
    )


def speed_of_result(payload: bytes | str) -> tuple[str, str, float] | None:
    """(site_id, passage_id, speed) of a PassageResult JSON, None if it has not these."""
    try:
        data = json.loads(payload)
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(data, dict):
        return None
    site, pid, speed = data.get("site_id"), data.get("passage_id"), data.get("speed")
    if (
        isinstance(site, str)
        and isinstance(pid, str)
        and isinstance(speed, int | float)
        and not isinstance(speed, bool)
        and math.isfinite(speed)
        and speed > 0
    ):
        return site, pid, float(speed)
    return None
