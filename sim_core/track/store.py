"""The reduced track kept on disk: a site's track is reduced once per machine, not once a process.

Reducing a track (dense eigen-solves of the finite model: ``sim_core.track.modal``) takes
seconds; its result depends only on the track, the stretch, the cribs and the reduction's
settings. It is written as one ``.npz`` a key (a SHA-256 of those inputs and of
``FORMAT``) to the directory ``RAILTWIN_TRACK_CACHE`` names, else ``track-cache`` beside
numba's cache (``NUMBA_CACHE_DIR``), else ``~/.cache/railtwin/track``; written to a
temporary file and renamed, so a reader never sees half a file. An unreadable or
foreign entry is ignored and replaced. ``RAILTWIN_TRACK_CACHE=off`` switches it off.

Worked example (a key names its inputs and nothing else):

    >>> key(("a", 1.0)) == key(("a", 1.0)), key(("a", 1.0)) == key(("a", 2.0))
    (True, False)
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

FORMAT = "railtwin-track-2"
"""Bumped whenever what a reduction holds or how it is computed changes."""


def key(inputs: Any) -> str:
    """The entry's name: a SHA-256 of the inputs' ``repr`` and ``FORMAT``."""
    return hashlib.sha256(repr((FORMAT, inputs)).encode()).hexdigest()[:40]


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
    """The arrays of entry ``name``, or None: absent, unreadable (a truncated or foreign file
    raises anything from ``EOFError`` to ``zipfile.BadZipFile``), missing one of ``fields``,
    or the cache off."""
    d = directory()
    if d is None:
        return None
    path = d / f"{name}.npz"
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except Exception:
        return None
    if any(f not in arrays for f in fields):
        return None
    return arrays


def save(name: str, arrays: dict[str, np.ndarray]) -> None:
    """Write entry ``name`` atomically; a cache that cannot be written is skipped silently."""
    d = directory()
    if d is None:
        return
    tmp = None
    try:
        d.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=d, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(f, **arrays)  # type: ignore[arg-type]  # numpy stubs: **kwds as bool
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would keep other users of a shared cache out
        os.replace(tmp, d / f"{name}.npz")
        tmp = None
    except OSError:
        return
    finally:
        if tmp is not None:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
