"""The recorder child's queue is bounded in bytes: Rerun drawings give way, MCAP waits."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from schemas.messages import PassageResult
from service.recording.mcap_log import read_log
from service.recording.recorder_process import ProcessRecorder, RecordingPlan
from service.recording.rerun_recording import entities
from tests.test_service_rerun import result, rrd_columns, rrd_texts

TOPIC = "railtwin/s/result"


def run(plan: RecordingPlan, n: int) -> tuple[ProcessRecorder, list[PassageResult]]:
    """``n`` results queued at once (MCAP message and Rerun drawing), then closed."""
    rec = ProcessRecorder(plan)
    results = [result(f"p{i}", n=2000) for i in range(n)]
    for i, r in enumerate(results):
        data = r.model_dump_json().encode()
        rec.message(TOPIC, PassageResult, data, 1_000 + i)
        rec.passage(r, data)
    rec.close()
    return rec, results


def test_past_the_drawing_limit_passages_are_logged_not_drawn(tmp_path: Path) -> None:
    plan = RecordingPlan(tmp_path, "run", "s", rerun_backlog_bytes=0)
    rec, results = run(plan, 5)
    assert rec.not_drawn == 5 and rec.pending_bytes() == 0
    assert rec.failures == 1 and rec.last_failure is not None
    assert "5 passages, dents or diagnoses not drawn" in rec.last_failure
    assert plan.rrd_path is not None
    assert entities("s")["force"] not in rrd_columns(plan.rrd_path)
    lines = rrd_texts(plan.rrd_path)[entities("s")["passages"]]
    assert [(i, text.split(":")[0]) for i, text in lines] == [
        (i, f"#{i} {r.passage_id}") for i, r in enumerate(results)
    ]
    assert all("not drawn" in text for _, text in lines)
    logged = [
        PassageResult.model_validate_json(m.data).passage_id
        for m in read_log(sorted(tmp_path.glob("*.mcap")))
        if m.topic == TOPIC
    ]
    assert sorted(logged) == sorted(r.passage_id for r in results)  # the log has them all


def test_past_the_log_limit_messages_wait_and_none_is_lost(tmp_path: Path) -> None:
    plan = replace(RecordingPlan(tmp_path, "run", "s"), mcap_backlog_bytes=1, rerun=False)
    rec, results = run(plan, 20)  # each message waits until the child has written the last
    assert rec.failures == 0 and rec.not_drawn == 0 and rec.pending_bytes() == 0
    logged = [
        PassageResult.model_validate_json(m.data)
        for m in read_log(sorted(tmp_path.glob("*.mcap")))
        if m.topic == TOPIC
    ]
    assert [r.passage_id for r in logged] == [r.passage_id for r in results]
