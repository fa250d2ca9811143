"""The scenario/result contract: what is accepted, what is refused, and how errors name fields."""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from schemas import (
    MAX_SAMPLES,
    SCHEMA_VERSION,
    ErrorReport,
    Result,
    Scenario,
    all_json_schemas,
    all_models,
)
from schemas.errors import format_path
from schemas.scenario import EXAMPLE_JSON
from tests.conftest import EXAMPLE_SCENARIOS, ROOT

CONTRACT_MD = [ROOT / "docs" / "CONTRACT.md"]


def errors_of(data: Any) -> ErrorReport:
    """Validate ``data`` expecting failure; the report with clean field paths."""
    with pytest.raises(ValidationError) as info:
        Scenario.model_validate(data)
    return ErrorReport.from_validation_error(info.value, data)


def paths(report: ErrorReport) -> list[str]:
    return [e.path for e in report.errors]


def with_(data: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    """A deep copy of ``data`` with the dotted ``path`` set to ``value`` (``...`` deletes it)."""
    out = copy.deepcopy(data)
    *parents, last = path.split(".")
    node = out
    for key in parents:
        node = node[key]
    if value is ...:
        del node[last]
    else:
        node[last] = value
    return out


# --- accepted -------------------------------------------------------------------------------


def test_examples_exist_for_every_kind() -> None:
    kinds: set[str] = set()
    for p in EXAMPLE_SCENARIOS:
        s = Scenario.model_validate_json(p.read_text())
        kinds |= {f"outline:{s.wheel.outline.kind}", f"rail:{s.rail.kind}"}
        kinds |= {f"contact:{s.contact}", f"foundation:{s.foundation.kind}"}
        if s.passes > 1:
            kinds.add("multipass")
    for kind in (
        "outline:round",
        "outline:flat",
        "outline:rounded_flat",
        "outline:sampled",
        "rail:flat",
        "rail:cosine",
        "rail:step",
        "rail:sampled",
        "contact:hertz",
        "contact:johnson",
        "contact:hertz_plastic",
        "foundation:rigid",
        "foundation:compliant",
        "multipass",
    ):
        assert kind in kinds, f"no example scenario with {kind}"


@pytest.mark.parametrize("path", EXAMPLE_SCENARIOS, ids=lambda p: p.name)
def test_every_example_validates(path: Path) -> None:
    s = Scenario.model_validate_json(path.read_text())
    assert s.expected_samples <= 50_000, "examples must stay small (a second or two each)"
    # the echo round-trips exactly
    assert Scenario.model_validate_json(s.model_dump_json()) == s


def test_contract_example_verbatim() -> None:
    s = Scenario.model_validate_json(EXAMPLE_JSON)
    assert s.wheel.radius == 0.475 and s.rail.kind == "cosine" and s.passes == 1
    assert s.initial is None and s.material.yield_stress == 6.0e8
    assert (s.constraint, s.curvature_stiffness, s.rtol) == ("exact", False, 1e-9)


def test_contract_example_matches_contract_md() -> None:
    """EXAMPLE_JSON is the first JSON block of CONTRACT.md, character for character."""
    found = [p for p in CONTRACT_MD if p.exists()]
    assert found, "docs/CONTRACT.md (the contract, copied into the repository) is missing"
    block = re.search(r"```json\n(.*?)```", found[0].read_text(), re.S)
    assert block is not None
    assert json.loads(block.group(1)) == json.loads(EXAMPLE_JSON)
    Scenario.model_validate_json(block.group(1))


def test_defaults_and_optional_fields(contract_example: dict[str, Any]) -> None:
    data = with_(contract_example, "wheel.phase", ...)
    for key in ("initial", "passes"):
        del data[key]
    data["foundation"] = {"kind": "compliant", "mass": 4000.0, "stiffness": 2.31e8}
    data["material"]["yield_stress"] = None
    data |= {
        "curvature_stiffness": True,
        "constraint": "profile",
        "rtol": 1e-8,
        "schema_version": SCHEMA_VERSION,
    }
    s = Scenario.model_validate(data)
    assert s.wheel.phase == 0.0 and s.passes == 1 and s.initial is None
    assert s.foundation.kind == "compliant" and s.foundation.damping == 0.0
    assert s.curvature_stiffness and s.constraint == "profile"


def test_integers_are_accepted_where_floats_are_expected(contract_example: dict[str, Any]) -> None:
    s = Scenario.model_validate(with_(contract_example, "wheel.mass", 400))
    assert s.wheel.mass == 400.0 and isinstance(s.wheel.mass, float)


# --- refused, with the field named ----------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "value", "expected_path", "fragment"),
    [
        ("wheel.mass", -400.0, "wheel.mass", "greater than 0"),
        ("wheel.mass", 0.0, "wheel.mass", "greater than 0"),
        ("wheel.load", "39240", "wheel.load", "valid number"),
        ("wheel.radius", math.nan, "wheel.radius", "finite"),
        ("wheel.radius", math.inf, "wheel.radius", "finite"),
        ("speed", -1.0, "speed", "greater than 0"),
        ("duration", math.nan, "duration", "finite"),
        ("passes", 0, "passes", "greater than or equal to 1"),
        ("passes", 2.0, "passes", "valid integer"),
        ("passes", "2", "passes", "valid integer"),
        ("material.poisson_ratio", 0.5, "material.poisson_ratio", "less than 0.5"),
        ("material.youngs_modulus", -2.14e11, "material.youngs_modulus", "greater than 0"),
        ("contact", "coulomb", "contact", "hertz"),
        ("constraint", "approximate", "constraint", "exact"),
        ("curvature_stiffness", 1, "curvature_stiffness", "boolean"),
        ("rtol", 0.0, "rtol", "greater than or equal"),
        ("wheel.phase", math.inf, "wheel.phase", "finite"),
        ("rail.wavelength", 0.0, "rail.wavelength", "greater than 0"),
        ("rail.amplitude", math.nan, "rail.amplitude", "finite"),
        ("wheel.outline", {"kind": "square"}, "wheel.outline", "round"),
        ("schema_version", "2.0", "schema_version", "not compatible"),
    ],
)
def test_bad_value_names_the_field(
    contract_example: dict[str, Any], path: str, value: Any, expected_path: str, fragment: str
) -> None:
    report = errors_of(with_(contract_example, path, value))
    assert expected_path in paths(report), report.to_text()
    message = next(e.message for e in report.errors if e.path == expected_path)
    assert fragment in message, message


