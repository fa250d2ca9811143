"""Every subcommand answers bad input alike: one line on stderr naming the file (or flag) and
the field or problem, exit status 2, no traceback, nothing on stdout.

Each command is given a malformed file (``{bad``, as a new user would try) and an
invalid-but-well-formed one, in process (``main(argv)``); one case runs as a subprocess.
Nothing here opens a Zenoh session, starts a service or compiles the physics: every input
is refused before that.
"""

from __future__ import annotations

import argparse
import json
import logging
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from mcap.writer import Writer

from schemas.scenario import EXAMPLE_JSON
from service.cli import main as cli
from tests.conftest import EXAMPLES, ROOT
from tests.test_cli import run_main

TRAIN = ROOT / "recordings/samples/train_160kmh.json"
SITE = EXAMPLES / "site_compliant.toml"
DATA = ROOT / "tests" / "data"
MALFORMED = "{bad"


def _passage() -> dict[str, Any]:
    passage: dict[str, Any] = json.loads(TRAIN.read_text())["wheels"][0]["passage"]
    return passage


def _invalid_train() -> dict[str, Any]:
    train: dict[str, Any] = json.loads(TRAIN.read_text())
    train["wheels"][3]["passage"]["load"] = "heavy"
    return train


def _empty_mcap(path: Path) -> None:
    """A finished MCAP log holding no message."""
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="test")
        w.finish()


@pytest.fixture
def files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, str]:
    """The inputs by name: ``bad.*`` malformed, ``inv.*`` well-formed but invalid."""
    monkeypatch.chdir(tmp_path)  # nothing is written beside the sources (fleet.sqlite, ...)
    scenario = json.loads(EXAMPLE_JSON)
    scenario["wheel"]["mass"] = -1.0
    texts = {
        "bad.json": MALFORMED,
        "bad.toml": MALFORMED,
        "bad.mcap": MALFORMED,
        "bad.csv": MALFORMED,
        "scenario.json": json.dumps(scenario),
        "passage.json": json.dumps(_passage() | {"speed": -1.0}),
        "good_passage.json": json.dumps(_passage()),
        "train.json": json.dumps(_invalid_train()),
        "measured.json": json.dumps([{"passage_id": "a", "sample_rate": 1.0, "force": [1.0]}]),
        "site.toml": SITE.read_text().replace('contact = "hertz"', 'contact = "glue"'),
        "limits.toml": "[diagnosis]\ninspect_force = -1.0\n",
        "zenoh.json5": '{mode: "bogus"}',
        "run-inputs.journal": '{"not": "a journal"}',
        "out_file": "",
    }
    for name, text in texts.items():
        (tmp_path / name).write_text(text)
    _empty_mcap(tmp_path / "empty.mcap")
    return {name: str(tmp_path / name) for name in [*texts, "empty.mcap"]}


@pytest.fixture(autouse=True)
def _logging_kept() -> Iterator[None]:
    """``serve`` points the ``railtwin`` loggers at stderr: put them back afterwards."""
    root, ours = logging.getLogger(), logging.getLogger("railtwin")
    kept = [(lg, list(lg.handlers), lg.level, lg.propagate) for lg in (root, ours)]
    yield
    for lg, handlers, level, propagate in kept:
        lg.handlers[:] = handlers
        lg.setLevel(level)
        lg.propagate = propagate


DIAGNOSE = ["diagnose", "--site", str(SITE)]
FEED_MEASURED = ["feed-measured", "--site-file", str(SITE), "--train", str(TRAIN)]
SYNTHESIZE = ["synthesize", "--site", str(SITE), "--passage", "{good_passage.json}"]
OUT = ["--out", "o.csv"]
REANALYSE = ["--site", str(SITE), "--out", "o"]

