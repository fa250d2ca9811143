"""The MCAP log: schemas per channel, read back, flushed data survives a crash, rotation."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from schemas.messages import (
    PassageResult,
    RejectedInput,
    ServiceError,
    WheelPassage,
    encoding_schema,
)
from service.recording.mcap_log import LoggedMessage, McapLog, decode, read_log

PASSAGE = WheelPassage(
    passage_id="t1-a00-r",
    train_id="t1",
    axle_index=0,
    side="right",
    timestamp=1.7e9,
    speed=44.4,
    load=52000.0,
    mass=600.0,
    radius=0.46,
)


def test_channels_carry_their_json_schema(tmp_path: Path) -> None:
    log = McapLog(tmp_path, "run")
    data = PASSAGE.model_dump_json().encode()
    log.write("railtwin/s/passage", WheelPassage, data, 10)
    err = (
        ServiceError(site_id="s", kind="invalid_json", message="m", field=None, received_at=1.0)
        .model_dump_json()
        .encode()
    )
    log.write("railtwin/s/error", ServiceError, err, 20)
    log.close()
    with log.files[0].open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    schemas = {s.name: s for s in summary.schemas.values()}
    assert set(schemas) == {encoding_schema(WheelPassage), encoding_schema(ServiceError)}
    for s in schemas.values():
        assert s.encoding == "jsonschema"
    assert json.loads(schemas[encoding_schema(WheelPassage)].data) == (
        WheelPassage.model_json_schema()
    )
    assert {c.message_encoding for c in summary.channels.values()} == {"json"}
    messages = list(read_log(log.files))
    assert [m.topic for m in messages] == ["railtwin/s/passage", "railtwin/s/error"]
    assert messages[0].data == data
    assert decode(messages[0]) == PASSAGE


def test_flushed_messages_survive_a_crash(tmp_path: Path) -> None:
    log = McapLog(tmp_path, "crash")
    for i in range(5):
        log.write("railtwin/s/passage", WheelPassage, PASSAGE.model_dump_json().encode(), i)
    log.flush()  # then the process dies: no finish()
    path = log.files[0]
    records = []
    with path.open("rb") as f:
        try:
            for record in StreamReader(f, skip_magic=False).records:
                records.append(type(record).__name__)
        except Exception:  # the file ends mid-stream: expected
            pass
    assert records.count("Message") == 5
    log.close()


def test_rotation_by_size(tmp_path: Path) -> None:
    log = McapLog(tmp_path, "rot", max_bytes=2000, chunk_size=500)
    payload = (
        RejectedInput(key="railtwin/s/passage", payload_base64="QUJD" * 200, payload_text="x")
        .model_dump_json()
        .encode()
    )
    for i in range(40):
        log.write("railtwin/s/passage/rejected", RejectedInput, payload, i)
        log.flush()
    log.close()
    assert len(log.files) > 1
    assert [m.log_time_ns for m in read_log(log.files)] == list(range(40))


def test_errors_and_verdicts_also_go_to_a_foxglove_log_channel(tmp_path: Path) -> None:
    from service.recording import foxglove

    err = ServiceError(
        site_id="s",
        kind="simulation_failed",
        message="over budget",
        field=None,
        passage_id="p7",
        received_at=1.0,
    )
    entry = foxglove.log_entry("ServiceError", err.model_dump_json().encode(), 1_500_000_001)
    assert entry is not None
    assert (entry.timestamp.sec, entry.timestamp.nsec) == (1, 500_000_001)
    assert entry.level == foxglove.ERROR and "p7" in entry.message
    assert "over budget" in entry.message
    assert foxglove.log_entry("WheelPassage", PASSAGE.model_dump_json().encode(), 0) is None
    log = McapLog(tmp_path, "run")
    log.write(
        foxglove.log_topic("railtwin/s/error"),
        foxglove.Log,
        entry.model_dump_json().encode(),
        20,
        schema_name=foxglove.SCHEMA_NAME,
    )
    log.close()
    (m,) = list(read_log(log.files))
    assert m.topic == "railtwin/s/log" and m.schema_name == "foxglove.Log"
    logged = decode(m)
    assert isinstance(logged, foxglove.Log) and logged.level == foxglove.ERROR


def test_every_sample_of_a_result_is_plottable_against_time(tmp_path: Path) -> None:
    """Foxglove's Plot panel plots against the messages' time: one message per sample on
    ``.../samples``, at the sample's own time (log and publish time, ``timestamp`` field);
    the whole-passage result stays. Skipped while the recorder is behind."""
    from service.recording import foxglove
    from service.recording.recorder_process import ProcessRecorder, RecordingPlan
    from tests.test_service_rerun import result

    r = result("p1", n=40).model_copy(update={"timestamp": 1_780_000_000.25})
    data = r.model_dump_json().encode()
    for behind, name in ((64 * 2**20, "fed"), (0, "behind")):
        d = tmp_path / name
        rec = ProcessRecorder(
            RecordingPlan(d, "run", "s", rerun=False, samples_backlog_bytes=behind)
        )
        rec.message("railtwin/s/result", PassageResult, data, 1_780_000_009_000_000_000)
        rec.close()
        with sorted(d.glob("*.mcap"))[0].open("rb") as f:
            msgs = list(make_reader(f).iter_messages(log_time_order=False))
        results = [m for _, c, m in msgs if c.topic == "railtwin/s/result"]
        assert len(results) == 1 and results[0].data == data
        rows = [(s, m) for s, c, m in msgs if c.topic == "railtwin/s/samples"]
        if behind == 0:
            assert rows == [] and rec.not_sampled == 1
            continue
        assert len(rows) == 40 and rec.not_sampled == 0
        want = [round((r.timestamp + x / r.speed) * 1e9) for x in r.x]
        assert [m.log_time for _, m in rows] == want
        assert [m.publish_time for _, m in rows] == want
        assert {s.name for s, _ in rows} == {foxglove.SAMPLE_SCHEMA_NAME}
        got = [
            decode(LoggedMessage("railtwin/s/samples", s.name, m.log_time, m.data)) for s, m in rows
        ]
        assert all(isinstance(g, foxglove.PassageSample) for g in got)
        for name in ("force", "indentation", "x"):  # 7 significant digits: a plot's precision
            np.testing.assert_allclose(
                [getattr(g, name) for g in got], getattr(r, name), rtol=1e-6, atol=0
            )
        assert {g.passage_id for g in got} == {"p1"}
        assert [g.timestamp.sec * 10**9 + g.timestamp.nsec for g in got] == want