def test_nan_in_json_text_is_refused() -> None:
    text = EXAMPLE_JSON.replace('"speed": 13.53', '"speed": NaN')
    with pytest.raises(ValidationError) as info:
        Scenario.model_validate_json(text)
    assert [e["loc"] for e in info.value.errors()] == [("speed",)]


@pytest.mark.parametrize(
    ("where", "expected_path"),
    [
        ((), "colour"),
        (("wheel",), "wheel.colour"),
        (("rail",), "rail.colour"),
        (("wheel", "outline"), "wheel.outline.colour"),
        (("material",), "material.colour"),
    ],
)
def test_unknown_fields_are_refused(
    contract_example: dict[str, Any], where: tuple[str, ...], expected_path: str
) -> None:
    node = contract_example
    for key in where:
        node = node[key]
    node["colour"] = "red"
    report = errors_of(contract_example)
    assert paths(report) == [expected_path]
    assert "unknown field" in report.errors[0].message


def test_missing_field_is_named(contract_example: dict[str, Any]) -> None:
    report = errors_of(with_(contract_example, "wheel.radius", ...))
    assert paths(report) == ["wheel.radius"]
    assert "missing" in report.errors[0].message


def test_flat_longer_than_the_diameter(contract_example: dict[str, Any]) -> None:
    data = with_(contract_example, "wheel.outline", {"kind": "flat", "length": 0.95})
    report = errors_of(data)
    assert paths(report) == ["wheel.outline.length"]
    assert "2·radius = 0.95" in report.errors[0].message  # says the limit
    Scenario.model_validate(
        with_(contract_example, "wheel.outline", {"kind": "flat", "length": 0.9})
    )


def test_rounded_flat_deeper_than_the_radius(contract_example: dict[str, Any]) -> None:
    outline = {"kind": "rounded_flat", "length": 0.05, "depth": 0.5}
    report = errors_of(with_(contract_example, "wheel.outline", outline))
    assert paths(report) == ["wheel.outline.depth"]
    assert "radius = 0.475" in report.errors[0].message


def test_negative_flat_length_path_has_no_union_tag(contract_example: dict[str, Any]) -> None:
    report = errors_of(with_(contract_example, "wheel.outline", {"kind": "flat", "length": -1.0}))
    assert paths(report) == ["wheel.outline.length"]


@pytest.mark.parametrize("contact", ["johnson", "hertz_plastic"])
def test_plastic_laws_need_a_yield_stress(contract_example: dict[str, Any], contact: str) -> None:
    data = with_(contract_example, "material.yield_stress", None)
    data["contact"] = contact
    report = errors_of(data)
    assert paths(report) == ["material.yield_stress"]
    assert contact in report.errors[0].message
    assert "required" in report.errors[0].message
    # and missing altogether is the same
    report = errors_of(with_(data, "material.yield_stress", ...))
    assert paths(report) == ["material.yield_stress"]


