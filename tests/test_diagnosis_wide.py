"""The diagnosis on independent data (``validation/measured-wide``) through ``railtwin
diagnose``, the fields that say how well the fit explains a record, and the worn flat's
fitted depth. The full tables are ``make validate`` (validation/diagnosis_validation.py)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import WheelPassage
from service.cli.main import main as cli_main
from service.clients.synthesize import measure
from service.physics.diagnosis import EXPLAINED_RATIO, Diagnoser
from service.wire.site import load_site
from sim_core.diagnosis.estimate import estimate_flat, record_noise
from sim_core.diagnosis.forward import Flat
from sim_core.diagnosis.sensor import SensorModel
from sim_core.diagnosis.synthetic import Perturbations, synthetic_measurement
from sim_core.diagnosis.verdict import verdict
from sim_core.rail import RailProfile
from tests.test_diagnosis import R, wheel
from validation.wide_set import WIDE_DIR, load_case


def _tolerance(true_length: float) -> float:
    return max(0.005, 0.1 * true_length)


# passages the fit explains (a spread of kinds, speeds and chains); the misses of the wide
# set are listed and explained in docs/diagnosis.md
@pytest.mark.parametrize("case_id", ["W04", "W22", "W32", "W36"])
def test_wide_set_passage_through_railtwin_diagnose(
    case_id: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    c = load_case(case_id)
    pj = tmp_path / "p.json"
    pj.write_text(c.passage.model_dump_json())
    out = tmp_path / "d.json"
    code = cli_main(
        [
            "diagnose",
            "--site",
            str(WIDE_DIR / f"{case_id}.site.toml"),
            "--passage",
            str(pj),
            "--measured",
            str(WIDE_DIR / f"{case_id}.csv"),
            "--out",
            str(out),
        ]
    )
    assert code == 0
    capsys.readouterr()
    d = Diagnosis.model_validate_json(out.read_text())
    assert d.explained is True and d.noise_level is not None and d.fit_residual_ratio is not None
    assert d.fit_residual_ratio <= EXPLAINED_RATIO
    kind = c.truth["kind"]
    if kind is None:
        assert d.flat is None
        return
    true_len = float(c.truth["flat_length_m"])
    assert d.flat is not None and d.flat.kind == kind
    assert abs(d.flat.length - true_len) <= _tolerance(true_len)
    assert d.flat.length_low <= true_len <= d.flat.length_high
    lo, hi = d.peak_force_at_line_speed_low, d.peak_force_at_line_speed_high
    assert lo is not None and hi is not None and d.peak_force_at_line_speed is not None
    assert lo <= d.peak_force_at_line_speed <= hi
    assert c.line_peak_measured is not None and lo <= c.line_peak_measured <= hi
    if kind == "rounded_flat":  # the depth is fitted, not l²/16R
        assert d.flat.depth_factor is not None and 0.7 <= d.flat.depth_factor <= 1.3
        typical = d.flat.length**2 / (16 * c.passage.radius)
        assert d.flat.depth == pytest.approx(d.flat.depth_factor * typical)


def test_record_noise_is_the_white_noise_of_a_filtered_record() -> None:
    rng = np.random.default_rng(5)
    t = np.arange(0.0, 0.5, 1e-4)
    smooth = 80e3 + 20e3 * np.sin(2 * np.pi * 30 * t) + 5e3 * np.sin(2 * np.pi * 400 * t)
    f = smooth + rng.normal(0.0, 1500.0, t.size)
    f[2000:2020] += 300e3  # an impact: a small part of the record
    assert record_noise(f) == pytest.approx(1500.0, rel=0.1)


def test_a_record_the_model_cannot_make_is_not_explained_and_says_so() -> None:
    """A flat's record with a 40 Hz swing of 0.4 P added (nothing a flat on this site makes):
    the residual stands far above the record's noise, ``explained`` is false, the reasons
    say so and the verdict is at least what the measured peaks alone give."""
    root = Path(__file__).resolve().parents[1]
    site = load_site(root / "examples/site_compliant.toml")
    d = Diagnoser(site)
    p = WheelPassage(
        passage_id="odd",
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=20.0,
        load=80e3,
        mass=600.0,
        radius=0.46,
    )
    m = measure(
        site, p, Flat.ideal(0.46, 0.03, 1.0), seed=3, noise=0.01, roughness=0.0, diagnoser=d
    )
    f = m.force + 0.4 * p.load * np.sin(2 * np.pi * 40.0 * m.t)
    mp = MeasuredPassage(
        passage_id="odd", sample_rate=m.sample_rate, t_start=m.t_start, force=f.tolist()
    )
    diag, _ = d.diagnose(p, mp)
    assert diag.explained is False
    assert diag.fit_residual_ratio is not None and diag.fit_residual_ratio > EXPLAINED_RATIO
    assert "does not explain" in diag.reasons[0]
    peak_only, _ = verdict(d.limits, float(np.max(f)), None, None)
    order = ("ok", "watch", "inspect", "remove")
    assert order.index(diag.verdict) >= order.index(peak_only)


def test_a_worn_flat_depth_is_fitted() -> None:
    """A worn flat 1.25 × l²/16R deep, no roughness: depth and length are fitted together (they
    trade off: a longer, shallower flat makes nearly the same dip), the depth to 15 %."""
    length, factor, kmh = 0.07, 1.25, 50.0
    flat = Flat.rounded(R, length, factor * length**2 / (16 * R), 1.0)
    sensor = SensorModel(3000.0, 2)
    pert = Perturbations(
        noise_fraction=0.01,
        roughness_rms=0.0,
        foundation_damping=2 * 0.2 * math.sqrt(2e8 * 150.0),
        seed=11,
    )
    m = synthetic_measurement(wheel(), kmh / 3.6, flat, RailProfile.flat(), 6.0, 1e4, sensor, pert)
    est = estimate_flat(wheel(), kmh / 3.6, m.t, m.force, sensor)
    assert est.flat is not None and est.flat.kind == "rounded_flat"
    assert abs(est.flat.length - length) <= 0.1 * length
    assert 0.7 <= est.depth_factor <= 1.3
    assert est.flat.depth == pytest.approx(flat.depth, rel=0.15)


def test_a_diagnosis_from_before_schema_1_1_still_reads() -> None:
    old = {
        "site_id": "s",
        "passage_id": "p",
        "flat": None,
        "verdict": "ok",
        "reasons": [],
        "peak_force_measured": 8e4,
        "peak_force_fit": 8e4,
        "fit_rms": 1e3,
        "peak_force_at_line_speed": None,
        "wall_time": 0.1,
    }
    d = Diagnosis.model_validate(old)
    assert d.explained is None and d.peak_force_at_line_speed_high is None
    props = Diagnosis.model_json_schema()["properties"]
    assert {
        "noise_level",
        "fit_residual_ratio",
        "explained",
        "peak_force_at_line_speed_low",
        "peak_force_at_line_speed_high",
    } <= set(props)
    assert json.loads(d.model_dump_json())["verdict"] == "ok"


@pytest.mark.parametrize("case_id", ["W32", "W39"])
def test_cores_do_not_change_the_diagnosis(case_id: str) -> None:
    """``railtwin diagnose`` spreads the fit over two cores (a forked child searches one kind
    and runs half the line-speed band); the answer is the one core's."""
    c = load_case(case_id)
    one, _ = Diagnoser(c.site).diagnose(c.passage, c.measured)
    two, _ = Diagnoser(c.site, cores=2).diagnose(c.passage, c.measured)
    keep = {"wall_time"}
    assert one.model_dump(exclude=keep) == two.model_dump(exclude=keep)
    with pytest.raises(ValueError, match="cores must be at least 1"):
        Diagnoser(c.site, cores=0)


