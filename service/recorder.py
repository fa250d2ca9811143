"""One thread that writes the MCAP log and the Rerun recording, off the twin's hot path.

The twin hands it every message as it is received or published (in that
order); this thread writes them to MCAP in the same order, draws passages in
Rerun, and flushes the MCAP log at least every ``flush_interval`` seconds, so
a crash loses at most that much of the log.
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from pydantic import BaseModel

from schemas.diagnosis import Diagnosis
from schemas.messages import PassageResult, RailState
from service.mcap_log import McapLog
from service.rerun_recording import RerunRecording


@dataclass(frozen=True)
class _Message:
    topic: str
    model: type[BaseModel]
    data: bytes
    log_time_ns: int
    publish_time_ns: int | None = None


@dataclass(frozen=True)
class _Passage:
    result: PassageResult


@dataclass(frozen=True)
class _Dent:
    passage_id: str
    state: RailState


@dataclass(frozen=True)
class _Rail:
    state: RailState


@dataclass(frozen=True)
class _Diagnosis:
    diag: Diagnosis
    t: Any
    measured: Any
    fitted: Any
    x: Any
    impacts_x: Any


_STOP = object()


class RecorderFront(Protocol):
    """What the twin needs of a recorder (this thread's, or ``recorder_process``'s child)."""

    def message(self, topic: str, model: type[BaseModel], data: bytes, log_time_ns: int,
                publish_time_ns: int | None = None) -> None: ...
    def passage(self, result: PassageResult, data: bytes | None = None) -> None: ...
    def dent(self, passage_id: str, state: RailState) -> None: ...
    def rail(self, state: RailState) -> None: ...
    def diagnosis(self, diag: Diagnosis, curves_t: Sequence[float], measured: Sequence[float],
                  fitted: Sequence[float], x: Sequence[float],
                  impacts_x: Sequence[float]) -> None: ...
    def backlog(self) -> int: ...
    def mcap_path(self) -> str | None: ...
    def rrd_path(self) -> str | None: ...
    def close(self, timeout: float = 60.0) -> None: ...


class Recorder:
    """Thread-safe front (``message``, ``passage``, ...); the writing happens in one thread."""

    def __init__(
        self,
        mcap: McapLog | None,
        rerun: RerunRecording | None,
        *,
        flush_interval: float = 0.5,
    ) -> None:
        self.mcap = mcap
        self.rerun = rerun
        self.flush_interval = flush_interval
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._run, name="railtwin-recorder", daemon=True)
        self.failures = 0
        self.last_failure: str | None = None
        self._thread.start()

    # --- front -------------------------------------------------------------------------

    def message(self, topic: str, model: type[BaseModel], data: bytes, log_time_ns: int,
                publish_time_ns: int | None = None) -> None:
        if self.mcap is not None:
            self._queue.put(_Message(topic, model, data, log_time_ns, publish_time_ns))

    def passage(self, result: PassageResult, data: bytes | None = None) -> None:
        """``data``, when given, is the whole result (``result`` may lack its arrays)."""
        if self.rerun is not None:
            if data is not None and not result.x:
                result = PassageResult.model_validate_json(data)
            self._queue.put(_Passage(result))

    def dent(self, passage_id: str, state: RailState) -> None:
        if self.rerun is not None:
            self._queue.put(_Dent(passage_id, state))

    def rail(self, state: RailState) -> None:
        if self.rerun is not None:
            self._queue.put(_Rail(state))

    def diagnosis(self, diag: Diagnosis, curves_t: Sequence[float], measured: Sequence[float],
                  fitted: Sequence[float], x: Sequence[float],
                  impacts_x: Sequence[float]) -> None:
        """Measured and fitted force of one diagnosis (at the measured times ``curves_t``,
        wheel positions ``x``, m), its impacts (m along the site) and verdict."""
        if self.rerun is not None:
            self._queue.put(_Diagnosis(diag, curves_t, measured, fitted, x, impacts_x))

    def backlog(self) -> int:
        return self._queue.qsize()

    def mcap_path(self) -> str | None:
        """The MCAP file being written (or the last one)."""
        if self.mcap is None:
            return None
        path = self.mcap.path or (self.mcap.files[-1] if self.mcap.files else None)
        return str(path) if path is not None else None

    def rrd_path(self) -> str | None:
        return str(self.rerun.path) if self.rerun is not None else None

    def close(self, timeout: float = 60.0) -> None:
        """Write what is queued, finish the files."""
        self._queue.put(_STOP)
        self._thread.join(timeout)

    # --- thread ------------------------------------------------------------------------

    def _run(self) -> None:
        last_flush = time.monotonic()
        while True:
            try:
                item = self._queue.get(timeout=self.flush_interval / 2)
            except queue.Empty:
                item = None
            if item is _STOP:
                break
            if item is not None:
                self._write(item)
            now = time.monotonic()
            if self.mcap is not None and now - last_flush >= self.flush_interval:
                self._guard(self.mcap.flush)
                last_flush = now
        if self.mcap is not None:
            self._guard(self.mcap.close)
        if self.rerun is not None:
            self._guard(self.rerun.close)

    def _write(self, item: Any) -> None:
        if isinstance(item, _Message) and self.mcap is not None:
            mcap = self.mcap
            self._guard(lambda: mcap.write(item.topic, item.model, item.data, item.log_time_ns,
                                           item.publish_time_ns))
        elif self.rerun is not None:
            rerun = self.rerun
            if isinstance(item, _Passage):
                self._guard(lambda: rerun.log_passage(item.result))
            elif isinstance(item, _Dent):
                self._guard(lambda: rerun.log_dent(item.passage_id, item.state))
            elif isinstance(item, _Diagnosis):
                self._guard(lambda: rerun.log_diagnosis(
                    item.diag, np.asarray(item.t, dtype=np.float64),
                    np.asarray(item.measured, dtype=np.float64),
                    np.asarray(item.fitted, dtype=np.float64),
                    np.asarray(item.x, dtype=np.float64),
                    np.asarray(item.impacts_x, dtype=np.float64)))
            elif isinstance(item, _Rail):
                self._guard(lambda: rerun.log_rail(np.asarray(item.state.x),
                                                   np.asarray(item.state.y)))

    def _guard(self, action: Any) -> None:
        """A recording failure is counted and reported, never fatal to the service."""
        try:
            action()
        except Exception as exc:
            self.failures += 1
            self.last_failure = f"{type(exc).__name__}: {exc}"