def test_hertz_without_yield_stress_is_fine(contract_example: dict[str, Any]) -> None:
    Scenario.model_validate(with_(contract_example, "material.yield_stress", None))


@pytest.mark.parametrize(
    ("rail", "expected_path", "fragment"),
    [
        (
            {"kind": "sampled", "x": [0.0, 1.0, 1.0], "y": [0.0, 0.0, 0.0]},
            "rail.x[2]",
            "increasing",
        ),
        (
            {"kind": "sampled", "x": [0.0, 2.0, 1.0], "y": [0.0, 0.0, 0.0]},
            "rail.x[2]",
            "increasing",
        ),
        ({"kind": "sampled", "x": [0.0, 1.0], "y": [0.0]}, "rail.y", "same length"),
        ({"kind": "sampled", "x": [0.0], "y": [0.0]}, "rail.x", "at least 2"),
        ({"kind": "sampled", "x": [0.0, math.nan], "y": [0.0, 0.0]}, "rail.x[1]", "finite"),
        ({"kind": "cosine", "amplitude": 1e-4}, "rail.wavelength", "missing"),
    ],
)
def test_bad_rail_names_the_field(
    contract_example: dict[str, Any], rail: dict[str, Any], expected_path: str, fragment: str
) -> None:
    report = errors_of(with_(contract_example, "rail", rail))
    assert paths(report) == [expected_path], report.to_text()
    assert fragment in report.errors[0].message


def _ring(n: int, span: float = 2 * math.pi) -> list[float]:
    return [span * i / n for i in range(n)]


@pytest.mark.parametrize(
    ("outline", "expected_path", "fragment"),
    [
        (
            {"theta": [0.0, 3.0, 2.0, 5.0], "radius": [0.475] * 4},
            "wheel.outline.theta[2]",
            "increasing",
        ),
        ({"theta": _ring(8, math.pi), "radius": [0.475] * 8}, "wheel.outline.theta", "cover"),
        ({"theta": [*_ring(8), 6.5], "radius": [0.475] * 9}, "wheel.outline.theta", "one turn"),
        (
            {"theta": [*_ring(8), 2 * math.pi], "radius": [0.475] * 9},
            "wheel.outline.theta",
            "repeat",
        ),
        ({"theta": _ring(8), "radius": [0.475] * 7}, "wheel.outline.radius", "same length"),
        ({"theta": _ring(8), "radius": [0.475] * 7 + [0.6]}, "wheel.outline.radius[7]", "10 %"),
        ({"theta": _ring(8), "radius": [0.475] * 7 + [-0.1]}, "wheel.outline.radius[7]", "greater"),
    ],
)
def test_bad_sampled_outline_names_the_field(
    contract_example: dict[str, Any], outline: dict[str, Any], expected_path: str, fragment: str
) -> None:
    report = errors_of(with_(contract_example, "wheel.outline", {"kind": "sampled", **outline}))
    assert paths(report) == [expected_path], report.to_text()
    assert fragment in report.errors[0].message


def test_too_many_samples_says_why(contract_example: dict[str, Any]) -> None:
    data = with_(contract_example, "duration", MAX_SAMPLES / 1e5 * 2)
    report = errors_of(data)
    assert paths(report) == ["sample_rate"]
    assert (
        "GB" in report.errors[0].message
        and "lower sample_rate or duration" in report.errors[0].message
    )


def test_initial_foundation_state_needs_a_foundation(contract_example: dict[str, Any]) -> None:
    data = with_(contract_example, "initial", {"y_c": 0.0, "v_c": -0.3, "y_m": 1e-5, "v_m": 0.0})
    assert paths(errors_of(data)) == ["initial.y_m"]


def test_several_errors_are_all_reported(contract_example: dict[str, Any]) -> None:
    data = with_(contract_example, "wheel.mass", -1.0)
    data["speed"] = "fast"
    data["extra"] = 1
    assert sorted(paths(errors_of(data))) == ["extra", "speed", "wheel.mass"]


@settings(max_examples=50, deadline=None)
@given(
    xs=st.lists(st.floats(-10.0, 10.0, allow_nan=False), min_size=2, max_size=30, unique=True).map(
        sorted
    ),
    data=st.data(),
)
def test_sampled_rail_property(xs: list[float], data: st.DataObject) -> None:
    """Strictly increasing x is accepted; swapping any neighbour pair is refused at that index."""
    scenario = json.loads(EXAMPLE_JSON)
    scenario["rail"] = {"kind": "sampled", "x": xs, "y": [0.0] * len(xs)}
    Scenario.model_validate(scenario)
    i = data.draw(st.integers(1, len(xs) - 1))
    bad = list(xs)
    bad[i - 1], bad[i] = bad[i], bad[i - 1]
    scenario["rail"]["x"] = bad
    assert paths(errors_of(scenario)) == [f"rail.x[{i}]"]


