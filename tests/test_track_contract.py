"""The contract of a rail on discrete supports and a detector (CONTRACT.md, MODEL.md §8).

What is accepted and refused, with the field named, through the models and through
``railtwin simulate``; the limits at their edges; the channels of a result; the
conversion to ``sim_core``.
"""

from __future__ import annotations

import copy
import json
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from schemas import MAX_CRIBS, MAX_TRACK_LENGTH, ErrorReport, Result, Scenario
from schemas.messages import PassageResult
from schemas.site import SiteConfig
from schemas.track import DiscreteFoundation
from service.physics import inputs as physics_inputs
from sim_core.track.spec import Crib, TrackError, TrackSpec, check_cribs
from tests.conftest import ROOT
from tests.test_cli import run_main

DISCRETE: dict[str, Any] = {
    "kind": "discrete",
    "sleeper_spacing": 0.6,
    "first_sleeper": 0.1,
    "pad": {"stiffness": 2.0e8, "damping": 3.0e4},
    "sleeper_mass": 150.0,
    "ballast": {"stiffness": 1.2e8, "damping": 8.0e4},
}
"""The ballasted track of MODEL.md §8, sleepers at 0.1 + 0.6·i m."""

SLAB: dict[str, Any] = {
    "kind": "slab",
    "sleeper_spacing": 0.6,
    "first_sleeper": 0.1,
    "pad": {"stiffness": 5.0e7},
}

CRIBS = [{"id": "c1", "x_a": 1.4, "x_b": 1.8}, {"id": "c2", "x_a": 2.0, "x_b": 2.4}]
"""CONTRACT.md's detector: the cribs between the sleepers at 1.3, 1.9 and 2.5 m."""


@pytest.fixture
def track_scenario(contract_example: dict[str, Any]) -> dict[str, Any]:
    """CONTRACT.md's scenario on the ballasted track with its detector (stretch 2.706 m)."""
    return contract_example | {
        "foundation": copy.deepcopy(DISCRETE),
        "detector": {"cribs": copy.deepcopy(CRIBS)},
    }


def edited(data: dict[str, Any], path: str, value: Any) -> dict[str, Any]:
    """A deep copy of ``data`` with ``path`` (dots and [i]) set to ``value`` (``...`` deletes)."""
    out = copy.deepcopy(data)
    keys: list[str | int] = [int(k) if k.isdigit() else k for k in re.findall(r"[^.\[\]]+", path)]
    node: Any = out
    for key in keys[:-1]:
        node = node[key]
    if value is ...:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return out


def report_of(
    data: dict[str, Any], model: type[Scenario] | type[SiteConfig] = Scenario
) -> ErrorReport:
    with pytest.raises(ValidationError) as info:
        model.model_validate(data)
    return ErrorReport.from_validation_error(info.value, data)


def cribs(n: int) -> list[dict[str, Any]]:
    """``n`` consecutive cribs between the sleepers at 0.1 + 0.6·i m (0.1 m inside each)."""
    return [{"id": f"c{i}", "x_a": 0.2 + 0.6 * i, "x_b": 0.6 + 0.6 * i} for i in range(n)]


# --- accepted -------------------------------------------------------------------------------


def test_a_discrete_scenario_with_cribs_validates_and_round_trips(
    track_scenario: dict[str, Any],
) -> None:
    s = Scenario.model_validate(track_scenario)
    assert s.foundation.kind == "discrete" and s.detector is not None
    assert [c.id for c in s.detector.cribs] == ["c1", "c2"]
    # the rail left out is UIC60, Timoshenko (MODEL.md §8)
    rail = s.foundation.rail  # type: ignore[union-attr]
    assert (rail.youngs_modulus, rail.second_moment, rail.mass_per_length) == (
        2.1e11,
        3.038e-5,
        60.2,
    )
    assert (rail.shear_modulus, rail.area, rail.shear_coefficient) == (8.1e10, 7.67e-3, 0.4)
    assert rail.beam == "timoshenko"
    assert Scenario.model_validate_json(s.model_dump_json()) == s


