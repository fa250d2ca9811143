"""Channels in, everywhere (issue 26, item 1): a measured passage of a detector's crib
channels in the contract, read from a CSV, checked against the site's cribs by
``railtwin diagnose``, ``railtwin feed-measured`` and the twin's pairing: ids that are not
the site's cribs are refused clearly, valid channels go on to the diagnosis
(``tests/test_diagnosis_channels.py`` has the fit itself).

Fast: no track simulation runs here (the twin runs the stand-in ``StubPhysics``; the
command's round wheel is dismissed by the screen). The real channel
record is site S01's passage P01 of the handed-over ``track-sites`` data
(``tests/data/track-sites/README.md``).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from pydantic import ValidationError

from schemas.diagnosis import MAX_MEASURED_SAMPLES, MeasuredPassage
from schemas.messages import MESSAGE_SCHEMA_VERSION, Health, ServiceError, WheelPassage
from schemas.site import SiteConfig
from service.cli.main import main as cli_main
from service.clients.measured_io import MeasuredFileError, read_measured, read_measured_csv
from service.physics.local import LocalPhysics
from service.physics.port import DiagnosisOutcome, MeasurementError
from service.physics.stub import StubPhysics
from service.recording.mcap_log import read_log
from service.recording.recorder_process import ProcessRecorder, RecordingPlan
from service.twin.twin import Twin
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.measured_channels import channel_mismatch, channels_mismatch
from service.wire.site import load_site
from service.wire.zenoh_session import build_config, free_tcp_endpoint
from tests import test_service_channels as detector_site

DATA = Path(__file__).parent / "data" / "track-sites"
SITE = DATA / "S01.site.toml"
CSV = DATA / "S01_P01.csv"
PASSAGE = DATA / "S01_P01.passage.json"
CRIBS = [f"ch{i}" for i in range(1, 9)]


def channels(ids: list[str], n: int = 32) -> dict[str, list[float]]:
    return {c: [float(k + i) for k in range(n)] for i, c in enumerate(ids)}


def measured(**fields: Any) -> MeasuredPassage:
    return MeasuredPassage.model_validate(
        {"passage_id": "p1", "sample_rate": 1e4, "t_start": 0.0, **fields}
    )


def write_csv(path: Path, ids: list[str], n: int = 40, rate: float = 1e4, t0: float = 0.0) -> Path:
    rows = [",".join(["t_s", *ids])]
    rows += [
        ",".join([f"{t0 + k / rate:.6f}", *(f"{1000.0 * (k + i):.2f}" for i in range(len(ids)))])
        for k in range(n)
    ]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


# -- the contract -------------------------------------------------------------------------


def test_a_measured_passage_carries_channels_or_force_and_the_version_is_1_4() -> None:
    m = measured(channels=channels(["ch1", "ch2"]))
    assert m.force is None and m.channel_ids == ("ch1", "ch2")
    assert m.samples == 32 and m.duration == pytest.approx(31e-4)
    assert MeasuredPassage.model_validate_json(m.model_dump_json()) == m
    assert MESSAGE_SCHEMA_VERSION == "1.5" and m.schema_version == "1.5"
    f = measured(force=[6e4] * 20)  # the contact-force sensor keeps working
    assert f.channels is None and f.samples == 20 and f.channel_ids == ()
    # a 1.3 producer's force measurement (no channels key) still reads
    old = '{"schema_version": "1.3", "passage_id": "p", "sample_rate": 1e4, "t_start": 0,'
    assert MeasuredPassage.model_validate_json(old + '"force": ' + str([1.0] * 16) + "}").samples


@pytest.mark.parametrize(
    ("fields", "where", "fragment"),
    [
        ({}, "force", "exactly one of force"),
        ({"force": [1.0] * 16, "channels": channels(["a"])}, "force", "exactly one of force"),
        ({"channels": {}}, "channels", "1 to 32"),
        ({"channels": channels([f"c{i}" for i in range(33)])}, "channels", "1 to 32"),
        ({"channels": {"a": [1.0] * 16, "b": [1.0] * 17}}, "channels.b", "same samples"),
        ({"channels": channels(["a"], n=15)}, "channels.a", "at least 16"),
        ({"channels": {"a/b": [1.0] * 16}}, "channels.a/b", "pattern"),
        ({"channels": {"a": [1.0] * 15 + [float("nan")]}}, "channels.a.15", "finite"),
        (
            {"channels": channels(["a", "b"], n=MAX_MEASURED_SAMPLES // 2 + 1)},
            "channels",
            "values in all",
        ),
    ],
)
def test_bad_channels_are_refused_naming_the_field(
    fields: dict[str, Any], where: str, fragment: str
) -> None:
    with pytest.raises(ValidationError) as info:
        measured(**fields)
    e = info.value.errors()[0]
    path = ".".join(map(str, e["loc"])) or str((e.get("ctx") or {}).get("field"))
    assert path.startswith(where), e
    assert fragment in e["msg"], e["msg"]


def test_channel_ids_must_be_exactly_the_sites_cribs() -> None:
    site = load_site(SITE)
    assert channels_mismatch(measured(channels=channels(CRIBS)), site) is None
    assert channels_mismatch(measured(channels=channels(CRIBS[::-1])), site) is None  # any order
    assert channels_mismatch(measured(force=[1.0] * 16), site) is None
    bad = channels_mismatch(measured(channels=channels([*CRIBS[:6], "ch9", "x"])), site)
    assert bad is not None and "missing ch7, ch8; extra ch9, x" in bad
    assert "ch1, ch2, ch3, ch4, ch5, ch6, ch7, ch8" in bad
    assert channel_mismatch(["ch1"], ()) is not None
    assert "no detector" in (channel_mismatch(["ch1"], ()) or "")


# -- the measured CSV ---------------------------------------------------------------------


def test_the_handed_over_channel_csv_is_read_at_the_sites_rate() -> None:
    site = load_site(SITE)
    m = read_measured(CSV, "S01_P01", sample_rate=site.diagnosis.sample_rate)
    assert m.channel_ids == tuple(CRIBS) and m.force is None
    assert m.sample_rate == 1e4 and m.t_start == 0.0 and m.samples == 2167
    raw = np.loadtxt(CSV, delimiter=",", skiprows=1)
    assert np.array_equal(np.asarray(m.channels["ch5"]), raw[:, 5])  # type: ignore[index]
    assert channels_mismatch(m, site) is None
    assert read_measured_csv(CSV, "x").sample_rate == pytest.approx(1e4)  # no rate given


def test_a_force_csv_reads_as_before(tmp_path: Path) -> None:
    p = write_csv(tmp_path / "f.csv", ["force_N"], n=20, rate=2e4, t0=-0.001)
    m = read_measured_csv(p, "p1", speed=30.0, sample_rate=2e4)
    assert m.channels is None and m.samples == 20 and m.t_start == pytest.approx(-0.001)
    assert m.force is not None and m.force[3] == 3000.0 and m.speed == 30.0


def _edited(path: Path, line: int, text: str) -> Path:
    lines = path.read_text(encoding="utf-8").splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("line", "text", "fragment"),
    [
        (1, "time,ch1,ch2", "line 1: header must be 't_s,force_N'"),
        (1, "t_s", "line 1: header must be"),
        (1, "t_s,ch1,ch1", "line 1, column 3: crib id 'ch1' repeated"),
        (1, "t_s,ch1,c/2", "line 1, column 3: 'c/2' is not a crib id"),
        (1, "t_s,force_N,ch2", "line 1, column 2: 'force_N' is the contact force's only"),
        (7, "0.000500,1.0", "line 7: expected 3 values (t_s,ch1,ch2), got 2"),
        (7, "0.000500,1.0,2.0,3.0", "line 7: expected 3 values"),
        (9, "0.000700,,2.0", "line 9, column 2 (ch1): not a number: ''"),
        (9, "0.000700,1.0,abc", "line 9, column 3 (ch2): not a number: 'abc'"),
        (12, "0.001000,1.0,nan", "line 12, column 3 (ch2): must be finite, got 'nan'"),
        (12, "inf,1.0,2.0", "line 12, column 1 (t_s): must be finite"),
        (12, "0.000900,1.0,2.0", "line 12, column 1 (t_s): time must increase"),
        (12, "0.001050,1.0,2.0", "line 12, column 1 (t_s): 0.00105 s is 0.00015 s after"),
    ],
)
def test_a_bad_csv_is_refused_naming_file_line_and_column(
    tmp_path: Path, line: int, text: str, fragment: str
) -> None:
    p = _edited(write_csv(tmp_path / "m.csv", ["ch1", "ch2"], n=40), line, text)
    with pytest.raises(MeasuredFileError) as info:
        read_measured_csv(p, "p1")
    msg = str(info.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    assert fragment in msg, msg


def test_time_must_keep_the_sites_sample_rate(tmp_path: Path) -> None:
    p = write_csv(tmp_path / "m.csv", CRIBS, n=40, rate=2e4)
    with pytest.raises(MeasuredFileError, match=r"line 3, column 1 \(t_s\): .*site's sample rate"):
        read_measured_csv(p, "p1", sample_rate=1e4)
    assert read_measured_csv(p, "p1", sample_rate=2e4).sample_rate == 2e4


def test_a_short_or_empty_csv_is_refused(tmp_path: Path) -> None:
    with pytest.raises(MeasuredFileError, match="15 samples, at least 16"):
        read_measured_csv(write_csv(tmp_path / "s.csv", ["ch1"], n=15), "p1")
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(MeasuredFileError, match="line 1: header"):
        read_measured_csv(tmp_path / "e.csv", "p1")
    with pytest.raises(MeasuredFileError, match="passage_id"):
        read_measured_csv(write_csv(tmp_path / "b.csv", ["ch1"], n=16), "not/an id")


def test_the_diagnoser_refuses_channels_before_any_fit() -> None:
    """The library path (re-analysis, workers) refuses as the CLI and the twin do."""
    from service.physics.diagnosis import Diagnoser  # the physics, imported, not run

    compliant = load_site(Path(__file__).parents[1] / "examples" / "site_compliant.toml")
    p = WheelPassage.model_validate_json(PASSAGE.read_text(encoding="utf-8"))
    m = measured(passage_id=p.passage_id, channels=channels(CRIBS, n=2000))
    with pytest.raises(MeasurementError) as info:
        Diagnoser(compliant).diagnose(p, m)
    assert info.value.field == "channels" and "no detector" in info.value.message


# -- railtwin diagnose --------------------------------------------------------------------


def diagnose(tmp_path: Path, csv: Path, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    out = tmp_path / "d.json"
    files = ["--site", str(SITE), "--passage", str(PASSAGE), "--measured", str(csv)]
    code = cli_main(["diagnose", *files, "--out", str(out)])
    assert not out.exists()  # never a diagnosis
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return code, err[0]


def test_diagnose_diagnoses_a_round_wheel_from_its_channels(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "d.json"
    files = ["--site", str(SITE), "--passage", str(PASSAGE), "--measured", str(CSV)]
    assert cli_main(["diagnose", *files, "--out", str(out), "--format", "json"]) == 0
    d = json.loads(out.read_text())
    assert d["measured"] == "channels" and d["flat"] is None and d["verdict"] == "ok"
    assert d["calibration"]["source"] == "nominal"


def test_diagnose_names_the_missing_and_extra_channels(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    csv = write_csv(tmp_path / "m.csv", [*CRIBS[:7], "ch9"], n=40)
    code, err = diagnose(tmp_path, csv, capsys)
    assert code == 2 and "channels: " in err and "missing ch8; extra ch9" in err
    csv = write_csv(tmp_path / "w.csv", CRIBS, n=40, rate=2e4)  # not the site's 10 kHz
    code, err = diagnose(tmp_path, csv, capsys)
    assert code == 2 and "line 3, column 1 (t_s)" in err and "sample rate 10000 Hz" in err


# -- railtwin feed-measured ---------------------------------------------------------------


def feed(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """``railtwin feed-measured`` at site S01 towards a port nobody listens on: whatever it
    refuses, it refuses before opening Zenoh."""
    train = Path(__file__).parents[1] / "recordings" / "samples" / "train_160kmh.json"
    files = ["--site-file", str(SITE), "--train", str(train)]
    code = cli_main(
        ["feed-measured", *files, "--timeout", "1", "--connect", "tcp/127.0.0.1:9", *args]
    )
    err = capsys.readouterr().err.strip().splitlines()
    return code, err[-1] if err else ""


def test_feed_measured_refuses_channels_that_are_not_the_sites_cribs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    csv = write_csv(tmp_path / "t1-a0-r.csv", ["ch1", "ch2"], n=40)
    code, err = feed(["--measured", str(csv)], capsys)
    assert code == 2, err
    assert "measurement of t1-a0-r: channels:" in err and "missing ch3, ch4" in err
    saved = tmp_path / "m.json"
    m = measured(passage_id="t1-a0-r", channels=channels([*CRIBS, "ch9"]))
    saved.write_text(json.dumps([m.model_dump(mode="json")]))
    code, err = feed(["--load", str(saved)], capsys)
    assert code == 2 and f"invalid measurement in {saved}" in err and "extra ch9" in err
    bad = write_csv(tmp_path / "t1-a1-r.csv", CRIBS, n=40)
    _edited(bad, 5, "0.000300,1,2")
    code, err = feed(["--measured", str(bad)], capsys)
    assert code == 2 and f"{bad}: line 5: expected 9 values" in err


# -- the twin's pairing -------------------------------------------------------------------


class Answers:
    """What the twin publishes for a client: results and errors, by passage id."""

    PROBE = "probe"

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.results: list[str] = []
        self.errors: list[ServiceError] = []
        self.probes = 0

    def __call__(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        with self.lock:
            if "/result/" in key:
                self.results.append(key.rsplit("/", 1)[1])
            elif key.endswith("/error"):
                e = ServiceError.model_validate_json(sample.payload.to_bytes())
                if e.passage_id == self.PROBE:
                    self.probes += 1
                else:
                    self.errors.append(e)

    def wait(self, results: int, errors: int, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if len(self.results) >= results and len(self.errors) >= errors:
                    return
            time.sleep(0.02)
        raise AssertionError(f"timed out: {self.results}, {self.errors}")


@pytest.fixture
def twin_answers(tmp_path: Path) -> Iterator[tuple[Answers, list[str], Health]]:
    """The twin of a 2-crib site (``ch1``, ``ch2``) on the stand-in physics, whose diagnoses
    are a spy: fed a passage and its contact-force measurement between two channel
    measurements (wrong ids, right ids). Yields the answers, the passage ids the spy was
    asked to diagnose, and the twin's health after."""
    config: SiteConfig = detector_site.site()
    keys = SiteKeys(config.site_id)
    asked: list[str] = []

    def spy(passage: WheelPassage, m: MeasuredPassage) -> DiagnosisOutcome:
        asked.append(m.passage_id)
        raise MeasurementError("force", "the spy does not diagnose")

    endpoint = free_tcp_endpoint()
    answers = Answers()
    recorder = ProcessRecorder(
        RecordingPlan(tmp_path, "run", config.site_id, flush_interval=0.05, cribs=("ch1", "ch2"))
    )
    with (
        zenoh.open(build_config(listen=[endpoint])) as server,
        zenoh.open(build_config(connect=[endpoint])) as client,
    ):
        twin = Twin(config, server, LocalPhysics(StubPhysics(config), spy), recorder=recorder)
        twin.start()
        try:
            sub = client.declare_subscriber(keys.all_outputs, answers)
            ppub = client.declare_publisher(keys.passage, encoding=json_encoding(WheelPassage))
            mpub = client.declare_publisher(keys.measured, encoding=json_encoding(MeasuredPassage))
            deadline = time.monotonic() + 20
            while not (ppub.matching_status.matching and mpub.matching_status.matching):  # type: ignore[attr-defined]
                assert time.monotonic() < deadline, "the twin did not subscribe"
                time.sleep(0.02)
            # the twin hears us, but do its answers reach us yet? probe until one has come
            while not answers.probes:
                assert time.monotonic() < deadline, "the twin's answers never reached us"
                ppub.put(json.dumps({"passage_id": Answers.PROBE}))
                time.sleep(0.2)
            ppub.put(detector_site.passage("p0").model_dump_json())
            wrong = measured(passage_id="p1", channels=channels(["ch1", "ch3"], n=64))
            right = measured(passage_id="p2", channels=channels(["ch2", "ch1"], n=64))
            force = measured(passage_id="p3", force=[6e4] * 64)
            mpub.put(wrong.model_dump_json())
            ppub.put(detector_site.passage("p3").model_dump_json())
            mpub.put(force.model_dump_json())
            mpub.put(right.model_dump_json())
            ppub.put(detector_site.passage("p2").model_dump_json())
            answers.wait(results=3, errors=3)
            time.sleep(0.1)  # and nothing more
            (reply,) = [r for r in client.get(keys.health, timeout=5.0) if r.ok]
            health = Health.model_validate_json(reply.ok.payload.to_bytes())
            sub.undeclare()
        finally:
            twin.stop()
            recorder.close()
    yield answers, asked, health


