"""The site's rail state on disk: dents, revision and the passages already applied (SQLite).

A plastic (``hertz_plastic``) site's rail is history: every wheel that yielded it left a
dent the next one rides over. ``RailStore`` keeps it in ``<state dir>/<site_id>.sqlite``,
committed once per passage (WAL journal, ``synchronous=NORMAL``: a committed passage
survives kill -9 of every process of the service; after a power cut the last few
passages before it may be lost, not the file), and restored at start. A passage id already applied is
recognised and never applied twice. A state file written for another site, or by another
model version, is refused with a message saying which.

    >>> import tempfile, numpy as np
    >>> from pathlib import Path
    >>> d = Path(tempfile.mkdtemp())
    >>> s = RailStore(d, "km12", "1")
    >>> s.load() is None
    True
    >>> s.commit("t1-a0-r", 1, np.array([0.0, 1.0]), np.array([0.0, -1e-5]))
    >>> s.close()
    >>> s = RailStore(d, "km12", "1")
    >>> st = s.load()
    >>> st.revision, st.y.tolist(), s.applied_revision("t1-a0-r"), s.applied_revision("nope")
    (1, [0.0, -1e-05], 1, None)
"""

from __future__ import annotations

import sqlite3
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

__all__ = ["RailState", "RailStore", "StateMismatchError"]

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS rail (id INTEGER PRIMARY KEY CHECK (id = 1), revision INTEGER NOT NULL,
                                 x BLOB NOT NULL, y BLOB NOT NULL);
CREATE TABLE IF NOT EXISTS applied (passage_id TEXT PRIMARY KEY, revision INTEGER NOT NULL);
"""


class StateMismatchError(ValueError):
    """The state file belongs to another site or model version."""


@dataclass(frozen=True)
class RailState:
    """The stored rail: samples (x, y) in m after ``revision`` dented passages."""

    revision: int
    x: NDArray[np.float64]
    y: NDArray[np.float64]


class RailStore:
    """One site's state database (not thread-safe: the physics owns it)."""

    def __init__(self, directory: Path, site_id: str, model_version: str) -> None:
        directory.mkdir(parents=True, exist_ok=True)
        self.path = directory / f"{site_id}.sqlite"
        self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._lock = threading.Lock()
        self._db.executescript(SCHEMA)
        meta = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
        if not meta:
            with self._db:
                self._db.execute("BEGIN")
                self._db.executemany("INSERT INTO meta VALUES (?, ?)",
                                     [("site_id", site_id), ("model_version", model_version)])
        elif meta.get("site_id") != site_id:
            raise StateMismatchError(
                f"state {self.path} belongs to site {meta.get('site_id')!r}, not {site_id!r}")
        elif meta.get("model_version") != model_version:
            raise StateMismatchError(
                f"state {self.path} was written by model version {meta.get('model_version')!r}, "
                f"this is {model_version!r}: move it away to start the rail afresh")

    def load(self) -> RailState | None:
        """The stored rail, or None if no passage has dented it yet."""
        with self._lock:
            row = self._db.execute("SELECT revision, x, y FROM rail WHERE id = 1").fetchone()
        if row is None:
            return None
        rev, x, y = row
        return RailState(int(rev), np.frombuffer(x, dtype=np.float64).copy(),
                         np.frombuffer(y, dtype=np.float64).copy())

    def applied_revision(self, passage_id: str) -> int | None:
        """The rail revision the passage was applied at, or None if it never was."""
        with self._lock:
            row = self._db.execute("SELECT revision FROM applied WHERE passage_id = ?",
                                   (passage_id,)).fetchone()
        return None if row is None else int(row[0])

    def applied_count(self) -> int:
        """How many passages were applied."""
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM applied").fetchone()[0])

    def commit(self, passage_id: str, revision: int, x: NDArray[np.float64] | None = None,
               y: NDArray[np.float64] | None = None) -> None:
        """Record a passage as applied at ``revision`` and, if it dented, the new rail; atomic."""
        with self._lock, self._db:
            self._db.execute("BEGIN IMMEDIATE")
            self._db.execute("INSERT OR REPLACE INTO applied VALUES (?, ?)", (passage_id, revision))
            if x is not None and y is not None:
                self._db.execute(
                    "INSERT OR REPLACE INTO rail VALUES (1, ?, ?, ?)",
                    (revision, np.ascontiguousarray(x, dtype=np.float64).tobytes(),
                     np.ascontiguousarray(y, dtype=np.float64).tobytes()))

    def close(self) -> None:
        with self._lock:
            self._db.close()