def test_slab_and_euler_rail_validate(track_scenario: dict[str, Any]) -> None:
    data = track_scenario | {"foundation": SLAB | {"rail": {"beam": "euler", "area": 7.0e-3}}}
    s = Scenario.model_validate(data)
    assert s.foundation.kind == "slab"
    assert s.foundation.rail.beam == "euler" and s.foundation.rail.area == 7.0e-3  # type: ignore[union-attr]
    assert Scenario.model_validate_json(s.model_dump_json()) == s


def test_initial_wheel_state_is_fine_on_a_track(track_scenario: dict[str, Any]) -> None:
    data = track_scenario | {"initial": {"y_c": 1e-5, "v_c": -0.2, "y_m": 0.0, "v_m": 0.0}}
    assert Scenario.model_validate(data).initial is not None


def test_older_minor_versions_stay_readable(track_scenario: dict[str, Any]) -> None:
    assert Scenario.model_validate(track_scenario | {"schema_version": "1.0"})
    assert report_of(track_scenario | {"schema_version": "2.0"}).errors[0].path == "schema_version"


# --- refused, with the field named ----------------------------------------------------------

BAD_SCENARIOS: list[tuple[str, Callable[[dict[str, Any]], dict[str, Any]], str, str]] = [
    (
        "pad stiffness 0",
        lambda d: edited(d, "foundation.pad.stiffness", 0.0),
        "foundation.pad.stiffness",
        "greater than 0",
    ),
    (
        "negative ballast stiffness",
        lambda d: edited(d, "foundation.ballast.stiffness", -1.0e8),
        "foundation.ballast.stiffness",
        "greater than 0",
    ),
    (
        "negative pad damping",
        lambda d: edited(d, "foundation.pad.damping", -1.0),
        "foundation.pad.damping",
        "greater than or equal to 0",
    ),
    (
        "spacing 0",
        lambda d: edited(d, "foundation.sleeper_spacing", 0.0),
        "foundation.sleeper_spacing",
        "0.1",
    ),
    (
        "spacing below the minimum",
        lambda d: edited(d, "foundation.sleeper_spacing", 0.05),
        "foundation.sleeper_spacing",
        "0.1",
    ),
    (
        "no sleeper mass",
        lambda d: edited(d, "foundation.sleeper_mass", ...),
        "foundation.sleeper_mass",
        "missing",
    ),
    (
        "unknown beam",
        lambda d: edited(d, "foundation.rail", {"beam": "bernoulli"}),
        "foundation.rail.beam",
        "timoshenko",
    ),
    (
        "ballast on a slab",
        lambda d: edited(d, "foundation", SLAB | {"ballast": DISCRETE["ballast"]}),
        "foundation.ballast",
        "unknown field",
    ),
    (
        "x_a after x_b",
        lambda d: edited(d, "detector.cribs[1].x_b", 1.95),
        "detector.cribs[1].x_b",
        "greater than x_a",
    ),
    (
        "x_a equal to x_b",
        lambda d: edited(d, "detector.cribs[0].x_b", 1.4),
        "detector.cribs[0].x_b",
        "greater than x_a",
    ),
    (
        "duplicate id",
        lambda d: edited(d, "detector.cribs[1].id", "c1"),
        "detector.cribs[1].id",
        "earlier crib",
    ),
    (
        "id not an identifier",
        lambda d: edited(d, "detector.cribs[0].id", "crib 1"),
        "detector.cribs[0].id",
        "pattern",
    ),
    ("no cribs", lambda d: edited(d, "detector.cribs", []), "detector.cribs", "at least 1"),
    (
        "more than 32 cribs",
        lambda d: edited(d, "detector.cribs", cribs(MAX_CRIBS + 1)),
        "detector.cribs",
        "at most 32",
    ),
    (
        "crib beyond the stretch",
        lambda d: edited(d, "detector.cribs[1]", {"id": "c2", "x_a": 2.6, "x_b": 2.8}),
        "detector.cribs[1].x_b",
        "beyond the simulated stretch",
    ),
    (
        "crib before the stretch",
        lambda d: edited(d, "detector.cribs[0]", {"id": "c1", "x_a": -0.4, "x_b": 0.0}),
        "detector.cribs[0].x_a",
        "before the simulated stretch",
    ),
    (
        "crib over a sleeper",
        lambda d: edited(d, "detector.cribs[1].x_b", 2.6),
        "detector.cribs[1]",
        "sleeper at x = 2.5 m",
    ),
    (
        "crib touching a sleeper",
        lambda d: edited(d, "detector.cribs[0].x_a", 1.3),
        "detector.cribs[0]",
        "sleeper at x = 1.3 m",
    ),
    (
        "detector on a rigid foundation",
        lambda d: edited(d, "foundation", {"kind": "rigid"}),
        "detector",
        "rail on supports",
    ),
    (
        "detector on a compliant foundation",
        lambda d: edited(d, "foundation", {"kind": "compliant", "mass": 150.0, "stiffness": 2e8}),
        "detector",
        "rail on supports",
    ),
    (
        "stretch above the limit",
        lambda d: d | {"speed": 20.0, "duration": 1.5001, "sample_rate": 1e4},
        "duration",
        "30 m",
    ),
    (
        "foundation displacement on a track",
        lambda d: d | {"initial": {"y_c": 0.0, "v_c": 0.0, "y_m": 1e-5, "v_m": 0.0}},
        "initial.y_m",
        "only y_c and v_c may be nonzero",
    ),
    (
        "foundation velocity on a slab",
        lambda d: (
            edited(d, "foundation", SLAB)
            | {"initial": {"y_c": 0.0, "v_c": 0.0, "y_m": 0.0, "v_m": 0.1}}
        ),
        "initial.v_m",
        "only y_c and v_c may be nonzero",
    ),
]