def test_the_twin_rejects_channels_clearly_and_loses_nothing_else(
    twin_answers: tuple[Answers, list[str], Health], tmp_path: Path
) -> None:
    answers, asked, health = twin_answers
    by_id = {e.passage_id: e for e in answers.errors}
    assert sorted(by_id) == ["p1", "p2", "p3"]
    wrong, right = by_id["p1"], by_id["p2"]
    assert wrong.kind == right.kind == "invalid_measurement"
    assert wrong.field == "channels" and right.field == "force"  # the spy's field
    assert wrong.message == (
        "measurement of p1 rejected: channels: the ids must be the site's detector cribs "
        "ch1, ch2: missing ch2; extra ch3"
    )
    # the valid channels and the contact force went on to the diagnosis (the spy's error),
    # and the passages were served
    assert asked == ["p3", "p2"]
    assert "the spy does not diagnose" in by_id["p3"].message
    assert "the spy does not diagnose" in right.message
    assert sorted(answers.results) == ["p0", "p2", "p3"]
    assert health.errors == 3 + answers.probes and health.passages_done == 3
    logged = [m for m in read_log(sorted(tmp_path.glob("*.mcap")))]
    measured_logged = [
        MeasuredPassage.model_validate_json(m.data).passage_id
        for m in logged
        if m.topic == "railtwin/s/measured"
    ]
    assert sorted(measured_logged) == ["p1", "p2", "p3"]
    errors_logged = [m for m in logged if m.topic == "railtwin/s/error"]
    assert len(errors_logged) == 3 + answers.probes