@settings(max_examples=50, deadline=None)
@given(
    mass=st.floats(1e-3, 1e5),
    load=st.floats(1.0, 1e7),
    radius=st.floats(0.1, 2.0),
    frac=st.floats(0.001, 0.999),
)
def test_flat_length_limit_property(mass: float, load: float, radius: float, frac: float) -> None:
    """Any flat shorter than the diameter is accepted, any longer refused, whatever the wheel."""
    scenario = json.loads(EXAMPLE_JSON)
    scenario["wheel"] = {
        "mass": mass,
        "load": load,
        "radius": radius,
        "outline": {"kind": "flat", "length": frac * 2 * radius},
    }
    Scenario.model_validate(scenario)
    scenario["wheel"]["outline"]["length"] = 2 * radius / frac
    assert paths(errors_of(scenario)) == ["wheel.outline.length"]


# --- results and JSON Schema ----------------------------------------------------------------


def _summary(**kw: Any) -> dict[str, Any]:
    base = {
        "peak_force": 5e4,
        "min_force": 0.0,
        "contact_losses": 1,
        "first_loss_time": 0.01,
        "time_out_of_contact": 0.002,
        "max_indentation": 6e-5,
        "max_dent": 0.0,
    }
    return base | kw


def _result(n: int = 3) -> dict[str, Any]:
    series = {k: [0.0] * n for k in ("t", "x", "y_c", "v_c", "y_ck", "y_m", "delta", "force")}
    return {
        "scenario": json.loads(EXAMPLE_JSON),
        "derived": {
            "contact_coefficient": 1.08e11,
            "static_indentation": 5.09e-5,
            "contact_frequency": 270.6,
            "yield_force": 81829.0,
            "yield_indentation": 8.31e-5,
        },
        "series": series | {"in_contact": [True] * n},
        "transitions": [{"t": 0.0123, "kind": "loss"}],
        "summary": _summary(),
        "rail_after": None,
        "passes_summary": [_summary()],
    }


def test_result_round_trips() -> None:
    r = Result.model_validate(_result())
    assert r.schema_version == SCHEMA_VERSION
    again = Result.model_validate_json(r.model_dump_json())
    assert again == r


def test_result_refuses_ragged_series() -> None:
    data = _result()
    data["series"]["force"] = [0.0]
    with pytest.raises(ValidationError) as info:
        Result.model_validate(data)
    report = ErrorReport.from_validation_error(info.value, data)
    assert paths(report) == ["series.force"]


def test_result_refuses_unknown_transition_kind() -> None:
    data = _result()
    data["transitions"] = [{"t": 0.1, "kind": "bounce"}]
    with pytest.raises(ValidationError) as info:
        Result.model_validate(data)
    assert (
        ErrorReport.from_validation_error(info.value, data).errors[0].path == "transitions[0].kind"
    )


def test_json_schema_export() -> None:
    schemas = all_json_schemas()
    assert {"Scenario", "Result", "ErrorReport"} <= set(schemas)
    messages = set(all_models()) - {"Scenario", "Result", "ErrorReport", "SiteConfig", "TrainFile"}
    for name, schema in schemas.items():
        json.dumps(schema)  # serialisable
        assert schema["title"] == name
        # files a person writes reject unknown keys; messages ignore them (newer minor versions)
        assert schema.get("additionalProperties") is (None if name in messages else False), name
    scenario = schemas["Scenario"]
    assert set(scenario["required"]) >= {
        "wheel",
        "rail",
        "material",
        "contact",
        "foundation",
        "speed",
        "duration",
        "sample_rate",
    }
    assert "discriminator" in json.dumps(scenario)


def test_format_path_without_raw_input() -> None:
    assert format_path(("wheel", "outline", "flat", "length")) == "wheel.outline.length"
    assert format_path(("rail", "sampled", "x", 3)) == "rail.x[3]"
    assert format_path(("wheel",), None, {"field": "outline.length"}) == "wheel.outline.length"


@pytest.mark.parametrize("phase", [-0.44, 7.0, 2 * math.pi, -100.0])
def test_any_finite_phase_is_taken_modulo_two_pi(
    contract_example: dict[str, Any], phase: float
) -> None:
    """CONTRACT.md: any finite φ0 is accepted and taken modulo 2π."""
    scenario = Scenario.model_validate(with_(contract_example, "wheel.phase", phase))
    assert 0.0 <= scenario.wheel.phase < 2 * math.pi
    assert math.isclose(math.cos(scenario.wheel.phase), math.cos(phase), abs_tol=1e-12)
    assert math.isclose(math.sin(scenario.wheel.phase), math.sin(phase), abs_tol=1e-12)
