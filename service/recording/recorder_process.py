"""The recorder in a child process: MCAP and Rerun written outside the service's interpreter.

Writing the log and the recording costs about 2 ms of Python a passage
(Rerun's ``send_columns``, MCAP's compression), which in a thread competes
with the simulation for the GIL and cut the service's throughput by a third.
Here the twin only queues bytes it already has (the JSON of every message)
and a child process, on the other core, writes the files: same front as
``service.recording.recorder.Recorder`` (``message``, ``passage``, ``dent``, ``rail``,
``diagnosis``, ``close``), same order, same files.

The queue is bounded in bytes, so a flood cannot grow the service's memory
without limit: the recorder writes ~4–10 ms a passage on two shared cores, about
as slow as the simulation, and each passage queues ~330 kB (its result twice and
its series as JSON). Past ``rerun_backlog_bytes`` waiting (default 64 MB) a
passage, dent or diagnosis is not drawn in Rerun (the MCAP log has it; the
recording's passage log says so), which lets the MCAP writer catch up; past
``mcap_backlog_bytes`` (default 256 MB) a message waits for room (backpressure on
the twin) rather than being dropped.

The child ignores SIGINT/SIGTERM (the service stops it through the queue, so
that every queued message is written and the files get their footers), from its
first instruction: it is started with both signals blocked, so that a signal to the
whole process group while it is still starting does not kill it. It finishes its
files on its own if the service dies: it watches its parent. If it dies all the
same, the service stops queueing for it and never waits on its pipe.
The MCAP log is flushed at least every ``flush_interval`` seconds, so a
crash loses at most that much of it; and it tells the twin's journal
(``service.recording.input_journal``) which of its records are in a flushed chunk now:
a message carries its record's ticket, the child counts the items it has written and
publishes that count after each flush (and after closing the file), and the front
hands the tickets of the items counted back to the journal, which deletes the parts it
no longer needs. After a failed MCAP write the count stops: the journal keeps the rest.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import queue
import threading
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from schemas.diagnosis import Diagnosis
from schemas.messages import PassageResult, RailState
from service.recording import foxglove
from service.recording.input_journal import InputJournal
from service.wire.child_process import ignore_stop_signals, start_shielded


@dataclass(frozen=True)
class RecordingPlan:
    """What the child writes: ``<directory>/<stem>-NNN.mcap`` and ``<directory>/<stem>.rrd``."""

    directory: Path
    stem: str
    site_id: str
    mcap: bool = True
    rerun: bool = True
    mcap_max_bytes: int = 512 * 2**20
    mcap_max_seconds: float = 3600.0
    flush_interval: float = 0.5
    keep_bytes: int | None = None
    """Retention limit of the recordings directory (``service.recording.retention``); None: keep all."""
    metadata: tuple[tuple[str, str], ...] = ()
    """Written as a ``railtwin`` metadata record at the start of every MCAP file."""
    rerun_backlog_bytes: int = 64 * 2**20
    """Beyond this many bytes waiting for the child, passages are not drawn in Rerun."""
    samples_backlog_bytes: int = 16 * 2**20
    """Beyond this many bytes waiting, a result is not also written sample by sample on the
    MCAP's samples channel (~10 ms of the child a passage of 1 351 samples: under a flood
    the child keeps its time for the log and the Rerun drawings)."""
    mcap_backlog_bytes: int = 256 * 2**20
    """Beyond this many bytes waiting, a message for the MCAP log waits for room."""
    rrd_part_passages: int = 5000
    """Passages and diagnoses per ``.rrd`` part (``service.recording.rerun_recording``)."""
    cribs: tuple[str, ...] = ()
    """The ids of the site's detector's cribs: the Rerun blueprint's channel plots."""
    mcap_wait_timeout: float = 60.0
    """A message that found no room within this many seconds is dropped (and counted)."""

    @property
    def rrd_path(self) -> Path | None:
        return self.directory / f"{self.stem}.rrd" if self.rerun else None


