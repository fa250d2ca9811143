"""The fleet's alarm message: ``FleetAlarm``, published on
``railtwin/fleet/alarm/<vehicle_id>/<wheelset>/<side>`` (docs/fleet.md).

The fleet service (``service.fleet.alarms``) decides when to raise one; this is the
contract a subscriber reads. Unknown fields are ignored (a newer minor version may add
some), as for the other streaming messages.

    >>> a = FleetAlarm(
    ...     alarm_id="w1:verdict_escalated:remove:1", wheel_id="w1",
    ...     wheel={"vehicle_id": "V1", "wheelset": 2, "side": "left"},
    ...     kind="verdict_escalated", level="remove", severity="critical",
    ...     reason="verdict remove", evidence=["km12/p1"], data_time=0.0, raised_at=1.0,
    ...     episode=1)
    >>> a.wheel.side, a.schema_version
    ('left', '1.0')
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

AlarmKind = Literal["verdict_escalated", "forecast_flat_length", "forecast_peak_force"]
Severity = Literal["info", "warning", "critical"]

FLEET_SCHEMA_VERSION = "1.0"


class AlarmWheel(BaseModel):
    """The wheel an alarm is about, as the fleet identifies it."""

    model_config = ConfigDict(extra="ignore", frozen=True)
    vehicle_id: str
    wheelset: int
    side: Literal["left", "right"]


class FleetAlarm(BaseModel):
    """One alarm, as published on ``railtwin/fleet/alarm/<vehicle_id>/<wheelset>/<side>``."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    schema_version: str = FLEET_SCHEMA_VERSION
    alarm_id: str = Field(description="<wheel_id>:<kind>:<level>:<episode>")
    wheel_id: str
    wheel: AlarmWheel
    kind: AlarmKind
    level: Literal["watch", "inspect", "remove"]
    severity: Severity
    reason: str
    evidence: list[str] = Field(description="diagnosis ids <site_id>/<passage_id>")
    data_time: float = Field(description="passage time of the latest diagnosis, UNIX s")
    raised_at: float = Field(description="when the fleet raised it, UNIX s")
    episode: int
    forecast: dict[str, Any] | None = Field(
        default=None, description="forecast alarms: the crossing (at, earliest, latest)"
    )


__all__ = ["FLEET_SCHEMA_VERSION", "AlarmKind", "AlarmWheel", "FleetAlarm", "Severity"]