# (id, argv with {file} placeholders, exit status, what the line names besides the file)
CASES: list[tuple[str, list[str], int, tuple[str, ...]]] = [
    ("simulate-malformed", ["simulate", "{bad.json}"], 2, ("not valid JSON",)),
    (
        "calibrate-site-malformed",
        ["calibrate", "--site", "{bad.toml}", "--out", "o.toml", "."],
        2,
        ("not valid TOML",),
    ),
    (
        "calibrate-site-without-track",
        ["calibrate", "--site", str(SITE), "--out", "o.toml", "."],
        2,
        ("foundation.kind", "'compliant'"),
    ),
    ("simulate-invalid", ["simulate", "{scenario.json}"], 2, ("wheel.mass",)),
    (
        "diagnose-site-malformed",
        ["diagnose", "--site", "{bad.toml}", "--passage", "{passage.json}", "--measured", "x"],
        2,
        ("not valid TOML",),
    ),
    (
        "diagnose-passage-invalid",
        ["diagnose", "--site", str(SITE), "--passage", "{passage.json}", "--measured", "x"],
        2,
        ("invalid passage", "speed"),
    ),
    (
        "diagnose-measured-malformed",
        [*DIAGNOSE, "--passage", "{good_passage.json}", "--measured", "{bad.csv}"],
        2,
        ("header",),
    ),
    ("serve-site-malformed", ["serve", "--site", "{bad.toml}"], 2, ("not valid TOML",)),
    ("serve-site-invalid", ["serve", "--site", "{site.toml}"], 2, ("contact",)),
    (
        "serve-zenoh-malformed",
        ["serve", "--site", str(SITE), "--zenoh-config", "{bad.json}"],
        2,
        ("invalid Zenoh config", "line 1"),
    ),
    (
        "serve-zenoh-invalid",
        ["serve", "--site", str(SITE), "--zenoh-config", "{zenoh.json5}"],
        2,
        ("invalid Zenoh config", "bogus"),
    ),
    ("feed-train-malformed", ["feed", "--train", "{bad.json}"], 2, ("not valid JSON",)),
    (
        "feed-train-invalid",
        ["feed", "--train", "{train.json}"],
        2,
        ("invalid train", "wheels[3].passage.load"),
    ),
    (
        "feed-zenoh-malformed",
        ["feed", "--train", str(TRAIN), "--zenoh-config", "{bad.json}"],
        2,
        ("invalid Zenoh config",),
    ),
    ("feed-timeout", ["feed", "--timeout", "0"], 2, ("--timeout",)),
    (
        "feed-measured-site-malformed",
        ["feed-measured", "--site-file", "{bad.toml}"],
        2,
        ("not valid TOML",),
    ),
    (
        "feed-measured-site-invalid",
        ["feed-measured", "--site-file", "{site.toml}"],
        2,
        ("contact",),
    ),
    (
        "feed-measured-train-malformed",
        ["feed-measured", "--site-file", str(SITE), "--train", "{bad.json}"],
        2,
        ("not valid JSON",),
    ),
    (
        "feed-measured-load-malformed",
        [*FEED_MEASURED, "--load", "{bad.json}"],
        2,
        ("not valid JSON",),
    ),
    (
        "feed-measured-load-invalid",
        [*FEED_MEASURED, "--load", "{measured.json}"],
        2,
        ("invalid measurements", "[0].t_start"),
    ),
    (
        "feed-measured-axles",
        [*FEED_MEASURED, "--axles", "99"],
        2,
        ("--axles 99", "0..31"),
    ),
    (
        "synthesize-site-malformed",
        ["synthesize", "--site", "{bad.toml}", "--passage", "{good_passage.json}", *OUT],
        2,
        ("not valid TOML",),
    ),
    (
        "synthesize-passage-malformed",
        ["synthesize", "--site", str(SITE), "--passage", "{bad.json}", "--out", "o.csv"],
        2,
        ("not valid JSON",),
    ),
    (
        "synthesize-passage-invalid",
        ["synthesize", "--site", str(SITE), "--passage", "{passage.json}", "--out", "o.csv"],
        2,
        ("invalid passage", "speed"),
    ),
    (
        "synthesize-discrete-site-without-detector",
        [
            "synthesize",
            "--site",
            str(DATA / "site_discrete_no_detector.toml"),
            *SYNTHESIZE[3:],
            *OUT,
        ],
        2,
        ("invalid site", "foundation"),
    ),
    (
        "synthesize-length",
        [*SYNTHESIZE, "--flat", "flat", "--length", "2", *OUT],
        2,
        ("--length",),
    ),
    (
        "synthesize-noise",
        [*SYNTHESIZE, "--noise", "-1", *OUT],
        2,
        ("--noise",),
    ),
    ("replay-malformed", ["replay", "{bad.mcap}", "--dry-run"], 2, ("not an MCAP log",)),
    ("replay-invalid", ["replay", "{empty.mcap}", "--dry-run"], 2, ("no site's inputs",)),
    (
        "replay-zenoh-invalid",
        ["replay", "{empty.mcap}", "--zenoh-config", "{zenoh.json5}"],
        2,
        ("invalid Zenoh config",),
    ),
    ("recover-malformed", ["recover", "{bad.mcap}", "--out", "o.mcap"], 2, ("not an MCAP",)),
    (
        "recover-invalid",
        ["recover", "{empty.mcap}", "{run-inputs.journal}", "--out", "o.mcap"],
        2,
        ("not a railtwin input journal",),
    ),
    ("demo-site-malformed", ["demo", "--site", "{bad.toml}"], 2, ("not valid TOML",)),
    ("demo-train-invalid", ["demo", "--train", "{train.json}"], 2, ("wheels[3].passage.load",)),
    (
        "demo-recordings",
        ["demo", "--recordings", "{out_file}"],
        2,
        ("--recordings", "not a directory"),
    ),
    ("warm-site-malformed", ["warm", "--site", "{bad.toml}"], 2, ("not valid TOML",)),
    ("warm-site-invalid", ["warm", "--site", "{site.toml}"], 2, ("contact",)),
    ("warm-jobs", ["warm", "--jobs", "0"], 2, ("--jobs",)),
    ("router-zenoh-malformed", ["router", "--zenoh-config", "{bad.json}"], 2, ("line 1",)),
    ("router-zenoh-invalid", ["router", "--zenoh-config", "{zenoh.json5}"], 2, ("bogus",)),
    ("router-endpoint", ["router", "--listen", "nonsense"], 2, ("nonsense", "<protocol>")),
    (
        "fleet-serve-limits-malformed",
        ["fleet", "serve", "--limits", "{bad.toml}"],
        2,
        ("not valid TOML",),
    ),
    (
        "fleet-serve-limits-invalid",
        ["fleet", "serve", "--limits", "{limits.toml}"],
        2,
        ("diagnosis.inspect_force",),
    ),
    (
        "fleet-serve-zenoh-malformed",
        ["fleet", "serve", "--zenoh-config", "{bad.json}"],
        2,
        ("invalid Zenoh config",),
    ),
    (
        "fleet-serve-db-malformed",
        ["fleet", "serve", "--db", "{bad.json}", "--listen", "tcp/127.0.0.1:0"],
        2,
        ("--db", "not a SQLite database"),
    ),
    (
        "fleet-wheel-zenoh-malformed",
        ["fleet", "wheel", "V1/1/left", "--zenoh-config", "{bad.json}"],
        2,
        ("invalid Zenoh config",),
    ),
    ("fleet-wheel-id", ["fleet", "wheel", "V1/left"], 2, ("V1/left", "not a wheel id")),
    (
        "fleet-alarms-zenoh-invalid",
        ["fleet", "alarms", "--zenoh-config", "{zenoh.json5}"],
        2,
        ("bogus",),
    ),
    ("reanalyse-malformed", ["reanalyse", "{bad.mcap}", *REANALYSE], 2, ("not an MCAP log",)),
    ("reanalyse-invalid", ["reanalyse", "{empty.mcap}", *REANALYSE], 2, ("no site's inputs",)),
    (
        "reanalyse-site-invalid",
        ["reanalyse", "{empty.mcap}", "--site", "{site.toml}", "--out", "o"],
        2,
        ("contact",),
    ),
    ("study-malformed", ["study", "{bad.toml}", "--out", "o.parquet"], 2, ("not valid TOML",)),
    ("schema-name", ["schema", "Nope"], 2, ("no schema named 'Nope'",)),
    ("schema-out-file", ["schema", "--out", "{out_file}"], 1, ("cannot write",)),
    ("figures-out-file", ["figures", "--out", "{out_file}"], 1, ("cannot create",)),
]