class ProcessRecorder:
    """Front of the recording child process (thread-safe: ``multiprocessing.Queue``)."""

    def __init__(self, plan: RecordingPlan, journal: InputJournal | None = None) -> None:
        """``journal``: given the ticket of a message's record, the journal is told when the
        message is in a flushed MCAP chunk (``InputJournal.release``)."""
        self.plan = plan
        self.journal = journal
        ctx = mp.get_context("spawn")
        self._queue: Any = ctx.Queue()
        self._status: Any = ctx.Queue()
        self._pending: Any = ctx.Value("q", 0)  # bytes queued, not yet written by the child
        self._flushed: Any = ctx.Value("q", 0)  # items written by the child, MCAP flushed
        self._order = threading.Lock()  # an item's number is its place in the queue
        self._queued = 0
        self._tickets: deque[tuple[int, int]] = deque()  # (item number, journal ticket)
        self._process = ctx.Process(
            target=_child_main,
            args=(plan, self._queue, self._status, os.getpid(), self._pending, self._flushed),
            name="railtwin-recorder",
            daemon=True,
        )
        start_shielded(self._process)  # a signal to the group while it starts is not its death
        self.failures = 0
        self.last_failure: str | None = None
        self.not_drawn = 0
        """Passages, dents and diagnoses not drawn in Rerun because the child was behind."""
        self.not_sampled = 0
        """Results whose per-sample channel was not written because the child was behind."""
        self._mcap_path: str | None = None
        self._rrd_path: str | None = None
        self._closed = False
        self._done = threading.Event()
        if journal is not None:  # the journal lets go of what was flushed, even when idle
            threading.Thread(
                target=self._release_loop, name="railtwin-journal-release", daemon=True
            ).start()

    # --- front -------------------------------------------------------------------------

    def message(
        self,
        topic: str,
        model: type[BaseModel],
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        journal_ticket: int | None = None,
    ) -> None:
        """``journal_ticket``: the ticket of this message's journal record, released once
        the message is in a flushed MCAP chunk."""
        if self.plan.mcap and not self._closed:
            # a result's samples on their own channel too, unless the child is behind
            samples = (
                model is PassageResult
                and self.pending_bytes() + len(data) <= self.plan.samples_backlog_bytes
            )
            if model is PassageResult and not samples:
                self.not_sampled += 1
            self._put_waiting(
                (
                    "m",
                    len(data),
                    topic,
                    model.__name__,
                    data,
                    log_time_ns,
                    publish_time_ns,
                    samples,
                ),
                journal_ticket,
            )

    def passage(self, result: PassageResult, data: bytes | None = None) -> None:
        """``data``: the result's JSON if the caller has it already (saves serialising twice)."""
        if self.plan.rerun and not self._closed:
            data = data if data is not None else result.model_dump_json().encode()
            self._put_drawing(("p", len(data), data), result.passage_id)

    def dent(self, passage_id: str, state: RailState) -> None:
        if self.plan.rerun and not self._closed:
            data = state.model_dump_json().encode()
            self._put_drawing(("d", len(data), passage_id, data), None)

    def rail(self, state: RailState) -> None:
        if self.plan.rerun and not self._closed:
            data = state.model_dump_json().encode()
            self._put(("r", len(data), data))

    def diagnosis(
        self,
        diag: Diagnosis,
        curves_t: Sequence[float],
        measured: Sequence[float],
        fitted: Sequence[float],
        x: Sequence[float],
        impacts_x: Sequence[float],
    ) -> None:
        """Plain lists (or arrays) and the diagnosis's JSON cross to the child."""
        if self.plan.rerun and not self._closed:
            data = diag.model_dump_json().encode()
            size = len(data) + 8 * (
                len(curves_t) + len(measured) + len(fitted) + len(x) + len(impacts_x)
            )
            self._put_drawing(
                (
                    "g",
                    size,
                    data,
                    list(curves_t),
                    list(measured),
                    list(fitted),
                    list(x),
                    list(impacts_x),
                ),
                None,
            )

    def pending_bytes(self) -> int:
        """Bytes queued for the child and not yet written (what the queue holds in memory)."""
        return int(self._pending.value)

    def _put(self, item: tuple[Any, ...], journal_ticket: int | None = None) -> None:
        if not self._process.is_alive():  # nobody reads the pipe: queueing would fill it
            self._lost(f"the recorder process has died (exit code {self._process.exitcode})")
            return
        with self._pending.get_lock():
            self._pending.value += item[1]
        with self._order:
            self._queue.put(item)
            if journal_ticket is not None and self.journal is not None:
                self._tickets.append((self._queued, journal_ticket))
            self._queued += 1
        self._release_flushed()

    def _release_loop(self) -> None:
        while not self._done.wait(self.plan.flush_interval):
            self._release_flushed()

    def _release_flushed(self) -> None:
        """Hand the journal the tickets of the messages now in a flushed MCAP chunk."""
        if self.journal is None:
            return
        flushed = int(self._flushed.value)
        done: list[int] = []
        with self._order:
            while self._tickets and self._tickets[0][0] < flushed:
                done.append(self._tickets.popleft()[1])
        if done:
            self.journal.release(done)

    def _lost(self, why: str) -> None:
        self.failures += 1
        self.last_failure = f"recording stopped: {why}"

    def _put_drawing(self, item: tuple[Any, ...], passage_id: str | None) -> None:
        """Queue a Rerun drawing, unless the child is ``rerun_backlog_bytes`` behind."""
        behind = self.pending_bytes()
        if behind + item[1] <= self.plan.rerun_backlog_bytes:
            self._put(item)
            return
        self.not_drawn += 1
        if passage_id is not None:  # the recording's passage log says which wheel is missing
            note = f"{passage_id}".encode()
            self._put(("s", len(note), note, behind))

    def _put_waiting(self, item: tuple[Any, ...], journal_ticket: int | None) -> None:
        """Queue a message for the MCAP log, waiting while ``mcap_backlog_bytes`` are."""
        limit = self.plan.mcap_backlog_bytes
        if self.pending_bytes() + item[1] > limit:
            deadline = time.monotonic() + self.plan.mcap_wait_timeout
            while self.pending_bytes() > 0 and self.pending_bytes() + item[1] > limit:
                if not self._process.is_alive() or time.monotonic() > deadline:
                    self.failures += 1
                    self.last_failure = (
                        f"MCAP message on {item[2]} dropped: the recorder is "
                        f"{self.pending_bytes() / 2**20:.0f} MB behind and "
                        + (
                            "has died"
                            if not self._process.is_alive()
                            else f"made no room within {self.plan.mcap_wait_timeout:g} s"
                        )
                    )
                    return
                time.sleep(0.002)
        self._put(item, journal_ticket)

    def backlog(self) -> int:
        try:
            return int(self._queue.qsize())
        except NotImplementedError:  # macOS
            return 0

    def mcap_path(self) -> str | None:
        """The MCAP file being written (or the last one)."""
        self._poll()
        return self._mcap_path

    def rrd_path(self) -> str | None:
        """The ``.rrd`` part being written (or the last one)."""
        self._poll()
        if self._rrd_path is not None:
            return self._rrd_path
        path = self.plan.rrd_path
        return str(path) if path is not None else None

    def close(self, timeout: float = 60.0) -> None:
        """Have the child write what is queued and finish the files."""
        if self._closed:
            return
        self._closed = True
        behind = []
        if self.not_drawn:
            behind.append(
                f"{self.not_drawn} passages, dents or diagnoses not drawn in the Rerun recording"
            )
        if self.not_sampled:
            behind.append(
                f"{self.not_sampled} results not written sample by sample on the "
                "MCAP's samples channel"
            )
        if behind:
            self.failures += 1
            self.last_failure = (
                f"{' and '.join(behind)}: the recorder was behind (the MCAP log has them all)"
            )
        if self._process.is_alive():
            self._queue.put(None)
            self._process.join(timeout)
        if self._process.is_alive():
            self._process.terminate()
            self._process.join(5.0)
            self.failures += 1
            self.last_failure = f"recorder did not finish within {timeout:g} s"
        elif self._process.exitcode not in (0, None):
            self._lost(f"the recorder process ended with exit code {self._process.exitcode}")
        self._done.set()
        self._release_flushed()
        self._poll()
        # what is still in the queue's pipe has no reader: exit without waiting to write it
        self._queue.cancel_join_thread()
        self._queue.close()

    def _poll(self) -> None:
        while True:
            try:
                kind, text = self._status.get_nowait()
            except (queue.Empty, OSError, EOFError, ValueError):
                return
            if kind == "path":
                self._mcap_path = text
            elif kind == "rrd":
                self._rrd_path = text
            else:
                self.failures += 1
                self.last_failure = text


