"""The twin calibrates online in its worker processes and keeps the calibration across a
restart (``service.physics.worker`` with ``OnlineSetting``), on a round wheel of the
independent solver's S02 (``tests/data/calibration``: a slab whose nominal pad is 1.27 x too
stiff). Real worker processes; the new track's reduction is made once per machine (seconds,
then from the track store)."""

from __future__ import annotations

import dataclasses
import gzip
import json
import math
import shutil
import time
from pathlib import Path

import pytest

from schemas.calibration import OnlineCalibrationState
from schemas.diagnosis import MeasuredPassage
from schemas.messages import Health, WheelPassage
from service.clients.measured_io import read_measured_csv
from service.physics.local import LocalPhysics
from service.physics.port import DiagnosisOutcome
from service.physics.stub import StubPhysics
from service.physics.worker import OnlineSetting, ProcessPhysics
from service.twin.inbound import Inbound
from service.twin.twin import Twin
from service.wire.site import load_site
from tests.test_fuzz_inputs import GOOD_PASSAGE, RecordingSession
from tests.test_fuzz_inputs import SITE as FUZZ
from tests.test_network import measured as measured_force
from tests.test_network import stand_in_diagnoser

DATA = Path(__file__).parent / "data" / "calibration"
SITE = load_site(DATA / "S02.site.toml")
HOUR = 3600.0  # the rate limit: one calibration wheel in the test, whatever its duration


def _wheel(tmp_path: Path, name: str = "S02_P11") -> tuple[WheelPassage, MeasuredPassage]:
    passage = WheelPassage.model_validate_json((DATA / f"{name}.json").read_text())
    csv = tmp_path / f"{name}.csv"
    with gzip.open(DATA / f"{name}.csv.gz", "rb") as src, csv.open("wb") as dst:
        shutil.copyfileobj(src, dst)
    return passage, read_measured_csv(csv, passage.passage_id, sample_rate=1e4)


def test_the_twin_calibrates_online_and_reads_it_back_after_a_restart(tmp_path: Path) -> None:
    passage, measured = _wheel(tmp_path)
    state = tmp_path / "state"
    path = state / f"{SITE.site_id}.calibration.json"
    w = ProcessPhysics(SITE, warm_up=False, calibration=OnlineSetting(state, HOUR))
    w.start()
    try:
        first = w.diagnose(passage, measured)  # the verdict goes out before the learning
        second = w.diagnose(passage, measured)  # on the calibration the first wheel moved
    finally:
        w.close()
    assert first.diagnosis.flat is None and first.diagnosis.calibration is not None
    assert first.diagnosis.calibration.source == "nominal"
    assert first.calibration is not None and "after 0 wheels" in first.calibration
    kept = OnlineCalibrationState.model_validate_json(path.read_text())
    assert kept.wheels == 1 and len(kept.history) == 1  # the second: within the rate limit
    step = kept.history[0]
    assert step.passage_id == passage.passage_id
    assert step.applied[0] == -0.01  # a softer pad, by the per-wheel limit (1 %)
    online = second.diagnosis.calibration
    assert second.diagnosis.flat is None and online is not None
    assert online.source == "online" and online.wheels == 1
    assert second.calibration is not None
    assert "after 1 wheels" in second.calibration and "pad.stiffness x0.990" in second.calibration
    assert w.calibration_line == second.calibration

    again = ProcessPhysics(SITE, warm_up=False, calibration=OnlineSetting(state, HOUR))
    again.start()  # a restarted twin
    try:
        third = again.diagnose(passage, measured)
    finally:
        again.close()
    ref = third.diagnosis.calibration
    assert ref is not None and ref.source == "online"
    assert ref.id == online.id and ref.wheels == 1
    assert OnlineCalibrationState.model_validate_json(path.read_text()) == kept
    assert step.factors[0] == pytest.approx(math.exp(-0.01), rel=1e-12)


def test_a_failing_calibration_loses_neither_the_diagnosis_nor_the_worker(
    tmp_path: Path,
) -> None:
    passage, measured = _wheel(tmp_path)
    blocked = tmp_path / "not-a-dir"
    blocked.write_text("a file where the state dir should be")
    w = ProcessPhysics(SITE, warm_up=False, calibration=OnlineSetting(blocked, 0.0))
    w.start()
    try:
        pid = w.pid
        outs = [w.diagnose(passage, measured) for _ in range(2)]  # each learning fails
        assert w.pid == pid and w.restarts == 0
    finally:
        w.close()
    for out in outs:
        ref = out.diagnosis.calibration
        assert out.diagnosis.flat is None and ref is not None and ref.source == "nominal"


def test_the_health_reports_the_drift_the_last_diagnosis_used() -> None:
    line = "calibration after 1 wheels: pad.stiffness x0.990 (-1.0 % in 1)"

    def diagnose(p: WheelPassage, m: MeasuredPassage) -> DiagnosisOutcome:
        return dataclasses.replace(stand_in_diagnoser(FUZZ.site_id, p, m), calibration=line)

    twin = Twin(FUZZ, RecordingSession(), LocalPhysics(StubPhysics(FUZZ), diagnose=diagnose))  # type: ignore[arg-type]
    assert twin.health().calibration is None  # before any diagnosis
    pid = GOOD_PASSAGE["passage_id"]
    for key, payload in (
        (twin.keys.passage, json.dumps(GOOD_PASSAGE).encode()),
        (twin.keys.measured, measured_force(pid).model_dump_json().encode()),
    ):
        twin.serve(Inbound(key, payload, time.time_ns(), time.monotonic()))
    assert twin.pairing.done == 1
    health = Health.model_validate_json(twin.health().model_dump_json())
    assert health.calibration == line