def test_diagnose_command_leaves_quickly_with_its_output_whole(tmp_path: Path) -> None:
    """The ``railtwin`` script ends ``diagnose`` with ``os._exit`` after flushing
    (``service.cli.main.QUICK_EXIT_COMMANDS``): the table, the --out file and the exit
    status are all there, on success and on a usage error."""
    import subprocess
    import sys

    c = load_case("W32")
    pj = tmp_path / "p.json"
    pj.write_text(c.passage.model_dump_json())
    out = tmp_path / "d.json"
    args = [sys.executable, "-m", "service.cli", "diagnose", "--site"]
    args += [str(WIDE_DIR / "W32.site.toml"), "--passage", str(pj), "--measured"]
    ok = subprocess.run(
        [*args, str(WIDE_DIR / "W32.csv"), "--out", str(out), "--format", "json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert ok.returncode == 0, ok.stderr
    assert Diagnosis.model_validate_json(ok.stdout) == Diagnosis.model_validate_json(
        out.read_text()
    )
    bad = subprocess.run(
        [*args, str(tmp_path / "missing.csv")], capture_output=True, text=True, timeout=120
    )
    assert bad.returncode == 2 and "missing.csv" in bad.stderr


def _record(m: MeasuredPassage) -> tuple[np.ndarray, np.ndarray]:
    """(sample times, forces) of a measured passage, as ``Diagnoser.diagnose`` reads it."""
    return m.t_start + np.arange(m.samples) / m.sample_rate, np.asarray(m.force)


def test_a_slow_wheels_depth_grid_finds_w39_which_one_depth_misses() -> None:
    """W39 (worn 107.7 mm, 0.8 x l²/16R, 28 km/h): the wheel follows the shallow flat
    (28 km/h against a following speed of 28.7 km/h), so the dip's depth fixes the depth
    factor and its length the flat's. Searched at the factor 1.0 only, no length fits and
    the fit settles on 57 mm, although the truth costs 19x less; a slow wheel's worn kind is
    searched at the factors 0.8, 1.0, 1.2 (``FitOptions.slow_depth_factors``), which finds
    it. Faster wheels keep the one factor (a worn flat's extra freedom takes fresh flats
    for worn ones at speed: docs/diagnosis.md)."""
    from dataclasses import replace

    from sim_core.diagnosis.estimate import (
        DEFAULT_OPTIONS,
        following_speed,
        shallow_following_speed,
    )

    c = load_case("W39")
    d = Diagnoser(c.site)
    wheel = d.wheel(c.passage)
    assert c.passage.speed <= DEFAULT_OPTIONS.slow_speed_ratio * following_speed(wheel)
    assert c.passage.speed <= DEFAULT_OPTIONS.slow_speed_ratio * shallow_following_speed(wheel)
    t, f = _record(c.measured)
    true_length = float(c.truth["flat_length_m"])
    one_depth = estimate_flat(
        wheel, c.passage.speed, t, f, d.sensor, replace(DEFAULT_OPTIONS, slow_speed_ratio=0.0)
    )
    assert abs(one_depth.best_length - true_length) > _tolerance(true_length)
    found = estimate_flat(wheel, c.passage.speed, t, f, d.sensor)
    assert found.best_kind == "rounded_flat"
    assert abs(found.best_length - true_length) <= _tolerance(true_length)
    assert found.cost_best < 0.2 * one_depth.cost_best
    assert found.length_low <= true_length <= found.length_high


def test_only_slow_wheels_get_the_depth_grid() -> None:
    """The worn kind's coarse grid spans depth factors up to 1.5 x the following speed of
    the shallowest worn flat searched, sqrt(8RP/(0.7 m))/π, at the middle damping ratio;
    above it, the factor 1.0 alone."""
    from sim_core.diagnosis.estimate import (
        DEFAULT_OPTIONS,
        _coarse_keys,
        following_speed,
        shallow_following_speed,
    )

    c = load_case("W39")
    wheel = Diagnoser(c.site).wheel(c.passage)
    vc = shallow_following_speed(wheel)
    assert vc == pytest.approx(following_speed(wheel) / math.sqrt(0.7), rel=1e-12)
    zetas, grid = (0.04, 0.08, 0.16), (0.02, 0.05)

    class _P:  # what _coarse_keys reads of a problem
        def __init__(self, speed: float) -> None:
            self.speed, self.wheel = speed, wheel

    kinds = ("flat", "rounded_flat")
    slow = _coarse_keys(_P(1.5 * vc), kinds, zetas, grid, DEFAULT_OPTIONS)  # type: ignore[arg-type]
    fast = _coarse_keys(_P(1.5001 * vc), kinds, zetas, grid, DEFAULT_OPTIONS)  # type: ignore[arg-type]
    assert {k[3] for k in fast} == {1.0} and len(fast) == 2 * 3 * 2
    assert {k[3] for k in slow if k[0] == "rounded_flat"} == {0.8, 1.0, 1.2}
    assert {k[2] for k in slow if k[3] != 1.0} == {0.08}
    assert len(slow) == len(fast) + 2 * 2


def test_a_simulation_the_integrator_cannot_resolve_still_gets_a_verdict(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Should the integrator fail on the round-wheel baseline or on every line-speed run,
    the wheel still gets a verdict from what was measured, and the reasons say why the
    forecast is missing (a diagnosis is given for every measured wheel)."""
    import service.physics.diagnosis as sd
    from sim_core.passage import IntegrationError

    c = load_case("W32")
    line = c.site.diagnosis.line_speed
    real = sd.simulate_passage_run_in

    def failing(wheel, speed, flat, *args, **kwargs):  # type: ignore[no-untyped-def]
        if speed == line or flat is None:
            raise IntegrationError("the step size fell below 1e-15 s (injected)")
        return real(wheel, speed, flat, *args, **kwargs)

    monkeypatch.setattr(sd, "simulate_passage_run_in", failing)
    d, curves = Diagnoser(c.site).diagnose(c.passage, c.measured)
    assert d.flat is not None and d.verdict == "remove"  # 429 kN measured: over 400 kN
    assert d.peak_force_at_line_speed is None and d.peak_force_at_line_speed_high is None
    assert any("could not be simulated" in r for r in d.reasons)
    assert curves.fitted.shape == curves.measured.shape


def test_a_shallow_worn_flat_followed_above_the_nominal_following_speed_is_found() -> None:
    """Seed 777's o026 of the own generator: worn 49.9 mm at 0.73 x l²/16R and 33 km/h,
    1.52 x the following speed of a flat of depth l²/16R but 1.30 x its own (a shallower dip
    is followed faster). Searched at the factor 1.0 alone, which a slow-wheel bound at
    1.5 x ``following_speed`` gave, the fit settled on 33.9 mm; bounded at 1.5 x the
    shallowest searched flat's following speed, the depth grid reaches it."""
    from dataclasses import replace

    from sim_core.diagnosis.estimate import DEFAULT_OPTIONS, following_speed
    from validation import own_generator

    rng = np.random.default_rng(777)
    own_generator.skip_cases(26, rng)
    c = own_generator.measured_case(26, rng)
    assert c.tread is not None and c.tread.kind == "rounded_flat"
    wheel = c.diagnoser.wheel(c.passage)
    ratio = c.passage.speed / following_speed(wheel)
    assert 1.5 < ratio < DEFAULT_OPTIONS.slow_speed_ratio / math.sqrt(0.7)
    t, f = _record(c.measured)
    nominal = replace(DEFAULT_OPTIONS, slow_speed_ratio=1.5 * math.sqrt(0.7))
    before = estimate_flat(wheel, c.passage.speed, t, f, c.diagnoser.sensor, nominal)
    found = estimate_flat(wheel, c.passage.speed, t, f, c.diagnoser.sensor)
    true_length = c.tread.length
    assert found.best_kind == "rounded_flat"
    assert found.cost_best < 0.5 * before.cost_best
    assert abs(found.best_length - true_length) < 0.5 * abs(before.best_length - true_length)
    assert found.length_low <= true_length <= found.length_high