def _child_main(
    plan: RecordingPlan, inbox: Any, status: Any, parent_pid: int, pending: Any, flushed: Any
) -> None:
    """The child's loop: write every queued item in order; flush MCAP regularly, then
    publish in ``flushed`` how many items are written and flushed."""
    ignore_stop_signals()
    from schemas import all_models
    from service.recording.mcap_log import McapLog
    from service.recording.rerun_recording import RerunRecording

    models = all_models()
    mcap = (
        McapLog(
            plan.directory,
            plan.stem,
            metadata=dict(plan.metadata),
            keep_bytes=plan.keep_bytes,
            max_bytes=plan.mcap_max_bytes,
            max_seconds=plan.mcap_max_seconds,
        )
        if plan.mcap
        else None
    )
    path = plan.rrd_path
    rerun = (
        RerunRecording(path, plan.site_id, part_passages=plan.rrd_part_passages, cribs=plan.cribs)
        if path is not None
        else None
    )
    rrd_path = path
    last_flush = time.monotonic()
    last_path: Path | None = None
    received = 0  # items taken off the queue
    mcap_failed = False  # a message may be missing from the MCAP: the journal keeps the rest
    try:
        while True:
            try:
                item = inbox.get(timeout=plan.flush_interval / 2)
            except queue.Empty:
                item = ()
                if os.getppid() != parent_pid:  # the service died: finish the files
                    break
            except (EOFError, OSError):
                break
            if item is None:
                break
            try:
                _write(item, models, mcap, rerun)
                if rerun is not None and rerun.path != rrd_path:
                    rrd_path = rerun.path
                    status.put(("rrd", str(rrd_path)))
            except Exception as exc:  # a recording failure is reported, never fatal
                status.put(("fail", f"{type(exc).__name__}: {exc}"))
                mcap_failed = mcap_failed or item[0] == "m"
            if item:
                received += 1
                with pending.get_lock():
                    pending.value -= item[1]
            if mcap is not None:
                if mcap.path is not None and mcap.path != last_path:
                    last_path = mcap.path
                    status.put(("path", str(last_path)))
                now = time.monotonic()
                if now - last_flush >= plan.flush_interval:
                    mcap.flush()
                    last_flush = now
                    if not mcap_failed:
                        flushed.value = received
    finally:
        if mcap is not None:
            with contextlib.suppress(Exception):
                mcap.close()
                if not mcap_failed:
                    flushed.value = received
        if rerun is not None:
            with contextlib.suppress(Exception):
                rerun.close()


