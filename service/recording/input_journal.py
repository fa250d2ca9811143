"""The journal: every received payload on disk before it is queued, every answer as sent.

The MCAP log is written by a recorder process from a queue in memory; a kill -9 of
every process of the service would lose what is still in that queue. So the Zenoh
callback first appends each input, as it came, to ``<run>-inputs.journal`` (then
``<run>-inputs-001.journal``… past 256 MB a part) with one
``write`` system call (the operating system keeps it once the call returns, whatever
happens to the process), and only then queues it; each result, diagnosis and error is
appended as it is published. ``railtwin recover`` merges a run's journal into its MCAP: what
the recorder never wrote is added back.

The journal is a crash-safety copy of what the MCAP log will hold, so it holds only what
the MCAP does not hold yet. ``append`` returns a ticket; the recorder hands the ticket back
(``release``) once the MCAP chunk holding that record's message is flushed to the
operating system. A part (a new one every ``part_bytes`` or ``part_seconds``) is deleted
once it is closed and every ticket of it is released; on ``close`` the last part goes the
same way. A record whose message never reached a flushed chunk (the recorder died, was
behind and dropped it, failed to write it; an input still queued at a stop) keeps its part
on disk, for ``railtwin recover``. So at any moment a kill -9 loses nothing: a record is
either in a flushed MCAP chunk or in a journal part still on disk.

Record: magic ``RTJ1``, key length (u16), payload length (u32), received time (u64 ns),
key, payload, CRC-32 of everything before it (little endian). A torn last record
(the process died inside ``write``) fails its length or CRC and ends the reading.

    >>> import tempfile
    >>> from pathlib import Path
    >>> p = Path(tempfile.mkdtemp()) / "run-inputs.journal"
    >>> j = InputJournal(p)
    >>> j.append("railtwin/km12/passage", 17, b'{"a": 1}')
    0
    >>> j.close()
    >>> [(e.key, e.received_ns, e.payload) for e in read_journal(p)]
    [('railtwin/km12/passage', 17, b'{"a": 1}')]
    >>> j.release([0]); p.exists()  # the MCAP has it now: the journal lets it go
    False
"""

from __future__ import annotations

import bisect
import contextlib
import os
import struct
import threading
import time
import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = [
    "PART_BYTES",
    "PART_SECONDS",
    "InputJournal",
    "JournalEntry",
    "part_path",
    "read_journal",
]

MAGIC = b"RTJ1"
_HEAD = struct.Struct("<4sHIQ")
_CRC = struct.Struct("<I")


@dataclass(frozen=True)
class JournalEntry:
    """One received input: its key, when (UNIX ns) and its bytes."""

    key: str
    received_ns: int
    payload: bytes


PART_BYTES = 4 * 1024 * 1024
"""A journal part is closed and the next one started past this size: parts whose records
are all in the MCAP are deleted, and what is left is a series of files the retention limit
can delete oldest first."""

PART_SECONDS = 10.0
"""... or when its first record is this old (at the next append), so that a trickle of
passages does not keep an old part open."""


def part_path(first: Path, index: int) -> Path:
    """Part ``index`` of the journal whose first part is ``first``.

    >>> part_path(Path("run-inputs.journal"), 0).name, part_path(Path("run-inputs.journal"), 2).name
    ('run-inputs.journal', 'run-inputs-002.journal')
    """
    return first if index == 0 else first.with_name(f"{first.stem}-{index:03d}{first.suffix}")


