"""The service's messages and site file: validation names the offending field."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from pydantic import ValidationError

from schemas.messages import (
    MESSAGE_MODELS,
    MESSAGE_SCHEMA_VERSION,
    PassageResult,
    ServiceError,
    TrainFile,
    WheelPassage,
    encoding_schema,
)
from service.twin.errors import service_error_from_validation
from service.wire.site import SiteFileError, load_site

ROOT = Path(__file__).resolve().parents[1]
GOOD = {
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


def rejection(payload: bytes) -> ServiceError:
    with pytest.raises(ValidationError) as info:
        WheelPassage.model_validate_json(payload)
    return service_error_from_validation(info.value, payload, "site", 1.0)


def test_good_passage_has_defaults_and_version() -> None:
    p = WheelPassage.model_validate_json(json.dumps(GOOD))
    assert p.outline.kind == "round"
    assert p.phase == 0.0
    assert json.loads(p.model_dump_json())["schema_version"] == MESSAGE_SCHEMA_VERSION == "1.5"


@pytest.mark.parametrize(
    ("payload", "kind", "field"),
    [
        (b'{"passage_id": "x", ', "invalid_json", None),
        (json.dumps({**GOOD, "speed": "fast"}).encode(), "invalid_passage", "speed"),
        (json.dumps({**GOOD, "mass": -400.0}).encode(), "invalid_passage", "mass"),
        (json.dumps({**GOOD, "mass": math.nan}).encode(), "invalid_passage", "mass"),
        (json.dumps({**GOOD, "load": math.inf}).encode(), "invalid_passage", "load"),
        (json.dumps({**GOOD, "axle_index": "3"}).encode(), "invalid_passage", "axle_index"),
        (
            json.dumps({**GOOD, "schema_version": "2.0"}).encode(),
            "invalid_passage",
            "schema_version",
        ),
        (
            json.dumps({k: v for k, v in GOOD.items() if k != "radius"}).encode(),
            "invalid_passage",
            "radius",
        ),
        (
            json.dumps({**GOOD, "outline": {"kind": "flat", "length": -0.05}}).encode(),
            "invalid_passage",
            "outline.length",
        ),
        (json.dumps({**GOOD, "phase": "north"}).encode(), "invalid_passage", "phase"),
        (json.dumps({**GOOD, "passage_id": "a/b"}).encode(), "invalid_passage", "passage_id"),
        (b"[1, 2]", "invalid_passage", None),
    ],
)
def test_bad_passages_name_the_field(payload: bytes, kind: str, field: str | None) -> None:
    err = rejection(payload)
    assert err.kind == kind
    assert err.field == field
    if field is not None:
        assert field in err.message
    assert err.problems
    ServiceError.model_validate_json(err.model_dump_json())


def test_rejection_keeps_a_readable_passage_id() -> None:
    err = rejection(json.dumps({**GOOD, "mass": -1.0}).encode())
    assert err.passage_id == GOOD["passage_id"]


def test_every_message_has_a_json_schema_and_a_version() -> None:
    for name, model in MESSAGE_MODELS.items():
        schema = model.model_json_schema()
        assert schema["title"] == name
        if name not in ("TrainFile",):
            assert "schema_version" in schema["properties"], name
        assert encoding_schema(model) == f"railtwin.{name}/1.5"


def test_result_series_must_have_one_length() -> None:
    with pytest.raises(ValidationError, match="force"):
        PassageResult.model_validate(
            {
                "site_id": "s",
                "passage_id": "p",
                "train_id": "t",
                "axle_index": 0,
                "side": "left",
                "timestamp": 0.0,
                "speed": 1.0,
                "sample_rate": 1.0,
                "t_start": 0.0,
                "site_length": 1.0,
                "x": [0.0, 1.0],
                "force": [0.0],
                "indentation": [0.0, 0.0],
                "y_c": [0.0, 0.0],
                "y_ck": [0.0, 0.0],
                "transitions": [],
                "summary": {
                    "peak_force": 0.0,
                    "min_force": 0.0,
                    "contact_losses": 0,
                    "first_loss_time": None,
                    "time_out_of_contact": 0.0,
                    "max_indentation": 0.0,
                    "max_dent": 0.0,
                },
                "rail_revision": 0,
                "wall_time": 0.0,
                "steps": 0,
            }
        )


def test_sample_train_is_valid_and_has_a_measured_flat() -> None:
    train = TrainFile.model_validate_json(
        (ROOT / "recordings/samples/train_160kmh.json").read_bytes()
    )
    assert len(train.wheels) >= 24
    kinds = [w.passage.outline.kind for w in train.wheels]
    assert kinds.count("sampled") == 1
    assert all(abs(w.passage.speed - 160 / 3.6) < 1e-9 for w in train.wheels)
    offsets = [w.offset for w in train.wheels]
    assert offsets == sorted(offsets)


def test_example_site_loads() -> None:
    site = load_site(ROOT / "examples/site.toml")
    assert site.site_id == "demo"
    assert site.length == 6.0
    assert site.foundation.kind == "discrete" and site.detector is not None
    assert [c.id for c in site.detector.cribs] == [f"ch{i}" for i in range(1, 9)]
    compliant = load_site(ROOT / "examples/site_compliant.toml")  # the diagnosis's site
    assert compliant.foundation.kind == "compliant" and compliant.detector is None
    same = ("site_id", "length", "output_sample_rate", "rail", "material", "contact", "rtol")
    assert compliant.model_dump(include=set(same)) == site.model_dump(include=set(same))


def test_site_with_rail_file(tmp_path: Path) -> None:
    (tmp_path / "rail.csv").write_text("x,y\n0,0\n1,1e-6\n2,0\n")
    (tmp_path / "site.toml").write_text(
        'site_id = "s"\nlength = 2.0\noutput_sample_rate = 1e4\ncontact = "hertz"\n'
        '[rail]\nkind = "file"\npath = "rail.csv"\n'
        "[material]\nyoungs_modulus = 2.14e11\npoisson_ratio = 0.3\n"
    )
    site = load_site(tmp_path / "site.toml")
    assert site.rail.kind == "sampled"
    assert site.rail.y == [0.0, 1e-6, 0.0]  # type: ignore[union-attr]


def test_bad_site_names_the_field(tmp_path: Path) -> None:
    (tmp_path / "site.toml").write_text(
        'site_id = "s"\nlength = -2.0\noutput_sample_rate = 1e4\ncontact = "johnson"\n'
        '[rail]\nkind = "flat"\n[material]\nyoungs_modulus = 2.14e11\npoisson_ratio = 0.3\n'
    )
    with pytest.raises(SiteFileError, match="length"):
        load_site(tmp_path / "site.toml")
