"""The railtwin command line: help, simulate, schema, figures; exit codes and error messages."""

from __future__ import annotations

import json
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from schemas import ErrorReport, Result, Scenario
from schemas.scenario import EXAMPLE_JSON
from service.cli import main as cli
from service.physics.scenario_runner import package_result
from tests.conftest import EXAMPLE_SCENARIOS, EXAMPLES

Run = Callable[..., Any]


def run_main(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """cli.main in-process; (exit code, stdout, stderr). argparse's SystemExit is caught."""
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def write(tmp_path: Path, name: str, data: Any) -> Path:
    path = tmp_path / name
    path.write_text(data if isinstance(data, str) else json.dumps(data))
    return path


# --- help and usage -------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv", [["--help"], ["simulate", "--help"], ["schema", "--help"], ["figures", "--help"]]
)
def test_help_exits_zero(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_main(argv, capsys)
    assert code == 0
    assert "usage: railtwin" in out
    assert "exit status" in out and "invalid input" in out


def test_no_command_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_main([], capsys)
    assert code == 2 and "required" in err


def test_help_via_subprocess(cli: Run) -> None:
    proc = cli("--help")
    assert proc.returncode == 0, proc.stderr
    for command in ("simulate", "schema", "figures"):
        assert command in proc.stdout


# --- simulate: bad input --------------------------------------------------------------------


def test_invalid_scenario_exits_2_naming_the_field(cli: Run, tmp_path: Path) -> None:
    data = json.loads(EXAMPLE_JSON)
    data["wheel"]["outline"] = {"kind": "flat", "length": 1.2}
    path = write(tmp_path, "bad.json", data)
    proc = cli("simulate", str(path), "--out", str(tmp_path / "r.json"))
    assert proc.returncode == 2
    assert "wheel.outline.length" in proc.stderr and "2·radius" in proc.stderr
    assert proc.stdout == ""
    assert not (tmp_path / "r.json").exists()


def test_invalid_scenario_json_error_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = json.loads(EXAMPLE_JSON)
    data["contact"] = "johnson"
    data["material"]["yield_stress"] = None
    path = write(tmp_path, "bad.json", data)
    code, out, err = run_main(["simulate", str(path), "--format", "json"], capsys)
    assert code == 2 and out == ""
    report = ErrorReport.model_validate_json(err)
    assert report.error == "invalid_scenario" and report.source == str(path)
    assert [e.path for e in report.errors] == ["material.yield_stress"]


@pytest.mark.parametrize(
    ("content", "fragment"),
    [("{not json", "not valid JSON: line 1"), ('{"wheel": 1, "colour": 2}', "colour")],
)
def test_unreadable_input_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: str, fragment: str
) -> None:
    code, _, err = run_main(["simulate", str(write(tmp_path, "s.json", content))], capsys)
    assert code == 2 and fragment in err


def test_missing_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_main(["simulate", str(tmp_path / "nope.json")], capsys)
    assert code == 2 and "cannot read" in err and "nope.json" in err