@pytest.mark.parametrize(
    ("edit", "path", "fragment"),
    [case[1:] for case in BAD_SCENARIOS],
    ids=[case[0] for case in BAD_SCENARIOS],
)
def test_bad_track_input_names_the_field(
    track_scenario: dict[str, Any],
    edit: Callable[[dict[str, Any]], dict[str, Any]],
    path: str,
    fragment: str,
) -> None:
    report = report_of(edit(track_scenario))
    assert [e.path for e in report.errors] == [path], report.to_text()
    assert fragment in report.errors[0].message, report.to_text()


@pytest.mark.parametrize(
    ("edit", "path", "fragment"),
    [case[1:] for case in BAD_SCENARIOS],
    ids=[case[0] for case in BAD_SCENARIOS],
)
def test_simulate_refuses_bad_track_input_on_one_line(
    track_scenario: dict[str, Any],
    edit: Callable[[dict[str, Any]], dict[str, Any]],
    path: str,
    fragment: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(edit(track_scenario)))
    code, out, err = run_main(["simulate", str(bad), "--out", str(tmp_path / "r.json")], capsys)
    assert code == 2 and out == ""
    assert "1 invalid field" in err, err
    naming = [line for line in err.splitlines() if line.strip().startswith(f"{path}:")]
    assert len(naming) == 1 and fragment in naming[0], err
    assert not (tmp_path / "r.json").exists()


def test_simulate_refuses_a_bad_crib_via_subprocess(
    track_scenario: dict[str, Any], tmp_path: Path, cli: Callable[..., Any]
) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(edited(track_scenario, "detector.cribs[1].x_b", 1.95)))
    proc = cli("simulate", str(bad))
    assert proc.returncode == 2 and proc.stdout == ""
    assert [line for line in proc.stderr.splitlines() if "detector.cribs[1].x_b:" in line]


# --- the limits at their edges --------------------------------------------------------------


def test_32_cribs_are_accepted_33_refused(track_scenario: dict[str, Any]) -> None:
    data = track_scenario | {"duration": 2.0}  # 27 m of track: room for 33 cribs
    ok = Scenario.model_validate(edited(data, "detector.cribs", cribs(MAX_CRIBS)))
    assert ok.detector is not None and len(ok.detector.cribs) == MAX_CRIBS == 32
    report = report_of(edited(data, "detector.cribs", cribs(MAX_CRIBS + 1)))
    assert [e.path for e in report.errors] == ["detector.cribs"]


@pytest.mark.parametrize("foundation", [DISCRETE, SLAB], ids=["discrete", "slab"])
def test_a_30_m_stretch_is_accepted_longer_refused(
    track_scenario: dict[str, Any], foundation: dict[str, Any]
) -> None:
    data = track_scenario | {"foundation": foundation, "speed": 20.0, "sample_rate": 1e4}
    s = Scenario.model_validate(data | {"duration": 1.5})
    assert s.speed * s.duration == MAX_TRACK_LENGTH == 30.0
    report = report_of(data | {"duration": 1.5 + 1e-9})
    assert [e.path for e in report.errors] == ["duration"]
    assert "MAX_TRACK_LENGTH" in Scenario.model_fields["duration"].description  # type: ignore[operator]


