"""What the twin needs of a recorder: ``RecorderFront``.

The one implementation is ``service.recording.recorder_process.ProcessRecorder``: a child
process writes the MCAP log and the Rerun recording from a queue bounded in bytes,
in the order the twin hands it messages (an earlier thread-based recorder competed
with the simulation for the GIL, and its queue was unbounded).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from pydantic import BaseModel

from schemas.diagnosis import Diagnosis
from schemas.messages import PassageResult, RailState


class RecorderFront(Protocol):
    """Thread-safe: the twin calls it from its worker, publisher and Zenoh threads."""

    def message(
        self,
        topic: str,
        model: type[BaseModel],
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        journal_ticket: int | None = None,
    ) -> None:
        """``journal_ticket``: of the message's journal record, released (``InputJournal``)
        once the message is in a flushed MCAP chunk."""

    def passage(self, result: PassageResult, data: bytes | None = None) -> None: ...
    def dent(self, passage_id: str, state: RailState) -> None: ...
    def rail(self, state: RailState) -> None: ...
    def diagnosis(
        self,
        diag: Diagnosis,
        curves_t: Sequence[float],
        measured: Sequence[float],
        fitted: Sequence[float],
        x: Sequence[float],
        impacts_x: Sequence[float],
    ) -> None: ...
    def backlog(self) -> int: ...
    def mcap_path(self) -> str | None: ...
    def rrd_path(self) -> str | None: ...
    def close(self, timeout: float = 60.0) -> None: ...
