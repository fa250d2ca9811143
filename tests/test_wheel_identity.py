"""Wheel identity (issue 16) and the 1.x message versioning: schemas only, no service."""

from __future__ import annotations

import json
from typing import Any

import pytest
from pydantic import ValidationError

from schemas.diagnosis import Diagnosis
from schemas.messages import (
    MESSAGE_MODELS,
    MESSAGE_SCHEMA_VERSION,
    Health,
    PassageResult,
    TrainFile,
    WheelIdError,
    WheelPassage,
    WheelRef,
    is_encoding_of,
)
from schemas.site import SiteConfig

PASSAGE: dict[str, Any] = {
    "passage_id": "t1-a00-r",
    "train_id": "t1",
    "axle_index": 0,
    "side": "right",
    "timestamp": 1.7e9,
    "speed": 44.4,
    "load": 52000.0,
    "mass": 600.0,
    "radius": 0.46,
}
DIAGNOSIS: dict[str, Any] = {
    "site_id": "km12",
    "passage_id": "p1",
    "flat": None,
    "verdict": "ok",
    "reasons": [],
    "peak_force_measured": 9e4,
    "peak_force_fit": 9e4,
    "fit_rms": 100.0,
    "peak_force_at_line_speed": None,
    "wall_time": 0.5,
}


def errors(model: type[Any], data: dict[str, Any]) -> dict[str, str]:
    """{first loc element or ctx field: message} of a rejected ``data``."""
    with pytest.raises(ValidationError) as info:
        model.model_validate_json(json.dumps(data))
    out = {}
    for e in info.value.errors(include_url=False):
        key = str(e["loc"][0]) if e["loc"] else str((e.get("ctx") or {}).get("field", ""))
        out[key] = e["msg"]
    return out


# --- WheelRef ------------------------------------------------------------------------------


@pytest.mark.parametrize("text", ["31-80-4751-123-4/1/left", "V7/12/right", "a_b.c/3/left"])
def test_wheel_id_round_trips(text: str) -> None:
    w = WheelRef.parse(text)
    assert w.id == text
    assert WheelRef.parse(w.id) == w
    assert WheelRef.model_validate_json(w.model_dump_json()) == w


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("V1/2", "<vehicle_id>/<wheelset>/<side>"),
        ("V1/2/left/x", "<vehicle_id>/<wheelset>/<side>"),
        ("V1/0/left", "wheelset"),
        ("V1/-1/left", "not a number"),
        ("V1/two/left", "not a number"),
        ("V1/²/left", "not a number"),
        ("V1/2/up", "side"),
        ("V 1/2/left", "vehicle_id"),
        ("/2/left", "vehicle_id"),
    ],
)
def test_bad_wheel_ids_say_why(text: str, says: str) -> None:
    with pytest.raises(WheelIdError) as info:
        WheelRef.parse(text)
    assert says in str(info.value)
    assert isinstance(info.value, ValueError)


def test_wheel_ref_is_strict_on_types() -> None:
    assert "wheelset" in errors(WheelRef, {"vehicle_id": "V", "wheelset": "2", "side": "left"})
    assert "wheelset" in errors(WheelRef, {"vehicle_id": "V", "wheelset": 2.0, "side": "left"})


def test_a_wheel_keeps_its_id_when_the_vehicle_runs_the_other_way() -> None:
    """Same wheel, both directions: the rail side swaps, the wheel's id does not."""
    wheel = WheelRef.parse("V1/1/left")
    runs = []
    for direction in ("end2_leading", "end1_leading"):
        rail = wheel.rail_side(direction)
        p = WheelPassage.model_validate(
            {**PASSAGE, "side": rail, "direction": direction, "wheel": wheel.model_dump()}
        )
        runs.append((p.side, p.wheel))
    assert runs[0][0] != runs[1][0]  # left rail one way, right rail the other
    assert runs[0][1] == runs[1][1] == wheel  # one wheel


def test_side_must_agree_with_wheel_and_direction() -> None:
    bad = {
        **PASSAGE,
        "side": "right",
        "direction": "end2_leading",
        "wheel": {"vehicle_id": "V1", "wheelset": 1, "side": "left"},
    }
    msg = errors(WheelPassage, bad)
    assert "side" in msg and "V1/1/left" in msg["side"]
    # without a direction nothing ties the two sides together
    ok = WheelPassage.model_validate({**bad, "direction": None})
    assert ok.wheel is not None and ok.side == "right"


# --- versions and unknown fields -------------------------------------------------------------