def _write(
    item: tuple[Any, ...], models: dict[str, type[BaseModel]], mcap: Any, rerun: Any
) -> None:
    """One queued item: ``(kind, bytes it holds, ...)``."""
    if not item:
        return
    kind, _size, *rest = item
    if kind == "m" and mcap is not None:
        topic, model_name, data, log_time_ns, publish_time_ns, with_samples = rest
        mcap.write(topic, models[model_name], data, log_time_ns, publish_time_ns)
        if with_samples:  # plottable against time in Foxglove
            sample_topic = foxglove.samples_topic(topic)
            for ns, sample in foxglove.samples(data):
                mcap.write(
                    sample_topic,
                    foxglove.PassageSample,
                    sample,
                    ns,
                    ns,
                    schema_name=foxglove.SAMPLE_SCHEMA_NAME,
                )
        entry = foxglove.log_entry(model_name, data, log_time_ns)
        if entry is not None:  # errors and verdicts in Foxglove's Log panel too
            mcap.write(
                foxglove.log_topic(topic),
                foxglove.Log,
                entry.model_dump_json().encode(),
                log_time_ns,
                schema_name=foxglove.SCHEMA_NAME,
            )
    elif kind == "p" and rerun is not None:
        rerun.log_passage(PassageResult.model_validate_json(rest[0]))
    elif kind == "s" and rerun is not None:
        rerun.log_not_drawn(rest[0].decode(), rest[1])
    elif kind == "d" and rerun is not None:
        rerun.log_dent(rest[0], RailState.model_validate_json(rest[1]))
    elif kind == "g" and rerun is not None:
        import numpy as np

        diag, t, measured, fitted, x, impacts_x = rest
        rerun.log_diagnosis(
            Diagnosis.model_validate_json(diag),
            *(np.asarray(a, dtype=np.float64) for a in (t, measured, fitted, x, impacts_x)),
        )
    elif kind == "r" and rerun is not None:
        import numpy as np

        state = RailState.model_validate_json(rest[0])
        rerun.log_rail(np.asarray(state.x), np.asarray(state.y))
