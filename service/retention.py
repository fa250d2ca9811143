"""A retention limit for recordings: the oldest runs' files go when the directory is full.

A twin at the trackside runs for months; its MCAP logs, Rerun recordings and journals
must not fill the disk. ``enforce_retention`` deletes whole files named ``railtwin-*``
(``.mcap``, ``.rrd``, ``.journal``), oldest first by modification time, until their total
is at most ``keep_bytes``; the files of the run being written (``protect`` prefix) are
never deleted. The recorder calls it whenever it starts a new MCAP file (rotation).

    >>> import os, tempfile
    >>> from pathlib import Path
    >>> d = Path(tempfile.mkdtemp())
    >>> for i, name in enumerate(["railtwin-a-000.mcap", "railtwin-b-000.mcap", "railtwin-c.rrd"]):
    ...     _ = (d / name).write_bytes(b"x" * 100)
    ...     os.utime(d / name, (i, i))
    >>> [p.name for p in enforce_retention(d, 150, protect="railtwin-c")]
    ['railtwin-a-000.mcap', 'railtwin-b-000.mcap']
    >>> sorted(p.name for p in d.iterdir())
    ['railtwin-c.rrd']
"""

from __future__ import annotations

import contextlib
from pathlib import Path

__all__ = ["enforce_retention"]

SUFFIXES = (".mcap", ".rrd", ".journal")


def enforce_retention(directory: Path, keep_bytes: int, protect: str) -> list[Path]:
    """Delete the oldest recordings until at most ``keep_bytes`` remain; returns those deleted."""
    files = []
    for p in directory.glob("railtwin-*"):
        if p.suffix in SUFFIXES and p.is_file():
            with contextlib.suppress(OSError):
                st = p.stat()
                files.append((st.st_mtime, p.name, p, st.st_size))
    total = sum(f[3] for f in files)
    deleted = []
    for _, name, p, size in sorted(files):
        if total <= keep_bytes:
            break
        if name.startswith(protect):
            continue
        with contextlib.suppress(OSError):
            p.unlink()
            total -= size
            deleted.append(p)
    return deleted
