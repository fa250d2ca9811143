"""``railtwin recover``: logs cut by a crash lose nothing that was flushed."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mcap.reader import make_reader

from schemas.messages import RejectedInput, ServiceError, encoding_schema
from service.cli.main import main as cli_main
from service.recording.mcap_log import McapLog
from service.recording.mcap_recover import read_any, salvage


def _log(tmp_path: Path, n: int, flush_every: int) -> tuple[Path, list[int]]:
    """A log of n messages flushed every ``flush_every``; file sizes after each flush."""
    log = McapLog(tmp_path, "run", chunk_size=1 << 20)
    sizes = []
    for i in range(n):
        log.write(
            "railtwin/x/passage/rejected", RejectedInput, json.dumps({"i": i}).encode(), 1_000 + i
        )
        if i % flush_every == flush_every - 1:
            log.flush()
            assert log._file is not None
            log._file.flush()
            sizes.append(log._file.tell())
    path = log.files[0]
    assert log._file is not None
    log._file.flush()
    return path, sizes


@pytest.mark.parametrize("cut_after_flush", [0, 3, 9])
def test_everything_flushed_before_the_cut_is_recovered(
    tmp_path: Path, cut_after_flush: int
) -> None:
    path, sizes = _log(tmp_path, 100, 10)
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: sizes[cut_after_flush] + 17])  # a torn record after the flush
    with cut.open("rb") as f, pytest.raises(Exception):  # noqa: B017 - any reader error
        list(make_reader(f).iter_messages())
    kept = [json.loads(m.data)["i"] for m in salvage(cut)]
    assert kept == list(range(10 * (cut_after_flush + 1)))
    out = tmp_path / "fixed.mcap"
    assert cli_main(["recover", str(cut), "--out", str(out)]) == 0
    with out.open("rb") as f:
        msgs = [json.loads(m.data)["i"] for _, _, m in make_reader(f).iter_messages()]
    assert msgs == kept
    assert [json.loads(m.data)["i"] for m in read_any([out])] == kept


def test_recover_refuses_to_overwrite_its_input(tmp_path: Path) -> None:
    path, _ = _log(tmp_path, 10, 5)
    assert cli_main(["recover", str(path), "--out", str(path)]) == 2
    assert (
        cli_main(["recover", str(tmp_path / "missing.mcap"), "--out", str(tmp_path / "o.mcap")])
        == 2
    )


def test_the_journal_adds_back_the_inputs_the_recorder_never_wrote(tmp_path: Path) -> None:
    """kill -9 of every process: the MCAP lost its last inputs, the journal has them all."""
    from schemas.messages import WheelPassage
    from service.recording.input_journal import InputJournal

    good = WheelPassage(
        passage_id="p0",
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=30.0,
        load=5e4,
        mass=500.0,
        radius=0.46,
    )
    key = "railtwin/x/passage"
    payloads = [
        good.model_copy(update={"passage_id": f"p{i}"}).model_dump_json().encode() for i in range(6)
    ] + [b"not json"]
    journal = InputJournal(tmp_path / "run-inputs.journal")
    log = McapLog(tmp_path, "run")
    for i, data in enumerate(payloads):
        journal.append(key, 1_000 + i, data)
        if i < 3:  # the recorder wrote only the first three before the crash
            log.write(key, WheelPassage, data, 1_000 + i)
    log.flush()
    journal.close()
    with (tmp_path / "run-inputs.journal").open("ab") as f:
        f.write(b"RTJ1\x05\x00")  # a record torn by the kill
    out = tmp_path / "fixed.mcap"
    code = cli_main(
        ["recover", str(log.files[0]), str(tmp_path / "run-inputs.journal"), "--out", str(out)]
    )
    assert code == 0
    with out.open("rb") as f:
        got = [(c.topic, m.log_time) for _, c, m in make_reader(f).iter_messages()]
    assert got == [(key, 1_000 + i) for i in range(6)] + [(f"{key}/rejected", 1_006)]


def test_the_journal_adds_back_answers_the_recorder_never_wrote(tmp_path: Path) -> None:
    from service.recording.input_journal import InputJournal

    err = (
        ServiceError(site_id="x", kind="invalid_passage", message="m", field=None, received_at=1.0)
        .model_dump_json()
        .encode()
    )
    journal = InputJournal(tmp_path / "run-inputs.journal")
    journal.append("railtwin/x/error", 2_000, err)  # published, never logged by the recorder
    journal.close()
    log = McapLog(tmp_path, "run")
    log.write("railtwin/x/passage/rejected", RejectedInput, b'{"i": 0}', 1_000)
    log.flush()
    out = tmp_path / "fixed.mcap"
    assert (
        cli_main(
            ["recover", str(log.files[0]), str(tmp_path / "run-inputs.journal"), "--out", str(out)]
        )
        == 0
    )
    with out.open("rb") as f:
        got = [(s.name, c.topic, m.data) for s, c, m in make_reader(f).iter_messages()]
    assert got[-1] == (encoding_schema(ServiceError), "railtwin/x/error", err)