def test_the_length_limit_is_only_for_a_rail_on_supports(contract_example: dict[str, Any]) -> None:
    long = contract_example | {"speed": 20.0, "duration": 20.0, "sample_rate": 1e4}
    assert Scenario.model_validate(long).foundation.kind == "rigid"


# --- site files -----------------------------------------------------------------------------

SITE: dict[str, Any] = {
    "site_id": "km12",
    "length": 6.0,
    "output_sample_rate": 10000.0,
    "rail": {"kind": "flat"},
    "contact": "hertz",
    "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
    "foundation": DISCRETE,
    "detector": {"cribs": CRIBS},
}


def test_a_site_on_a_track_with_a_detector_validates() -> None:
    site = SiteConfig.model_validate(copy.deepcopy(SITE))
    assert site.foundation.kind == "discrete" and site.detector is not None
    for version in ("1.0", "1.1"):  # older site files stay readable
        assert SiteConfig.model_validate(copy.deepcopy(SITE) | {"schema_version": version})


@pytest.mark.parametrize(
    ("edit", "path"),
    [
        (lambda d: edited(d, "detector.cribs[1].x_b", 6.2), "detector.cribs[1].x_b"),
        (lambda d: edited(d, "detector.cribs[1].x_b", 2.5), "detector.cribs[1]"),
        (lambda d: d | {"foundation": {"kind": "rigid"}}, "detector"),
        (lambda d: d | {"foundation": SLAB, "length": 200.5}, "length"),
    ],
    ids=["beyond the site", "over a sleeper", "rigid", "too long"],
)
def test_a_bad_site_names_the_field(
    edit: Callable[[dict[str, Any]], dict[str, Any]], path: str
) -> None:
    report = report_of(edit(copy.deepcopy(SITE)), SiteConfig)
    assert [e.path for e in report.errors] == [path], report.to_text()


def test_a_30_m_site_on_a_track_is_accepted() -> None:
    site = SiteConfig.model_validate(copy.deepcopy(SITE) | {"length": 30.0})
    assert site.length == MAX_TRACK_LENGTH
    assert "MAX_TRACK_LENGTH" in SiteConfig.model_fields["length"].description  # type: ignore[operator]


# --- results --------------------------------------------------------------------------------


def _result(scenario: dict[str, Any], channels: dict[str, list[float]] | None) -> dict[str, Any]:
    n = 3
    series = {k: [0.0] * n for k in ("t", "x", "y_c", "v_c", "y_ck", "y_m", "delta", "force")}
    summary = {
        "peak_force": 1.0,
        "min_force": 0.0,
        "contact_losses": 0,
        "first_loss_time": None,
        "time_out_of_contact": 0.0,
        "max_indentation": 1e-5,
        "max_dent": 0.0,
    }
    return {
        "scenario": scenario,
        "derived": {
            "contact_coefficient": 1.08e11,
            "static_indentation": 5.09e-5,
            "contact_frequency": 270.6,
            "yield_force": None,
            "yield_indentation": None,
        },
        "series": series | {"in_contact": [True] * n, "channels": channels},
        "transitions": [],
        "summary": summary,
        "rail_after": None,
        "passes_summary": [summary],
    }


def test_result_channels_round_trip(track_scenario: dict[str, Any]) -> None:
    r = Result.model_validate(_result(track_scenario, {"c1": [0.0, 1.0, 2.0], "c2": [0.0] * 3}))
    assert r.series.channels is not None and r.series.channels["c1"] == [0.0, 1.0, 2.0]
    assert Result.model_validate_json(r.model_dump_json()) == r