class InputJournal:
    """Append-only, one ``write`` per record; safe to call from several threads.

    Past ``part_bytes`` (or ``part_seconds``) the journal goes on in a new part
    (``part_path``); a record is never split between parts. ``railtwin recover`` takes the
    parts in any order, and whichever are left.
    """

    def __init__(
        self, path: Path, part_bytes: int = PART_BYTES, part_seconds: float = PART_SECONDS
    ) -> None:
        if part_bytes <= 0:
            raise ValueError(f"part_bytes must be positive, got {part_bytes}")
        if not part_seconds > 0:
            raise ValueError(f"part_seconds must be positive, got {part_seconds}")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.first = path
        self.part_bytes = part_bytes
        self.part_seconds = part_seconds
        self._part = 0
        self.path = path
        self._lock = threading.Lock()
        self._next_ticket = 0
        self._part_first: list[int] = []
        """The first ticket of each part (index: part)."""
        self._outstanding: dict[int, set[int]] = {}
        """Parts on disk -> their tickets not yet released."""
        self._foreign: set[int] = set()
        """Parts that held records before this journal opened them: never deleted."""
        self.parts_deleted = 0
        self._fd = -1
        self._open_part()

    def _open_part(self) -> None:
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        self._size = os.fstat(self._fd).st_size
        if self._size > 0:
            self._foreign.add(self._part)
        self._opened = time.monotonic()
        self._part_first.append(self._next_ticket)
        self._outstanding[self._part] = set()

    @property
    def paths(self) -> list[Path]:
        """Every part still on disk, oldest first."""
        with self._lock:
            return [part_path(self.first, i) for i in sorted(self._outstanding)]

    def on_disk_bytes(self) -> int:
        """Bytes of the parts still on disk."""
        total = 0
        for p in self.paths:
            with contextlib.suppress(FileNotFoundError):
                total += p.stat().st_size
        return total

    def append(self, key: str, received_ns: int, payload: bytes) -> int | None:
        """Write one record; its ticket (for ``release``), None once closed."""
        k = key.encode()[:65535]
        body = _HEAD.pack(MAGIC, len(k), len(payload), received_ns) + k + payload
        record = body + _CRC.pack(zlib.crc32(body))
        with self._lock:
            if self._fd < 0:
                return None
            if self._size > 0 and (
                self._size + len(record) > self.part_bytes
                or time.monotonic() - self._opened >= self.part_seconds
            ):
                os.close(self._fd)
                done = self._part
                self._part += 1
                self.path = part_path(self.first, self._part)
                self._open_part()
                self._drop_if_done(done)
            os.write(self._fd, record)
            self._size += len(record)
            ticket = self._next_ticket
            self._next_ticket += 1
            self._outstanding[self._part].add(ticket)
            return ticket

    def release(self, tickets: Iterable[int]) -> None:
        """These records are in a flushed MCAP chunk: a part whose records all are, and which
        is closed, is deleted. Releasing a ticket twice, or an unknown one, does nothing."""
        with self._lock:
            touched: set[int] = set()
            for t in tickets:
                part = bisect.bisect_right(self._part_first, t) - 1
                waiting = self._outstanding.get(part)
                if waiting is not None:
                    waiting.discard(t)
                    touched.add(part)
            for part in touched:
                if part != self._part or self._fd < 0:
                    self._drop_if_done(part)

    def _drop_if_done(self, part: int) -> None:
        if self._outstanding.get(part) or part in self._foreign or part not in self._outstanding:
            return
        del self._outstanding[part]
        with contextlib.suppress(FileNotFoundError):  # the retention limit may have been first
            part_path(self.first, part).unlink()
        self.parts_deleted += 1

    def close(self) -> None:
        """No more records; the last part goes too if everything in it was released."""
        with self._lock:
            if self._fd >= 0:
                os.close(self._fd)
                self._fd = -1
                self._drop_if_done(self._part)


def read_journal(path: Path) -> Iterator[JournalEntry]:
    """The complete records of a journal, in order (stops at a torn one)."""
    data = path.read_bytes()
    pos = 0
    while pos + _HEAD.size <= len(data):
        magic, klen, plen, ns = _HEAD.unpack_from(data, pos)
        end = pos + _HEAD.size + klen + plen
        if magic != MAGIC or end + _CRC.size > len(data):
            return
        (crc,) = _CRC.unpack_from(data, end)
        if crc != zlib.crc32(data[pos:end]):
            return
        key = data[pos + _HEAD.size : pos + _HEAD.size + klen].decode(errors="replace")
        yield JournalEntry(key, ns, data[pos + _HEAD.size + klen : end])
        pos = end + _CRC.size
