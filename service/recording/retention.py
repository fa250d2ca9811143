"""A retention limit for recordings: the oldest files go when the directory is full.

A twin at the trackside runs for months; its MCAP logs, Rerun recordings and journals
must not fill the disk. ``enforce_retention`` deletes whole files named ``railtwin-*``
(``.mcap``, ``.rrd``, ``.journal``), oldest first by modification time, until their total
is at most ``keep_bytes``. Each kind of file is written in numbered parts
(``<run>-000.mcap``, ``<run>.rrd`` then ``<run>-002.rrd``, ``<run>-inputs.journal`` then
``<run>-inputs-001.journal``); of the run being written (``protect``, its name prefix)
only the newest part of each series is kept, so a single months-long run also gives up
its oldest parts. Files of other runs changed less than ``recent_s`` ago are kept too:
they may belong to another twin still writing in the same directory. The recorder calls
this whenever it starts a new MCAP file (rotation).

    >>> import os, tempfile
    >>> from pathlib import Path
    >>> d = Path(tempfile.mkdtemp())
    >>> names = ["railtwin-a-000.mcap", "railtwin-c-000.mcap", "railtwin-c-001.mcap",
    ...          "railtwin-c.rrd"]
    >>> for i, name in enumerate(names):
    ...     _ = (d / name).write_bytes(b"x" * 100)
    ...     os.utime(d / name, (i, i))
    >>> [p.name for p in enforce_retention(d, 150, protect="railtwin-c", now=1e9)]
    ['railtwin-a-000.mcap', 'railtwin-c-000.mcap']
    >>> sorted(p.name for p in d.iterdir())
    ['railtwin-c-001.mcap', 'railtwin-c.rrd']
"""

from __future__ import annotations

import contextlib
import re
import time
from pathlib import Path

__all__ = ["enforce_retention"]

SUFFIXES = (".mcap", ".rrd", ".journal")


RECENT_S = 600.0
"""Seconds within which another run's file counts as still being written."""

_PART = re.compile(r"^(?P<series>.+?)(?:-(?P<index>\d{3,}))?$")


def _series(path: Path) -> tuple[str, str, int]:
    """(series name, suffix, part index) of a recording file: parts of one series differ
    only by their index (an unnumbered file is part 0)."""
    m = _PART.match(path.stem)
    assert m is not None  # the pattern matches any non-empty stem
    return m["series"], path.suffix, int(m["index"] or 0)


def enforce_retention(
    directory: Path,
    keep_bytes: int,
    protect: str,
    *,
    recent_s: float = RECENT_S,
    now: float | None = None,
) -> list[Path]:
    """Delete the oldest recordings until at most ``keep_bytes`` remain; returns those deleted.

    Kept whatever the size: the newest part of each series of the run ``protect`` (the
    files it is writing now) and files of other runs changed in the last ``recent_s``.
    """
    clock = time.time() if now is None else now
    files = []
    for p in directory.glob("railtwin-*"):
        if p.suffix in SUFFIXES and p.is_file():
            with contextlib.suppress(OSError):
                st = p.stat()
                files.append((st.st_mtime, p.name, p, st.st_size))
    newest: dict[tuple[str, str], int] = {}
    for _, name, p, _ in files:
        if name.startswith(protect):
            series, suffix, index = _series(p)
            newest[(series, suffix)] = max(newest.get((series, suffix), index), index)
    total = sum(f[3] for f in files)
    deleted = []
    for mtime, name, p, size in sorted(files):
        if total <= keep_bytes:
            break
        if name.startswith(protect):
            series, suffix, index = _series(p)
            if index == newest[(series, suffix)]:
                continue
        elif clock - mtime < recent_s:
            continue
        with contextlib.suppress(OSError):
            p.unlink()
            total -= size
            deleted.append(p)
    return deleted