@pytest.mark.parametrize(
    ("scenario_kind", "channels", "path"),
    [
        ("track", {"c1": [0.0] * 3, "c2": [0.0] * 2}, "series.channels.c2"),
        ("track", {"c1": [0.0] * 3}, "series.channels"),
        ("track", None, "series.channels"),
        ("rigid", {"c1": [0.0] * 3}, "series.channels"),
    ],
)
def test_result_channels_must_match_the_detector(
    track_scenario: dict[str, Any],
    contract_example: dict[str, Any],
    scenario_kind: str,
    channels: dict[str, list[float]] | None,
    path: str,
) -> None:
    scenario = track_scenario if scenario_kind == "track" else contract_example
    data = _result(scenario, channels)
    with pytest.raises(ValidationError) as info:
        Result.model_validate(data)
    assert ErrorReport.from_validation_error(info.value, data).errors[0].path == path


def test_passage_result_channels_have_one_sample_per_x() -> None:
    base: dict[str, Any] = {
        "site_id": "km12",
        "passage_id": "p1",
        "train_id": "t1",
        "axle_index": 0,
        "side": "right",
        "timestamp": 1.7e9,
        "speed": 20.0,
        "sample_rate": 1e4,
        "t_start": 0.0,
        "site_length": 6.0,
        "rail_revision": 0,
        "wall_time": 0.1,
        "steps": 10,
        "transitions": [],
        "summary": _result({}, None)["summary"],
    } | {k: [0.0, 0.0] for k in ("x", "force", "indentation", "y_c", "y_ck")}
    ok = PassageResult.model_validate(base | {"channels": {"c1": [1.0, 2.0]}})
    assert ok.channels == {"c1": [1.0, 2.0]} and ok.schema_version == "1.5"
    assert PassageResult.model_validate(base).channels is None  # a 1.1 producer's result
    with pytest.raises(ValidationError, match=r"channels\.c1"):
        PassageResult.model_validate(base | {"channels": {"c1": [1.0]}})


# --- CONTRACT.md ----------------------------------------------------------------------------


def _section_blocks() -> list[dict[str, Any]]:
    text = (ROOT / "docs" / "CONTRACT.md").read_text(encoding="utf-8")
    section = text.split("## A rail on discrete supports, and a detector", 1)[1]
    blocks = re.findall(r"```json\n(.*?)```", section, re.S)
    return [json.loads("{" + b + "}") for b in blocks[:2]]


def test_the_contracts_track_and_detector_examples_validate(
    contract_example: dict[str, Any],
) -> None:
    foundation, detector = _section_blocks()
    s = Scenario.model_validate(contract_example | foundation)
    assert s.foundation.kind == "discrete"
    # the detector's cribs lie between sleepers at 0.1 + 0.6·i m (the example track's
    # first_sleeper = 0.3 puts sleepers at 1.5 and 2.1 m, inside them)
    shifted = edited(foundation, "foundation.first_sleeper", 0.1)
    assert Scenario.model_validate(contract_example | shifted | detector).detector is not None
    report = report_of(contract_example | foundation | detector)
    assert [e.path for e in report.errors] == ["detector.cribs[0]"]


# --- to sim_core ----------------------------------------------------------------------------


def test_the_foundations_convert_to_sim_core(track_scenario: dict[str, Any]) -> None:
    s = Scenario.model_validate(track_scenario)
    spec = physics_inputs.foundation(s.foundation)
    assert isinstance(spec, TrackSpec) and spec.kind == "discrete"
    assert (spec.sleeper_spacing, spec.first_sleeper, spec.sleeper_mass) == (0.6, 0.1, 150.0)
    assert (spec.pad.stiffness, spec.pad.damping) == (2.0e8, 3.0e4)
    assert spec.ballast is not None and spec.ballast.stiffness == 1.2e8
    assert spec.rail.shear_coefficient == 0.4 and spec.rail.beam == "timoshenko"
    assert physics_inputs.lumped(spec) is None
    slab = physics_inputs.foundation(
        Scenario.model_validate(track_scenario | {"foundation": SLAB}).foundation
    )
    assert isinstance(slab, TrackSpec) and slab.kind == "slab" and slab.ballast is None
    assert physics_inputs.cribs(s.detector) == (Crib("c1", 1.4, 1.8), Crib("c2", 2.0, 2.4))
    assert physics_inputs.cribs(None) == ()
    check_cribs(physics_inputs.cribs(s.detector), spec, 0.0, s.speed * s.duration)