def test_runtime_failure_exits_1(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def boom(scenario: Scenario, progress: Any = None) -> Result:
        raise RuntimeError("integrator diverged")

    monkeypatch.setattr("service.physics.scenario_runner.run_scenario", boom)
    path = write(tmp_path, "s.json", EXAMPLE_JSON)
    code, _, err = run_main(["simulate", str(path), "--out", str(tmp_path / "r.json")], capsys)
    assert code == 1 and "simulation failed: RuntimeError: integrator diverged" in err
    assert not (tmp_path / "r.json").exists()


# --- simulate: the plumbing, against a fake sim_core.multipass ------------------------------


def _fake_passage(n: int) -> Any:
    """Stands in for a ``PassageOutput``: the attributes the runner reads."""
    from sim_core.passage import Transition

    t = np.linspace(0.0, 0.01, n)
    delta = 5e-5 * np.cos(2 * np.pi * 300 * t)
    return types.SimpleNamespace(
        t=t,
        x=13.53 * t,
        y_c=np.zeros(n),
        v_c=np.zeros(n),
        y_ck=np.zeros(n),
        y_m=np.zeros(n),
        v_m=np.zeros(n),
        delta=delta,
        force=np.clip(delta, 0, None) * 1e9,
        in_contact=delta > 0,
        transitions=(Transition(0.00083, "loss", 0.0112), Transition(0.0025, "contact", 0.034)),
        steps=100,
        rejected_steps=2,
        rhs_evaluations=1200,
    )


def _fake_summary(i: int) -> Any:
    return types.SimpleNamespace(
        peak_force=np.float64(5e4 + i),
        min_force=0.0,
        contact_losses=np.int64(3),
        first_loss_time=None if i == 0 else 0.00083,
        time_out_of_contact=0.005,
        max_indentation=5e-5,
        max_dent=1e-6 * i,
    )


@pytest.fixture
def fake_multipass(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Replace sim_core.multipass/wheel/rail with fakes that record their calls."""
    calls: list[dict[str, Any]] = []

    def simulate_passes(wheel: Any, rail: Any, spec: Any, **kw: Any) -> Any:
        calls.append({"wheel": wheel, "rail": rail, "spec": spec, **kw})
        n = round(spec.sample_rate * spec.duration) + 1
        passes = [_fake_passage(n) for _ in range(kw["passes"])]
        for i in range(kw["passes"]):
            if "progress" in kw:
                kw["progress"](i + 1, kw["passes"], _fake_summary(i))
        rail_after = types.SimpleNamespace(x=np.array([0.0, 1.0]), y=np.array([0.0, -1e-6]))
        return types.SimpleNamespace(
            passes=passes,
            last=passes[-1],
            summaries=[_fake_summary(i) for i in range(len(passes))],
            rail_after=rail_after if spec.contact.law.is_plastic else None,
        )

    def factory(kind: str) -> Any:
        return lambda *a, **k: (kind, a)

    multipass = types.ModuleType("sim_core.multipass")
    multipass.simulate_passes = simulate_passes  # type: ignore[attr-defined]
    wheel = types.ModuleType("sim_core.wheel")
    wheel.WheelOutline = types.SimpleNamespace(  # type: ignore[attr-defined]
        round=factory("round"),
        ideal_flat=factory("flat"),
        rounded_flat=factory("rounded_flat"),
        sampled=factory("sampled"),
    )
    rail = types.ModuleType("sim_core.rail")
    rail.RailProfile = types.SimpleNamespace(  # type: ignore[attr-defined]
        flat=factory("flat"),
        cosine=factory("cosine"),
        step=factory("step"),
        sampled=factory("sampled"),
    )
    monkeypatch.setitem(sys.modules, "sim_core.multipass", multipass)
    # the runner builds wheel and rail through service.physics.inputs (imported already)
    monkeypatch.setattr("service.physics.inputs.WheelOutline", wheel.WheelOutline)
    monkeypatch.setattr("service.physics.inputs.RailProfile", rail.RailProfile)
    return calls


def test_simulate_plumbing(
    fake_multipass: list[dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sub" / "r.json"
    code, stdout, err = run_main(
        ["simulate", str(EXAMPLES / "hertz_plastic_dents.json"), "--out", str(out)], capsys
    )
    assert code == 0, err
    (call,) = fake_multipass
    assert call["passes"] == 3 and call["constraint"] == "exact" and call["phase"] == 0.0
    assert call["wheel"] == ("round", (0.475,)) and call["rail"] == ("flat", ())
    assert call["spec"].initial.v_c == -0.3 and call["spec"].contact.yield_force > 0
    assert "pass 3/3" in err  # progress on stderr
    result = Result.model_validate_json(out.read_text())
    assert len(result.passes_summary) == 3 and result.summary == result.passes_summary[-1]
    assert result.rail_after is not None and result.rail_after.y == [0.0, -1e-6]
    assert result.transitions[0].kind == "loss" and result.stats is not None
    assert result.stats.steps == 100
    assert "max dent" in stdout and "result written to" in stdout


def test_simulate_json_summary_and_stdout_result(
    fake_multipass: list[dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "s.json", EXAMPLE_JSON)
    code, stdout, _ = run_main(["simulate", str(path), "--format", "json"], capsys)
    assert code == 0
    doc = json.loads(stdout)
    assert doc["out"] is None and doc["summary"]["contact_losses"] == 3
    code, stdout, _ = run_main(["simulate", str(path), "--out", "-"], capsys)
    assert code == 0
    assert Result.model_validate_json(stdout).rail_after is None
    code, stdout, err = run_main(
        ["simulate", str(path), "-q", "-o", str(tmp_path / "r.json")], capsys
    )
    assert code == 0 and stdout == "" and err == ""


def test_package_result_converts_numpy_types() -> None:
    scenario = Scenario.model_validate_json(EXAMPLE_JSON)
    derived = types.SimpleNamespace(
        contact_coefficient=np.float64(1.08e11),
        static_indentation=5.09e-5,
        contact_frequency=270.6,
        yield_force=None,
        yield_indentation=None,
    )
    passage = _fake_passage(11)
    out = types.SimpleNamespace(
        passes=[passage], last=passage, summaries=[_fake_summary(0)], rail_after=None
    )
    result = package_result(scenario, derived, out, 0.5)
    assert result.series.in_contact[0] is True and len(result.series.t) == 11
    assert result.derived.yield_force is None
    assert result.transitions[1].x == 0.034


# --- simulate: the real physics -------------------------------------------------------------


@pytest.mark.parametrize("path", EXAMPLE_SCENARIOS, ids=lambda p: p.stem)
def test_simulate_every_example(
    path: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "result.json"
    code, stdout, err = run_main(["simulate", str(path), "--out", str(out)], capsys)
    assert code == 0, err
    result = Result.model_validate_json(out.read_text())
    scenario = Scenario.model_validate_json(path.read_text())
    assert result.scenario == scenario
    n = len(result.series.t)
    assert abs(n - scenario.expected_samples) <= 1
    assert result.series.t[0] == 0.0
    assert abs(result.series.t[-1] - scenario.duration) <= 1.0 / scenario.sample_rate
    assert len(result.passes_summary) == scenario.passes
    assert result.summary == result.passes_summary[-1]
    assert result.summary.contact_losses == sum(t.kind == "loss" for t in result.transitions)
    if scenario.contact == "hertz":
        assert result.rail_after is None and result.summary.max_dent == 0.0
    if scenario.contact == "hertz_plastic":
        assert result.rail_after is not None
        assert result.passes_summary[0].max_dent > 0.0  # the example is set up to dent
    assert "peak F" in stdout


def test_simulate_contract_example_via_subprocess(cli: Run, tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    proc = cli("simulate", "-", "--out", str(out), "--format", "json", stdin=EXAMPLE_JSON)
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    result = Result.model_validate_json(out.read_text())
    assert doc["summary"] == result.summary.model_dump(mode="json")
    assert result.derived.contact_coefficient == pytest.approx(1.0805e11, rel=1e-4)
    assert result.derived.contact_frequency == pytest.approx(270.6, abs=0.05)


# --- simulate: batch mode (several scenarios, --out-dir) -------------------------------------


def test_batch_help_documents_out_dir_and_exit_status(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_main(["simulate", "--help"], capsys)
    assert code == 0
    assert "--out-dir DIR" in out and "batch mode" in out
    assert "2 if any file was unreadable or invalid" in out


@pytest.mark.parametrize(
    ("argv", "fragment"),
    [
        (["a.json", "b.json"], "2 scenarios need --out-dir DIR"),
        (["a.json", "--out", "r.json", "--out-dir", "d"], "not allowed with argument"),
        (["a.json", "-", "--out-dir", "d"], "'-' (stdin) has no name"),
        (["x/a.json", "y/a.json", "--out-dir", "d"], "would both be written to"),
    ],
)
def test_batch_usage_errors_exit_2(
    argv: list[str], fragment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _, err = run_main(["simulate", *argv], capsys)
    assert code == 2 and fragment in err


def test_batch_refuses_to_overwrite_its_input(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(tmp_path, "s.json", EXAMPLE_JSON)
    code, _, err = run_main(["simulate", str(path), "--out-dir", str(tmp_path)], capsys)
    assert code == 2 and "would overwrite its own scenario" in err
    assert path.read_text() == EXAMPLE_JSON


@pytest.fixture
def batch_files(tmp_path: Path) -> list[Path]:
    """Two good scenarios (a slow one first, then a fast one), a bad one, a missing one."""
    slow = json.loads(EXAMPLE_JSON)
    slow["duration"] = 0.05
    fast = json.loads(EXAMPLE_JSON)
    fast["duration"] = 0.01
    bad = json.loads(EXAMPLE_JSON)
    bad["speed"] = -1.0
    return [
        write(tmp_path, "slow.json", slow),
        write(tmp_path, "bad.json", bad),
        tmp_path / "missing.json",
        write(tmp_path, "fast.scenario", fast),
    ]


def test_batch_plumbing_own_wall_times_and_exit_2(
    fake_multipass: list[dict[str, Any]],
    batch_files: list[Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    import time

    events: list[str] = []
    fake = sys.modules["sim_core.multipass"]
    plain = fake.simulate_passes

    def simulate_passes(wheel: Any, rail: Any, spec: Any, **kw: Any) -> Any:
        events.append(f"run {spec.duration:g}")
        time.sleep(0.3 if spec.duration == 0.05 else 0.0)  # the slow scenario takes 0.3 s
        return plain(wheel, rail, spec, **kw)

    monkeypatch.setattr(fake, "simulate_passes", simulate_passes)

    def warm_up() -> float:
        events.append("warm-up")
        return 0.0

    monkeypatch.setattr("service.physics.scenario_runner.warm_up", warm_up)
    out_dir = tmp_path / "results"
    code, stdout, err = run_main(
        ["simulate", *map(str, batch_files), "--out-dir", str(out_dir)], capsys
    )
    # the bad and the missing file: one line each, exit 2 at the end; the others written
    assert code == 2
    assert sorted(p.name for p in out_dir.iterdir()) == ["fast.json", "slow.json"]
    assert events == ["warm-up", "run 0.05", "run 0.01"]  # compiled once, before the first
    lines = err.splitlines()
    (bad_line,) = [ln for ln in lines if "bad.json" in ln]
    assert bad_line.startswith("railtwin simulate: [2/4] invalid scenario") and "speed" in bad_line
    (missing_line,) = [ln for ln in lines if "missing.json" in ln]
    assert "[3/4] cannot read" in missing_line
    assert any("[1/4]" in ln and "slow.json" in ln for ln in lines)  # progress on stderr
    assert "2 of 4 scenarios written" in err
    # each result is its own scenario with its own wall time (not the time since start)
    slow = Result.model_validate_json((out_dir / "slow.json").read_text())
    fast = Result.model_validate_json((out_dir / "fast.json").read_text())
    assert slow.scenario.duration == 0.05 and fast.scenario.duration == 0.01
    assert slow.stats is not None and fast.stats is not None
    assert slow.stats.wall_time is not None and fast.stats.wall_time is not None
    assert slow.stats.wall_time >= 0.3 and fast.stats.wall_time < 0.2
    assert stdout.count("peak F") == 2 and f"result written to {out_dir / 'fast.json'}" in stdout


def test_batch_runtime_failure_exits_1_others_written(
    fake_multipass: list[dict[str, Any]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    fake = sys.modules["sim_core.multipass"]
    plain = fake.simulate_passes

    def simulate_passes(wheel: Any, rail: Any, spec: Any, **kw: Any) -> Any:
        if spec.duration == 0.01:
            raise RuntimeError("integrator diverged")
        return plain(wheel, rail, spec, **kw)

    monkeypatch.setattr(fake, "simulate_passes", simulate_passes)
    monkeypatch.setattr("service.physics.scenario_runner.warm_up", lambda: 0.0)
    a = json.loads(EXAMPLE_JSON)
    b = dict(a, duration=0.01)
    paths = [str(write(tmp_path, "a.json", a)), str(write(tmp_path, "b.json", b))]
    out_dir = tmp_path / "out"
    code, stdout, err = run_main(
        ["simulate", *paths, "--out-dir", str(out_dir), "--format", "json"], capsys
    )
    assert code == 1
    assert [p.name for p in out_dir.iterdir()] == ["a.json"]
    (report,) = [json.loads(ln) for ln in err.splitlines() if ln.startswith("{")]
    assert report["error"] == "runtime_error" and report["source"] == paths[1]
    (doc,) = [json.loads(ln) for ln in stdout.splitlines()]  # one JSON line per result
    assert doc["source"] == paths[0] and doc["out"] == str(out_dir / "a.json")
    # --quiet: nothing on stdout, only the failure on stderr
    code, stdout, err = run_main(["simulate", *paths, "--out-dir", str(out_dir), "-q"], capsys)
    assert code == 1 and stdout == ""
    assert err.strip().splitlines() == [
        f"railtwin simulate: [2/2] {paths[1]}: simulation failed: RuntimeError: integrator diverged"
    ]


def test_batch_real_physics_via_subprocess(cli: Run, tmp_path: Path) -> None:
    """One process simulates several examples; each file equals its single-mode result."""
    names = ["ideal_flat.json", "sampled_rail.json", "step_rail.json"]
    out_dir = tmp_path / "batch"
    proc = cli("simulate", *(str(EXAMPLES / n) for n in names), "--out-dir", str(out_dir))
    assert proc.returncode == 0, proc.stderr
    assert "compiled physics loaded" in proc.stderr and "3 of 3 scenarios written" in proc.stderr
    single = tmp_path / "single.json"
    proc = cli("simulate", str(EXAMPLES / "step_rail.json"), "--out", str(single), "-q")
    assert proc.returncode == 0, proc.stderr
    for n in names:
        result = Result.model_validate_json((out_dir / n).read_text())
        assert result.scenario == Scenario.model_validate_json((EXAMPLES / n).read_text())
        assert result.stats is not None and result.stats.wall_time is not None
        assert result.stats.wall_time < 1.0  # its own time, without the compilation
    batch_step = Result.model_validate_json((out_dir / "step_rail.json").read_text())
    single_step = Result.model_validate_json(single.read_text())
    assert batch_step.series == single_step.series
    assert batch_step.summary == single_step.summary


# --- schema and figures ---------------------------------------------------------------------


def test_schema_all_and_one(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_main(["schema"], capsys)
    assert code == 0
    assert {"Scenario", "Result", "ErrorReport"} <= set(json.loads(out))
    code, out, _ = run_main(["schema", "scenario"], capsys)
    assert code == 0 and json.loads(out)["title"] == "Scenario"
    code, _, err = run_main(["schema", "Nope"], capsys)
    assert code == 2 and "known:" in err


def test_figures_without_matplotlib(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import fails
    code, _, err = run_main(["figures", "--out", str(tmp_path)], capsys)
    assert code == 1 and "matplotlib is not installed" in err


def test_figures_calls_make_figures(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    made: list[Path] = []

    def make_figures(out_dir: Path) -> list[Path]:
        made.append(out_dir / "fig3.png")
        return made

    fake = types.ModuleType("service.cli.figures")
    fake.make_figures = make_figures  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "service.cli.figures", fake)
    code, out, _ = run_main(["figures", "--out", str(tmp_path / "figs")], capsys)
    assert code == 0 and out.strip() == str(tmp_path / "figs" / "fig3.png")
    assert (tmp_path / "figs").is_dir()


def test_service_commands_register(monkeypatch: pytest.MonkeyPatch) -> None:
    """A register() in SERVICE_COMMANDS adds its subcommand, whose func gives the exit code."""

    def register(subparsers: Any) -> None:
        p = subparsers.add_parser("hello", help="say hello")
        p.set_defaults(func=lambda args: 7)

    monkeypatch.setattr(cli, "SERVICE_COMMANDS", {"hello": register})
    assert cli.main(["hello"]) == 7


@pytest.mark.parametrize(
    "command",
    [
        "serve",
        "feed",
        "feed-measured",
        "synthesize",
        "replay",
        "diagnose",
        "recover",
        "demo",
        "warm",
        "router",
        "fleet",
    ],
)
def test_every_entry_point_is_a_subcommand(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_main([command, "--help"], capsys)
    assert code == 0 and out.startswith(f"usage: railtwin {command}")
