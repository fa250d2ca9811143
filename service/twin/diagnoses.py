"""The diagnoses a twin made, kept for catch-up: ``railtwin/<site>/diagnoses?since=<unix s>``.

A consumer that was down (the fleet service, killed and restarted) asks each twin for
the diagnoses it made since a time and gets one reply per ``Diagnosis``, each on its own
concrete key ``railtwin/<site>/diagnosis/<passage_id>`` (so the querier must accept
replies on keys other than the query's: ``accept_replies=zenoh.ReplyKeyExpr.ANY``, or
the parameter ``_anyke``: ``?since=T;_anyke``). A diagnosis is returned when it was made at or after
``since`` *or* its passage's timestamp is at or after ``since``: a consumer may count
in either clock, and files each diagnosis by ``(site_id, passage_id)`` anyway.

The store is SQLite: a file beside the site's rail state when the twin keeps state
(``<state dir>/<site_id>-diagnoses.sqlite``, committed per diagnosis, WAL, so it
survives kill -9 and restarts), else in memory (this run only). Diagnoses made more
than ``keep_seconds`` ago are pruned, and at most ``max_rows`` are kept.

    >>> store = DiagnosisStore(None)
    >>> store.add("p1", made_at=100.0, timestamp=50.0, data=b'{"passage_id": "p1"}')
    >>> store.add("p2", made_at=200.0, timestamp=190.0, data=b'{"passage_id": "p2"}')
    >>> [pid for pid, _ in store.since(150.0)], [pid for pid, _ in store.since(60.0)]
    (['p2'], ['p1', 'p2'])
"""

from __future__ import annotations

import math
import sqlite3
import threading
from pathlib import Path

SCHEMA = """
CREATE TABLE IF NOT EXISTS diagnoses (
    passage_id TEXT PRIMARY KEY,
    made_at REAL NOT NULL,
    timestamp REAL,
    data BLOB NOT NULL
);
CREATE INDEX IF NOT EXISTS diagnoses_made_at ON diagnoses (made_at);
CREATE INDEX IF NOT EXISTS diagnoses_timestamp ON diagnoses (timestamp);
"""

DEFAULT_KEEP_SECONDS = 90 * 86400.0
"""Diagnoses are kept for catch-up this long after they were made (90 days)."""

DEFAULT_MAX_ROWS = 1_000_000
"""At most this many diagnoses are kept (the oldest go first)."""

MAX_REPLIES = 100_000
"""A catch-up query returns at most this many diagnoses (the oldest first)."""

PRUNE_EVERY = 1000
"""Pruning runs once every this many additions."""


class SinceError(ValueError):
    """A ``since`` parameter that is not a finite number of UNIX seconds."""


def parse_since(text: str | None) -> float:
    """The ``since`` of a catch-up query, in UNIX s; absent means everything kept."""
    if text is None or text == "":
        return -math.inf
    try:
        value = float(text)
    except ValueError:
        raise SinceError(f"since={text[:40]!r} is not a number of UNIX seconds") from None
    if not math.isfinite(value):
        raise SinceError(f"since={text[:40]!r} is not a finite number of UNIX seconds")
    return value


class DiagnosisStore:
    """The diagnoses made by one twin; thread-safe (the worker adds, Zenoh queries)."""

    def __init__(
        self,
        path: Path | None,
        *,
        keep_seconds: float = DEFAULT_KEEP_SECONDS,
        max_rows: int = DEFAULT_MAX_ROWS,
    ) -> None:
        self.path = path
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
        self._db = sqlite3.connect(
            ":memory:" if path is None else path, isolation_level=None, check_same_thread=False
        )
        if path is not None:
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=NORMAL")
        self._db.executescript(SCHEMA)
        self._lock = threading.Lock()
        self.keep_seconds = keep_seconds
        self.max_rows = max_rows
        self._added = 0

    def add(self, passage_id: str, *, made_at: float, timestamp: float | None, data: bytes) -> None:
        """Keep one diagnosis (its JSON); a passage diagnosed again replaces the former."""
        with self._lock:
            self._db.execute(
                "INSERT OR REPLACE INTO diagnoses VALUES (?, ?, ?, ?)",
                (passage_id, made_at, timestamp, data),
            )
            self._added += 1
            if self._added % PRUNE_EVERY == 0:
                self._prune(made_at)

    def _prune(self, now: float) -> None:
        self._db.execute("DELETE FROM diagnoses WHERE made_at < ?", (now - self.keep_seconds,))
        self._db.execute(
            "DELETE FROM diagnoses WHERE passage_id IN (SELECT passage_id FROM diagnoses "
            "ORDER BY made_at DESC LIMIT -1 OFFSET ?)",
            (self.max_rows,),
        )

    def since(self, since: float, limit: int = MAX_REPLIES) -> list[tuple[str, bytes]]:
        """(passage_id, JSON) of the diagnoses made, or of passages, at or after ``since``;
        oldest made first, at most ``limit``."""
        with self._lock:
            rows = self._db.execute(
                "SELECT passage_id, data FROM diagnoses WHERE made_at >= ? OR timestamp >= ? "
                "ORDER BY made_at, passage_id LIMIT ?",
                (since, since, limit),
            ).fetchall()
        return [(str(pid), bytes(data)) for pid, data in rows]

    def count(self) -> int:
        with self._lock:
            return int(self._db.execute("SELECT COUNT(*) FROM diagnoses").fetchone()[0])

    def close(self) -> None:
        with self._lock:
            self._db.close()
