"""An input as it arrived on Zenoh, before anything was made of it."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Inbound:
    """A payload as it arrived: its key, bytes and the time it came (wall and monotonic)."""

    key: str
    payload: bytes
    received_ns: int
    received_mono: float
    journal_ticket: int | None = None
    """Of its journal record (``InputJournal.append``): released once the MCAP holds it."""
    sender: str | None = None
    """The Zenoh session that published it, when its publisher says (``source_info``)."""

    @property
    def received_at(self) -> float:
        """UNIX s, as a ``ServiceError`` about this input says when it came."""
        return self.received_ns / 1e9
