"""The journal: every received payload on disk before it is queued, every answer as sent.

The MCAP log is written by a recorder process from a queue in memory; a kill -9 of
every process of the service would lose what is still in that queue. So the Zenoh
callback first appends each input, as it came, to ``<run>-inputs.journal`` (then
``<run>-inputs-001.journal``… past 256 MB a part) with one
``write`` system call (the operating system keeps it once the call returns, whatever
happens to the process), and only then queues it; each result, diagnosis and error is appended as it is published. ``railtwin
recover`` merges a run's journal into its MCAP: what the recorder never wrote is added back.

Record: magic ``RTJ1``, key length (u16), payload length (u32), received time (u64 ns),
key, payload, CRC-32 of everything before it (little endian). A torn last record
(the process died inside ``write``) fails its length or CRC and ends the reading.

    >>> import tempfile
    >>> from pathlib import Path
    >>> p = Path(tempfile.mkdtemp()) / "run-inputs.journal"
    >>> j = InputJournal(p)
    >>> j.append("railtwin/km12/passage", 17, b'{"a": 1}')
    >>> j.close()
    >>> [(e.key, e.received_ns, e.payload) for e in read_journal(p)]
    [('railtwin/km12/passage', 17, b'{"a": 1}')]
"""

from __future__ import annotations

import os
import struct
import threading
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

__all__ = ["PART_BYTES", "InputJournal", "JournalEntry", "part_path", "read_journal"]

MAGIC = b"RTJ1"
_HEAD = struct.Struct("<4sHIQ")
_CRC = struct.Struct("<I")


@dataclass(frozen=True)
class JournalEntry:
    """One received input: its key, when (UNIX ns) and its bytes."""

    key: str
    received_ns: int
    payload: bytes


PART_BYTES = 256 * 1024 * 1024
"""A journal part is closed and the next one started past this size, so that a months-long
run's journal is a series of files the retention limit can delete oldest first."""


def part_path(first: Path, index: int) -> Path:
    """Part ``index`` of the journal whose first part is ``first``.

    >>> part_path(Path("run-inputs.journal"), 0).name, part_path(Path("run-inputs.journal"), 2).name
    ('run-inputs.journal', 'run-inputs-002.journal')
    """
    return first if index == 0 else first.with_name(f"{first.stem}-{index:03d}{first.suffix}")


class InputJournal:
    """Append-only, one ``write`` per input; safe to call from several Zenoh callbacks.

    Past ``part_bytes`` the journal goes on in a new part (``part_path``); a record is
    never split between parts. ``railtwin recover`` takes the parts in any order.
    """

    def __init__(self, path: Path, part_bytes: int = PART_BYTES) -> None:
        if part_bytes <= 0:
            raise ValueError(f"part_bytes must be positive, got {part_bytes}")
        path.parent.mkdir(parents=True, exist_ok=True)
        self.first = path
        self.part_bytes = part_bytes
        self._part = 0
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        self._size = os.fstat(self._fd).st_size
        self._lock = threading.Lock()

    @property
    def paths(self) -> list[Path]:
        """Every part written so far, oldest first."""
        return [part_path(self.first, i) for i in range(self._part + 1)]

    def append(self, key: str, received_ns: int, payload: bytes) -> None:
        k = key.encode()[:65535]
        body = _HEAD.pack(MAGIC, len(k), len(payload), received_ns) + k + payload
        record = body + _CRC.pack(zlib.crc32(body))
        with self._lock:
            if self._fd < 0:
                return
            if self._size > 0 and self._size + len(record) > self.part_bytes:
                os.close(self._fd)
                self._part += 1
                self.path = part_path(self.first, self._part)
                self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
                self._size = os.fstat(self._fd).st_size
            os.write(self._fd, record)
            self._size += len(record)

    def close(self) -> None:
        with self._lock:
            if self._fd >= 0:
                os.close(self._fd)
                self._fd = -1


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
        key = data[pos + _HEAD.size:pos + _HEAD.size + klen].decode(errors="replace")
        yield JournalEntry(key, ns, data[pos + _HEAD.size + klen:end])
        pos = end + _CRC.size
