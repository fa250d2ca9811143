"""The journal holds only what the MCAP does not: its parts go once their records are in a
flushed chunk, and a kill -9 at any moment still loses no record (``railtwin recover``)."""

from __future__ import annotations

import base64
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path

from schemas.messages import RejectedInput
from service.recording.input_journal import InputJournal
from service.recording.mcap_log import read_log
from service.recording.mcap_recover import recover
from service.recording.recorder_process import ProcessRecorder, RecordingPlan

KEY = "railtwin/s/passage"


def record(i: int) -> bytes:
    """The i-th input: not a WheelPassage, so it is logged as a ``RejectedInput``."""
    return b"input %05d " % i + b"x" * 200


def feed(journal: InputJournal, rec: ProcessRecorder, first: int, n: int) -> None:
    """As the twin does: on disk in the journal first, then to the recorder with the ticket."""
    for i in range(first, first + n):
        raw = record(i)
        ticket = journal.append(KEY, 1_000 + i, raw)
        logged = RejectedInput(
            key=KEY, payload_base64=base64.b64encode(raw).decode(), payload_text=raw.decode()
        )
        rec.message(
            f"{KEY}/rejected",
            RejectedInput,
            logged.model_dump_json().encode(),
            1_000 + i,
            None,
            ticket,
        )


def wait_until(cond: Callable[[], bool], what: str, timeout: float = 60.0) -> None:
    """Poll ``cond`` (a callable); a generous time-out only turns a hang into a failure."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"still waiting for: {what}"
        time.sleep(0.02)


def kill_child(rec: ProcessRecorder) -> None:
    pid = rec._process.pid
    assert pid is not None
    os.kill(pid, signal.SIGKILL)
    rec._process.join(10)


def recovered_inputs(tmp_path: Path) -> list[int]:
    """The log times of the inputs in the log ``railtwin recover`` writes from what is left."""
    paths = sorted(tmp_path.glob("run-*.mcap")) + sorted(tmp_path.glob("*.journal"))
    out = tmp_path / "fixed.mcap"
    recover(paths, out)
    return sorted(m.log_time_ns - 1_000 for m in read_log([out]))


def test_parts_go_once_flushed_the_journal_stays_bounded_and_ends_empty(tmp_path: Path) -> None:
    part = 4_000
    journal = InputJournal(tmp_path / "run-inputs.journal", part_bytes=part)
    rec = ProcessRecorder(
        RecordingPlan(tmp_path, "run", "s", rerun=False, flush_interval=0.05), journal=journal
    )
    biggest = 0
    for batch in range(10):
        feed(journal, rec, batch * 40, 40)  # ~10 kB a batch: 3 parts
        wait_until(lambda: len(journal.paths) == 1, "the flushed parts to be deleted")
        biggest = max(biggest, journal.on_disk_bytes())
    assert journal.parts_deleted >= 25  # 400 records of ~250 B in parts of 4 kB
    assert biggest <= part  # only the part being written is left between batches
    rec.close()
    journal.close()
    assert list(tmp_path.glob("*.journal")) == []  # a clean stop: all of it is in the MCAP
    logged = [m.log_time_ns - 1_000 for m in read_log(sorted(tmp_path.glob("run-*.mcap")))]
    assert logged == list(range(400))


def test_kill_9_before_any_flush_the_journal_has_everything(tmp_path: Path) -> None:
    journal = InputJournal(tmp_path / "run-inputs.journal", part_bytes=4_000)
    rec = ProcessRecorder(
        RecordingPlan(tmp_path, "run", "s", rerun=False, flush_interval=1e6), journal=journal
    )
    feed(journal, rec, 0, 100)
    wait_until(lambda: rec.pending_bytes() == 0, "the child to take every message")
    kill_child(rec)  # written into a chunk never flushed; the service dies too (no close)
    assert journal.parts_deleted == 0 and len(journal.paths) >= 6
    assert recovered_inputs(tmp_path) == list(range(100))
    rec.close()


def test_kill_9_after_a_flush_loses_nothing_either(tmp_path: Path) -> None:
    journal = InputJournal(tmp_path / "run-inputs.journal", part_bytes=4_000)
    rec = ProcessRecorder(
        RecordingPlan(tmp_path, "run", "s", rerun=False, flush_interval=0.05), journal=journal
    )
    feed(journal, rec, 0, 100)
    wait_until(lambda: len(journal.paths) == 1, "the flushed parts to be deleted")
    deleted = journal.parts_deleted
    assert deleted >= 5  # the first 100 are in the MCAP only now
    feed(journal, rec, 100, 100)  # and these in the journal, flushed or not when it dies
    kill_child(rec)
    assert recovered_inputs(tmp_path) == list(range(200))
    rec.close()


def test_a_record_the_mcap_never_got_keeps_its_part(tmp_path: Path) -> None:
    """A message dropped before the recorder (its ticket never comes back): its part stays,
    the parts around it go."""
    journal = InputJournal(tmp_path / "run-inputs.journal", part_bytes=1_000)
    rec = ProcessRecorder(
        RecordingPlan(tmp_path, "run", "s", rerun=False, flush_interval=0.05), journal=journal
    )
    feed(journal, rec, 0, 20)
    lost = journal.append(KEY, 1_000 + 20, record(20))  # journaled, never logged
    assert lost is not None
    feed(journal, rec, 21, 20)
    rec.close()
    journal.close()
    kept = journal.paths
    assert len(kept) == 1 and journal.parts_deleted >= 8
    assert recovered_inputs(tmp_path) == list(range(41))
