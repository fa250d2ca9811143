"""The site's rail state on disk: dents, revision and the passages already applied (SQLite).

A plastic (``hertz_plastic``) site's rail is history: every wheel that yielded it left a
dent the next one rides over. ``RailStore`` keeps it in ``<state dir>/<site_id>.sqlite``,
committed once per passage (WAL journal, ``synchronous=NORMAL``: a committed passage
survives kill -9 of every process of the service; after a power cut the last few
passages before it may be lost, not the file), and restored at start. A passage id already applied is
recognised and never applied twice.

The state belongs to the physics that dented the rail: the site's length, rail, material,
contact law, foundation and the dent model (``physics_fingerprint``). A state file of another
site, or made with other physics, is refused with a message naming what changed; what does
not change the dents (alarm limits, the diagnosis table, recording options, a railtwin
upgrade) keeps it. The file's own layout has a version (``STATE_SCHEMA``): an older one is
migrated when it is opened, a newer one refused.

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

import hashlib
import json
import sqlite3
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from schemas.site import SiteConfig

__all__ = [
    "DENT_MODEL",
    "STATE_SCHEMA",
    "RailState",
    "RailStore",
    "StateMismatchError",
    "physics_fingerprint",
]

STATE_SCHEMA = 2
"""Layout of the state file. 1: meta ``model_version`` (railtwin version and a digest of the
whole site file: any edit or upgrade refused the state); 2: meta ``state_schema``,
``physics`` (``physics_fingerprint``) and ``written_by``."""

DENT_MODEL = 1
"""Version of the dent model (sim_core's plastic contact law, dent press and rail update).
Bump it when a change makes the same passage leave another dent: stored states are then
refused rather than continued with dents of another model."""

PHYSICS_PARTS = {
    "length": "the site length",
    "rail": "the rail",
    "material": "the material",
    "contact": "the contact law",
    "foundation": "the foundation",
    "dent_model": "the dent model (railtwin's plastic model changed)",
}
"""What the rail's dents depend on, as named in a refusal."""


def physics_fingerprint(site: SiteConfig) -> str:
    """What the site's dents depend on, as canonical JSON (the rail as a digest: a sampled
    rail may hold 10^6 points). Fields left at their defaults are left out, so that a field
    a later version adds (with a default) does not count as a change."""
    rail = site.rail.model_dump_json(exclude_defaults=True).encode()
    parts: dict[str, Any] = {
        "length": site.length,
        "rail": "sha256:" + hashlib.sha256(rail).hexdigest()[:16],
        "material": site.material.model_dump(mode="json", exclude_defaults=True),
        "contact": site.contact,
        "foundation": site.foundation.model_dump(mode="json", exclude_defaults=True),
        "dent_model": DENT_MODEL,
    }
    return json.dumps(parts, sort_keys=True, separators=(",", ":"))


def _changed(stored: str, now: str) -> str:
    """Which parts of the physics differ between two fingerprints, in words."""
    try:
        a, b = json.loads(stored), json.loads(now)
    except ValueError:
        return "the physics"
    if not (isinstance(a, dict) and isinstance(b, dict)):
        return "the physics"
    keys = [k for k in sorted(set(a) | set(b)) if a.get(k) != b.get(k)]
    return ", ".join(PHYSICS_PARTS.get(k, k) for k in keys) or "the physics"


SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS rail (id INTEGER PRIMARY KEY CHECK (id = 1), revision INTEGER NOT NULL,
                                 x BLOB NOT NULL, y BLOB NOT NULL);
CREATE TABLE IF NOT EXISTS applied (passage_id TEXT PRIMARY KEY, revision INTEGER NOT NULL);
"""


class StateMismatchError(ValueError):
    """The state file belongs to another site, other physics or a newer railtwin."""


@dataclass(frozen=True)
class RailState:
    """The stored rail: samples (x, y) in m after ``revision`` dented passages."""

    revision: int
    x: NDArray[np.float64]
    y: NDArray[np.float64]


class RailStore:
    """One site's state database (not thread-safe: the physics owns it)."""

    def __init__(
        self, directory: Path, site_id: str, physics: str, written_by: str = "unknown"
    ) -> None:
        """Open (or create) ``<directory>/<site_id>.sqlite`` for the physics ``physics``
        (``physics_fingerprint``); ``written_by`` is recorded (the railtwin version)."""
        directory.mkdir(parents=True, exist_ok=True)
        self.path = directory / f"{site_id}.sqlite"
        self.migrated_from: int | None = None
        self._db = sqlite3.connect(self.path, isolation_level=None, check_same_thread=False)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=NORMAL")
        self._lock = threading.Lock()
        self._db.executescript(SCHEMA)
        meta = dict(self._db.execute("SELECT key, value FROM meta").fetchall())
        try:
            self._check(meta, site_id, physics)
        except StateMismatchError:
            self._db.close()
            raise
        if not meta:
            self._set_meta(
                {
                    "site_id": site_id,
                    "state_schema": str(STATE_SCHEMA),
                    "physics": physics,
                    "written_by": written_by,
                }
            )
        elif self.migrated_from is not None:  # the physics is taken as it is now
            self._set_meta(
                {"state_schema": str(STATE_SCHEMA), "physics": physics, "written_by": written_by},
                drop=("model_version",),
            )
        elif meta.get("written_by") != written_by:  # an upgrade keeps the state
            self._set_meta({"written_by": written_by})

    def _check(self, meta: dict[str, str], site_id: str, physics: str) -> None:
        if not meta:
            return
        if meta.get("site_id") != site_id:
            raise StateMismatchError(
                f"state {self.path} belongs to site {meta.get('site_id')!r}, not {site_id!r}"
            )
        try:
            schema = int(meta.get("state_schema", "1"))
        except ValueError:
            schema = STATE_SCHEMA + 1
        if schema > STATE_SCHEMA:
            raise StateMismatchError(
                f"state {self.path} was written by a newer railtwin ({meta.get('written_by')}, "
                f"state schema {meta.get('state_schema')}; this one reads up to "
                f"{STATE_SCHEMA}): upgrade railtwin, or move the state away to start the rail "
                "afresh"
            )
        if schema == 1:
            # schema 1 kept a digest of the whole site file, not of its physics: what changed
            # cannot be told, so the physics is taken as the site file gives it now
            self.migrated_from = 1
            return
        stored = meta.get("physics", "")
        if stored != physics:
            raise StateMismatchError(
                f"state {self.path} holds a rail dented with other physics: "
                f"{_changed(stored, physics)} changed since. Its dents belong to that physics; "
                "move the state away (or give --state another directory) to start the rail "
                "afresh, or restore the site file"
            )

    def _set_meta(self, values: dict[str, str], drop: tuple[str, ...] = ()) -> None:
        with self._db:
            self._db.execute("BEGIN IMMEDIATE")
            for key in drop:
                self._db.execute("DELETE FROM meta WHERE key = ?", (key,))
            self._db.executemany(
                "INSERT OR REPLACE INTO meta VALUES (?, ?)", sorted(values.items())
            )

    def meta(self) -> dict[str, str]:
        """The state file's metadata (site_id, state_schema, physics, written_by)."""
        with self._lock:
            return dict(self._db.execute("SELECT key, value FROM meta").fetchall())

    def load(self) -> RailState | None:
        """The stored rail, or None if no passage has dented it yet."""
        with self._lock:
            row = self._db.execute("SELECT revision, x, y FROM rail WHERE id = 1").fetchone()
        if row is None:
            return None
        rev, x, y = row
        return RailState(
            int(rev),
            np.frombuffer(x, dtype=np.float64).copy(),
            np.frombuffer(y, dtype=np.float64).copy(),
        )

    def applied_revision(self, passage_id: str) -> int | None:
        """The rail revision the passage was applied at, or None if it never was."""
        with self._lock:
            row = self._db.execute(
                "SELECT revision FROM applied WHERE passage_id = ?", (passage_id,)
            ).fetchone()
        return None if row is None else int(row[0])

    def applied_count(self) -> int:
        """How many passages were applied."""
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM applied").fetchone()[0])

    def commit(
        self,
        passage_id: str,
        revision: int,
        x: NDArray[np.float64] | None = None,
        y: NDArray[np.float64] | None = None,
    ) -> None:
        """Record a passage as applied at ``revision`` and, if it dented, the new rail; atomic."""
        with self._lock, self._db:
            self._db.execute("BEGIN IMMEDIATE")
            self._db.execute("INSERT OR REPLACE INTO applied VALUES (?, ?)", (passage_id, revision))
            if x is not None and y is not None:
                self._db.execute(
                    "INSERT OR REPLACE INTO rail VALUES (1, ?, ?, ?)",
                    (
                        revision,
                        np.ascontiguousarray(x, dtype=np.float64).tobytes(),
                        np.ascontiguousarray(y, dtype=np.float64).tobytes(),
                    ),
                )

    def close(self) -> None:
        with self._lock:
            self._db.close()