def test_old_messages_stay_valid() -> None:
    """A 1.0 passage/diagnosis (no wheel, no direction, no timestamp) is read as it was."""
    p = WheelPassage.model_validate({**PASSAGE, "schema_version": "1.0"})
    assert (p.wheel, p.direction, p.schema_version) == (None, None, "1.0")
    d = Diagnosis.model_validate({**DIAGNOSIS, "schema_version": "1.0"})
    assert (d.wheel, d.timestamp) == (None, None)


def test_producers_write_1_1_with_the_wheel() -> None:
    wheel = {"vehicle_id": "V1", "wheelset": 2, "side": "right"}
    d = Diagnosis.model_validate({**DIAGNOSIS, "wheel": wheel, "timestamp": 1.7e9})
    out = json.loads(d.model_dump_json())
    assert out["schema_version"] == MESSAGE_SCHEMA_VERSION == "1.5"
    assert out["wheel"] == wheel and out["timestamp"] == 1.7e9
    assert "wheel" in PassageResult.model_fields and "timestamp" in PassageResult.model_fields


def test_a_newer_minor_version_with_new_fields_is_read() -> None:
    newer = {**PASSAGE, "schema_version": "1.7", "bogie": {"kind": "y25"}, "axle_load_t": 22.5}
    p = WheelPassage.model_validate_json(json.dumps(newer))
    assert p.passage_id == PASSAGE["passage_id"] and p.schema_version == "1.7"
    assert "bogie" not in json.loads(p.model_dump_json())  # producers write known fields only
    d = Diagnosis.model_validate(
        {
            **DIAGNOSIS,
            "schema_version": "1.2",
            "confidence": 0.9,
            "wheel": {"vehicle_id": "V", "wheelset": 1, "side": "left", "position": "L1"},
        }
    )
    assert d.wheel == WheelRef.parse("V/1/left")


def test_unknown_fields_do_not_relax_types() -> None:
    msg = errors(WheelPassage, {**PASSAGE, "speed": "44.4", "whatever": 1})
    assert set(msg) == {"speed"}
    assert "axle_index" in errors(WheelPassage, {**PASSAGE, "axle_index": 1.0})


@pytest.mark.parametrize("version", ["2.0", "0.9", "10.1"])
def test_another_major_version_is_refused_with_one_clear_error(version: str) -> None:
    for model, data in ((WheelPassage, PASSAGE), (Diagnosis, DIAGNOSIS)):
        msg = errors(model, {**data, "schema_version": version, "speed": "changed meaning"})
        assert list(msg) == ["schema_version"]
        assert "not supported" in msg["schema_version"] and "1.x" in msg["schema_version"]


@pytest.mark.parametrize("version", ["1", "1.x", "v1.1", "1.1.0", "01.1", ""])
def test_a_malformed_version_is_refused(version: str) -> None:
    assert "schema_version" in errors(WheelPassage, {**PASSAGE, "schema_version": version})


def test_files_a_person_writes_still_reject_unknown_keys() -> None:
    site = {
        "site_id": "km12",
        "length": 6.0,
        "output_sample_rate": 1e4,
        "rail": {"kind": "flat"},
        "contact": "hertz",
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
    }
    SiteConfig.model_validate(site)
    assert "lenght" in errors(SiteConfig, {**site, "lenght": 6.0})
    assert "whels" in errors(TrainFile, {"train_id": "t", "wheels": [], "whels": []})
    # a nested scenario part of a message is an input too: a misspelt outline key is refused
    bad = {**PASSAGE, "outline": {"kind": "flat", "length": 0.05, "lenght": 0.05}}
    assert "outline" in errors(WheelPassage, bad)


def test_encodings_of_any_1x_are_recognised() -> None:
    assert is_encoding_of("railtwin.Health/1.0", Health)
    assert is_encoding_of("railtwin.Health/1.1", Health)
    assert is_encoding_of("railtwin.Health/1.12", Health)
    assert not is_encoding_of("railtwin.Health/2.0", Health)
    assert not is_encoding_of("railtwin.RailState/1.1", Health)
    assert not is_encoding_of("Health/1.1", Health)


def test_every_message_publishes_the_version_pattern() -> None:
    for name, model in MESSAGE_MODELS.items():
        prop = model.model_json_schema()["properties"]["schema_version"]
        assert prop["pattern"].startswith("^1\\."), name


def test_the_worked_examples_in_the_messages_module_hold() -> None:
    import doctest

    import schemas.messages

    result = doctest.testmod(schemas.messages, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted >= 4 and result.failed == 0