@settings(max_examples=200, deadline=None)
@given(
    spacing_cm=st.integers(10, 120),
    first_mm=st.integers(-2000, 2000),
    gauges_mm=st.lists(st.tuples(st.integers(0, 9000), st.integers(1, 900)), max_size=4),
)
def test_the_contract_and_sim_core_agree_on_cribs(
    spacing_cm: int, first_mm: int, gauges_mm: list[tuple[int, int]]
) -> None:
    """A detector the schema accepts is one ``sim_core.track.spec.check_cribs`` accepts."""
    foundation = DiscreteFoundation.model_validate(
        DISCRETE | {"sleeper_spacing": spacing_cm / 100, "first_sleeper": first_mm / 1000}
    )
    track = physics_inputs.track(foundation)
    data = {
        "site_id": "s",
        "length": 8.0,
        "output_sample_rate": 1e4,
        "rail": {"kind": "flat"},
        "contact": "hertz",
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
        "foundation": foundation.model_dump(),
        "detector": {
            "cribs": [
                {"id": f"c{i}", "x_a": a / 1000, "x_b": (a + w) / 1000}
                for i, (a, w) in enumerate(gauges_mm)
            ]
        },
    }
    try:
        site = SiteConfig.model_validate(data)
    except ValidationError:
        accepted = False
    else:
        accepted = True
        assert physics_inputs.cribs(site.detector)
    try:
        given_cribs = tuple(Crib(c["id"], c["x_a"], c["x_b"]) for c in data["detector"]["cribs"])
        check_cribs(given_cribs, track, 0.0, 8.0)
    except TrackError:
        agreed = False
    else:
        agreed = True
    assert accepted == agreed


def test_the_diagnosis_refuses_a_contact_force_on_a_track() -> None:
    """On a track the diagnosis fits crib channels (``tests/test_diagnosis_channels.py``);
    a contact force it fits on a rigid or one-mass foundation only."""
    from schemas.messages import WheelPassage
    from service.physics.diagnosis import Diagnoser
    from service.physics.measurement_error import MeasurementError

    site = SiteConfig.model_validate(copy.deepcopy(SITE))
    d = Diagnoser(site)
    assert d.diagnoses_here == (d.crib_site is not None)
    passage = WheelPassage(
        passage_id="p1",
        train_id="t1",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=20.0,
        load=80e3,
        mass=800.0,
        radius=0.46,
    )
    with pytest.raises(MeasurementError) as info:
        d.wheel(passage)
    assert info.value.field == "foundation" and "discrete" in info.value.message


# --- through the physics --------------------------------------------------------------------


def test_a_scenario_with_a_detector_runs_with_its_channels(track_scenario: dict[str, Any]) -> None:
    from service.physics.scenario_runner import run_scenario

    data = track_scenario | {"rail": {"kind": "flat"}, "sample_rate": 1e4}
    r = run_scenario(Scenario.model_validate(data))
    assert r.series.channels is not None and list(r.series.channels) == ["c1", "c2"]
    load = data["wheel"]["load"]
    for values in r.series.channels.values():
        assert len(values) == len(r.series.t)
        assert max(values) == pytest.approx(load, rel=0.2)  # +P with the wheel in the crib
    Result.model_validate_json(r.model_dump_json())


def test_a_track_without_a_detector_runs_without_channels(
    track_scenario: dict[str, Any],
) -> None:
    from service.physics.scenario_runner import run_scenario

    data = track_scenario | {"rail": {"kind": "flat"}, "sample_rate": 1e4, "detector": None}
    assert run_scenario(Scenario.model_validate(data)).series.channels is None


def test_a_site_with_a_detector_publishes_its_channels() -> None:
    from schemas.messages import WheelPassage
    from service.physics.site_physics import SitePhysics

    physics = SitePhysics(SiteConfig.model_validate(copy.deepcopy(SITE)))
    passage = WheelPassage(
        passage_id="p1",
        train_id="t1",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=30.0,
        load=80e3,
        mass=800.0,
        radius=0.46,
    )
    result = physics.simulate(passage)
    assert result.channels is not None and list(result.channels) == ["c1", "c2"]
    assert all(len(v) == len(result.x) for v in result.channels.values())
    assert max(result.channels["c1"]) == pytest.approx(passage.load, rel=0.2)
