"""The reduced track kept on disk: a site's track is reduced once per machine, not once a process.

Reducing a track (dense eigen-solves of the finite model: ``sim_core.track.modal``) takes
seconds; its result depends only on the track, the stretch, the cribs and the reduction's
settings. It is written as one file a key (a SHA-256 of those inputs and of
``FORMAT``) to the directory ``RAILTWIN_TRACK_CACHE`` names, else ``track-cache`` beside
numba's cache (``NUMBA_CACHE_DIR``), else ``~/.cache/railtwin/track``; written to a
temporary file and renamed, so a reader never sees half a file. An unreadable, truncated,
damaged (CRC-32 of the payload) or foreign entry is ignored and replaced.
``RAILTWIN_TRACK_CACHE=off`` switches it off.

The directory is bounded: after each write, entries beyond ``RAILTWIN_TRACK_CACHE_MAX_MB``
(``MAX_MB`` by default) are deleted, the least recently used first (a read touches its
entry's mtime, and so does a process serving it from memory, every ``TOUCH_INTERVAL``),
never the one just written; a writer's temporary file left over an hour (a writer that died
before its rename) goes too. A calibrating twin reduces a new track for each
step of its estimate, and an unbounded cache would fill the disk.

The file is ``MAGIC``, the length of a JSON header (8 bytes, little-endian), the header
(each array's name, dtype, shape and offset; the payload's length and CRC-32) and the
arrays' bytes: read in one piece, the arrays are views of it (an ``.npz`` took 2-3x longer
to read, through ``zipfile``'s many small reads).

Worked example (a key names its inputs and nothing else):

    >>> key(("a", 1.0)) == key(("a", 1.0)), key(("a", 1.0)) == key(("a", 2.0))
    (True, False)
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import tempfile
import time
import zlib
from collections import OrderedDict
from collections.abc import Hashable
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim_core.track.lanes import aligned_empty

FORMAT = "railtwin-track-6"
"""Bumped whenever what a reduction holds or how it is computed changes."""

SUFFIX = ".track"
"""An entry's file name: its key and this."""

MAX_MB = 2048
"""The cache's default bound, MB (``RAILTWIN_TRACK_CACHE_MAX_MB`` overrides it): ~700 site-case
reductions of ~3 MB."""

STALE_TMP_S = 3600.0
"""A writer's temporary file older than this (s) was left by a writer that died before its
rename (a whole entry is written in well under a second): the next eviction deletes it."""

LEGACY_SUFFIXES = (".npz",)
"""Entries of earlier formats, never read again: counted against the bound, and evicted first.
Only a file named as the cache names its entries (a key, ``KEY_LENGTH`` hex digits) is one: a
directory ``RAILTWIN_TRACK_CACHE`` names may hold ``.npz`` files of the user's own."""

KEY_LENGTH = 40
"""Hex digits of a key (``key``): the stem of every entry the cache writes."""

MAGIC = b"RTTRACK1"
ALIGN = 64
"""Bytes: the payload and every array in it start at a multiple of this in the file (part of
the format); read into a buffer aligned as ``lanes.ALIGN`` (the same cache line), the arrays
start on cache lines in memory too."""


def key(inputs: Any) -> str:
    """The entry's name: a SHA-256 of the inputs' ``repr`` and ``FORMAT``."""
    return hashlib.sha256(repr((FORMAT, inputs)).encode()).hexdigest()[:KEY_LENGTH]


def _legacy(fname: str) -> bool:
    """Whether ``fname`` is an entry of an earlier format (``LEGACY_SUFFIXES``, a key's name)."""
    for suffix in LEGACY_SUFFIXES:
        stem = fname[: -len(suffix)]
        if fname.endswith(suffix) and len(stem) == KEY_LENGTH:
            return all(c in "0123456789abcdef" for c in stem)
    return False


def directory() -> Path | None:
    """Where entries live, or None when the cache is off."""
    env = os.environ.get("RAILTWIN_TRACK_CACHE")
    if env == "off":
        return None
    if env:
        return Path(env)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "track-cache"
    return Path.home() / ".cache" / "railtwin" / "track"


def load(name: str, fields: tuple[str, ...] = ()) -> dict[str, np.ndarray] | None:
    """The arrays of entry ``name``, or None: absent, unreadable, truncated, damaged, foreign,
    missing one of ``fields``, or the cache off."""
    d = directory()
    if d is None:
        return None
    path = d / f"{name}{SUFFIX}"
    try:
        data = _read(path)
        arrays = _parse(data) if data is not None else None
    except Exception:  # anything a foreign or damaged file raises
        return None
    if arrays is None or any(f not in arrays for f in fields):
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # recently used: evicted last
    return arrays


TOUCH_INTERVAL = 600.0
"""s between two touches of one entry by a process that serves it from memory (``touch``)."""

TOUCHED_KEPT = 64
"""Entries whose last touch ``touch`` remembers, the most recent: a calibrating twin reduces
a new track for each step of its estimate, and the memory would otherwise grow with them
(a forgotten entry is merely touched again on its next use)."""

_touched: OrderedDict[Hashable, float] = OrderedDict()


