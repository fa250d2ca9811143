"""``schemas.fleet.FleetAlarm``: the fleet's alarm is part of the light-client contract,
with its committed JSON Schema, and is the model the fleet service publishes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pydantic import ValidationError

import service.fleet.alarms as alarms
from schemas import all_json_schemas
from schemas.fleet import FLEET_SCHEMA_VERSION, FleetAlarm

ALARM = {
    "alarm_id": "V1/2/left:verdict_escalated:inspect:0",
    "wheel_id": "V1/2/left",
    "wheel": {"vehicle_id": "V1", "wheelset": 2, "side": "left"},
    "kind": "verdict_escalated",
    "level": "inspect",
    "severity": "warning",
    "reason": "verdict inspect",
    "evidence": ["km12/p1"],
    "data_time": 1.0,
    "raised_at": 2.0,
    "episode": 0,
}


def test_the_fleet_publishes_the_schemas_model() -> None:
    assert alarms.FleetAlarm is FleetAlarm


def test_its_json_schema_is_committed_and_lenient_on_unknown_fields() -> None:
    schema = all_json_schemas()["FleetAlarm"]
    path = Path(__file__).resolve().parents[1] / "schemas" / "json" / "FleetAlarm.schema.json"
    assert json.loads(path.read_text(encoding="utf-8")) == schema
    got = FleetAlarm.model_validate({**ALARM, "added_in_1_1": True})
    assert got.schema_version == FLEET_SCHEMA_VERSION and got.wheel.wheelset == 2


def test_a_wrong_side_or_kind_is_rejected() -> None:
    with pytest.raises(ValidationError, match="side"):
        FleetAlarm.model_validate({**ALARM, "wheel": {**ALARM["wheel"], "side": "middle"}})
    with pytest.raises(ValidationError, match="kind"):
        FleetAlarm.model_validate({**ALARM, "kind": "guess"})
