"""The MCAP log: schemas per channel, read back, flushed data survives a crash, rotation."""

from __future__ import annotations

import json
from pathlib import Path

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from schemas.messages import RejectedInput, ServiceError, WheelPassage, encoding_schema
from service.recording.mcap_log import McapLog, decode, read_log

PASSAGE = WheelPassage(
    passage_id="t1-a00-r", train_id="t1", axle_index=0, side="right", timestamp=1.7e9,
    speed=44.4, load=52000.0, mass=600.0, radius=0.46,
)


def test_channels_carry_their_json_schema(tmp_path: Path) -> None:
    log = McapLog(tmp_path, "run")
    data = PASSAGE.model_dump_json().encode()
    log.write("railtwin/s/passage", WheelPassage, data, 10)
    err = ServiceError(site_id="s", kind="invalid_json", message="m", field=None,
                       received_at=1.0).model_dump_json().encode()
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
        WheelPassage.model_json_schema())
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
    payload = RejectedInput(key="railtwin/s/passage", payload_base64="QUJD" * 200,
                            payload_text="x").model_dump_json().encode()
    for i in range(40):
        log.write("railtwin/s/passage/rejected", RejectedInput, payload, i)
        log.flush()
    log.close()
    assert len(log.files) > 1
    assert [m.log_time_ns for m in read_log(log.files)] == list(range(40))