def touch(inputs: Hashable) -> bool:
    """Mark the entry of ``inputs`` (``key(inputs)``) recently used (its mtime) for a process
    that holds it in memory and so never reads it: a long-running twin's track would
    otherwise be evicted as the least recently used while in use. At most once per
    ``TOUCH_INTERVAL`` an entry (one ``utime``; the key is hashed only then, not on every
    call); True if it touched the file now."""
    now = time.monotonic()
    last = _touched.get(inputs)
    if last is not None and now - last < TOUCH_INTERVAL:
        return False  # before ``directory()``, which builds a Path from the environment
    d = directory()
    if d is None:
        return False
    _touched[inputs] = now
    _touched.move_to_end(inputs)
    while len(_touched) > TOUCHED_KEPT:
        _touched.popitem(last=False)
    try:
        os.utime(d / f"{key(inputs)}{SUFFIX}")
    except OSError:  # gone or unwritable: the next read reduces it again
        return False
    return True


def max_bytes() -> int:
    """The cache's bound in bytes, from ``RAILTWIN_TRACK_CACHE_MAX_MB`` (a number ≥ 0) or
    ``MAX_MB``; an unreadable value is the default (the cache never stops the physics)."""
    raw = os.environ.get("RAILTWIN_TRACK_CACHE_MAX_MB")
    mb = float(MAX_MB)
    if raw:
        with contextlib.suppress(ValueError):
            v = float(raw)
            if v >= 0.0 and v == v and v != float("inf"):
                mb = v
    return int(mb * 1024 * 1024)


def evict(d: Path, keep: str = "") -> int:
    """Delete entries of ``d`` until they fit ``max_bytes()``: earlier formats first, then the
    least recently used, never ``keep`` (a file name). Returns how many this call deleted.

    Workers may evict at once: an entry another one deleted meanwhile (between the scan and
    the unlink, or while it was scanned) counts as gone, so that they do not delete the next
    entries in its place."""
    entries = []
    now = time.time()
    try:
        with os.scandir(d) as it:
            for e in it:
                if e.name.endswith(".tmp"):  # a writer's file aside: stale if it crashed
                    with contextlib.suppress(OSError):
                        if now - e.stat().st_mtime > STALE_TMP_S:
                            os.unlink(e.path)
                    continue
                legacy = _legacy(e.name)
                if not (e.name.endswith(SUFFIX) or legacy):
                    continue
                try:
                    if not e.is_file():
                        continue
                    st = e.stat()
                except OSError:  # deleted by another worker since the listing
                    continue
                entries.append((not legacy, st.st_mtime, e.name, st.st_size))
    except OSError:
        return 0
    total = sum(e[3] for e in entries)
    limit = max_bytes()
    deleted = 0
    for _, _, fname, size in sorted(entries):
        if total <= limit:
            break
        if fname == keep:
            continue
        try:
            os.unlink(d / fname)
            deleted += 1
        except FileNotFoundError:
            pass  # another worker evicted it meanwhile: gone all the same
        except OSError:
            continue
        total -= size
    return deleted


def _read(path: Path) -> NDArray[np.uint8] | None:
    """The file's bytes in one writable buffer starting on an ``ALIGN``-byte boundary (the
    arrays are views on it, so they start on cache lines too), read in place and not zeroed
    first: ``bytearray(path.read_bytes())`` copied them once more into fresh pages (a 21 MB
    entry: 28 -> 3.3 ms), and a zeroed ``bytearray`` cost a pass more (0.16 ms of the site
    case's 2.5 MB); None if the file changed size while read."""
    with path.open("rb") as f:
        size = os.fstat(f.fileno()).st_size
        data = aligned_empty(size, np.uint8)
        if f.readinto(data.data) != size:
            return None
    return data


def _parse(data: NDArray[np.uint8]) -> dict[str, np.ndarray] | None:
    n = len(MAGIC)
    if len(data) < n + 8 or bytes(data[:n]) != MAGIC:
        return None
    hl = int.from_bytes(bytes(data[n : n + 8]), "little")
    head = json.loads(bytes(data[n + 8 : n + 8 + hl]))
    start = n + 8 + hl
    payload = data.data[start:]
    if len(payload) != head["payload"] or zlib.crc32(payload) != head["crc32"]:
        return None
    out = {}
    for field, dtype, shape, offset in head["arrays"]:
        dt = np.dtype(dtype)
        count = math.prod(shape)
        out[field] = np.frombuffer(data, dt, count, start + offset).reshape(shape)
    return out


def save(name: str, arrays: dict[str, Any]) -> None:
    """Write entry ``name`` atomically; a cache that cannot be written is skipped silently."""
    d = directory()
    if d is None:
        return
    parts = []
    table = []
    offset = 0
    for field, value in arrays.items():
        a = np.asarray(value)
        a = np.ascontiguousarray(a) if a.ndim else a  # (ascontiguousarray makes 0-d 1-d)
        pad = -offset % ALIGN
        parts.append(bytes(pad))
        offset += pad
        table.append([field, a.dtype.str, list(a.shape), offset])
        parts.append(a.tobytes())
        offset += a.nbytes
    payload = b"".join(parts)
    head = json.dumps({"arrays": table, "payload": len(payload), "crc32": zlib.crc32(payload)})
    hb = head.encode()
    hb += b" " * (-(len(MAGIC) + 8 + len(hb)) % ALIGN)  # the payload starts aligned
    tmp = None
    try:
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            f.write(MAGIC + len(hb).to_bytes(8, "little") + hb)
            f.write(payload)
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would keep other users of a shared cache out
        os.replace(tmp, d / f"{name}{SUFFIX}")
        tmp = None
    except OSError:
        return
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    evict(d, keep=f"{name}{SUFFIX}")