NAMED_BY_FLAG = {"feed-timeout", "feed-measured-axles", "warm-jobs", "schema-name"}
"""Cases about a flag's value, not a file: the line names the flag instead."""


def _argv(template: list[str], files: dict[str, str]) -> tuple[list[str], list[str]]:
    """The command line, and the files it names in braces."""
    named = [a[1:-1] for a in template if a.startswith("{") and a.endswith("}")]
    return [files[a[1:-1]] if a[1:-1] in named else a for a in template], named


@pytest.mark.parametrize(
    ("argv", "code", "fragments"), [c[1:] for c in CASES], ids=[c[0] for c in CASES]
)
def test_bad_input_is_one_line_naming_the_file_and_field(
    argv: list[str],
    code: int,
    fragments: tuple[str, ...],
    files: dict[str, str],
    capsys: pytest.CaptureFixture[str],
    request: pytest.FixtureRequest,
) -> None:
    line, named = _argv(argv, files)
    got, out, err = run_main(line, capsys)
    assert (got, out) == (code, ""), err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    if request.node.callspec.id != "simulate-invalid":  # simulate: a line for each field
        assert len(lines) == 1, err
    assert f"railtwin {line[0]}: " in lines[0] or "railtwin.serve: " in lines[0], err
    for fragment in fragments:
        assert fragment in err, err
    bad = [n for n in named if n not in ("good_passage.json", "out_file", "empty.mcap")]
    if request.node.callspec.id not in NAMED_BY_FLAG and bad:
        assert any(Path(files[n]).name in err for n in bad), err


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """A parser's subcommands by name."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action._name_parser_map)
    return {}


def test_every_subcommand_is_tried() -> None:
    """Each command of ``railtwin --help`` (and each ``fleet`` command) has a case above."""
    choices = _subcommands(cli.build_parser(["--help"]))
    fleet = _subcommands(choices["fleet"])
    commands = {c for c in choices if c != "fleet"} | {f"fleet-{c}" for c in fleet}
    parts = [case[0].split("-") for case in CASES]
    tried = {"-".join(p[:k]) for p in parts for k in range(1, len(p) + 1)}
    assert commands <= tried, sorted(commands - tried)


def test_a_malformed_passage_via_subprocess(files: dict[str, str], cli: Callable[..., Any]) -> None:
    proc = cli("synthesize", "--site", str(SITE), "--passage", files["bad.json"], "--out", "o.csv")
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.splitlines() == [
        f"railtwin synthesize: {files['bad.json']} is not valid JSON: line 1 column 2: "
        "Expecting property name enclosed in double quotes"
    ]
