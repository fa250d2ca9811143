"""The fleet's database: every wheel's history, the sites, the wheels and the alarms.

``open_store(db)`` opens SQLite for a file path (stdlib ``sqlite3``, WAL journal) and
PostgreSQL for a ``postgresql://`` URL (psycopg 3, the ``postgres`` extra); both get the
same schema through ``service.fleet.migrations``. A diagnosis is stored once, keyed by
(site_id, passage_id): inserting it again changes nothing.

All access goes through one connection behind a lock (the service's ingest thread,
its queryables and the dashboard share it).

    >>> s = open_store(":memory:")
    >>> s.schema_version(), s.count()
    (5, 0)
    >>> s.close()
"""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

from service.fleet.entry import Entry
from service.fleet.migrations import (
    LATEST,
    MIGRATIONS,
    MIGRATIONS_TABLE,
    SITE_BACKFILL,
    WHEEL_BACKFILL,
)

Dialect = Literal["sqlite", "postgresql"]

ENTRY_COLUMNS = (
    "site_id",
    "passage_id",
    "wheel_id",
    "vehicle_id",
    "wheelset",
    "side",
    "timestamp",
    "verdict",
    "flat_kind",
    "flat_length",
    "flat_length_low",
    "flat_length_high",
    "peak_force_measured",
    "peak_force_at_line_speed",
    "speed",
    "distance_run",
    "received_at",
    "body",
)
_COLS = ", ".join(ENTRY_COLUMNS)
_ALARM_COLS = "wheel_id, kind, level, episode, raised_at, data_time, cleared_at, body"
"""The alarm table's columns in ``AlarmRow``'s order."""
_INSERT = (
    f"INSERT INTO diagnosis ({_COLS}) VALUES ({', '.join('?' * len(ENTRY_COLUMNS))}) "
    "ON CONFLICT (site_id, passage_id) DO NOTHING"
)
_SITE_UPSERT = """INSERT INTO site (site_id, last_timestamp, last_passage_id, last_verdict, diagnoses)
VALUES (?, ?, ?, ?, 1)
ON CONFLICT (site_id) DO UPDATE SET
  diagnoses = site.diagnoses + 1,
  last_passage_id = CASE WHEN excluded.last_timestamp >= site.last_timestamp
                         THEN excluded.last_passage_id ELSE site.last_passage_id END,
  last_verdict = CASE WHEN excluded.last_timestamp >= site.last_timestamp
                      THEN excluded.last_verdict ELSE site.last_verdict END,
  last_timestamp = CASE WHEN excluded.last_timestamp >= site.last_timestamp
                        THEN excluded.last_timestamp ELSE site.last_timestamp END"""
_WHEEL_UPSERT = """INSERT INTO wheel (wheel_id, vehicle_id, wheelset, side, last_timestamp,
  last_verdict, alarmed_level, episode, alarms_due) VALUES (?, ?, ?, ?, ?, ?, 0, 0, 1)
ON CONFLICT (wheel_id) DO UPDATE SET
  alarms_due = 1,
  last_verdict = CASE WHEN excluded.last_timestamp >= wheel.last_timestamp
                      THEN excluded.last_verdict ELSE wheel.last_verdict END,
  last_timestamp = CASE WHEN excluded.last_timestamp >= wheel.last_timestamp
                        THEN excluded.last_timestamp ELSE wheel.last_timestamp END"""


class StoreError(RuntimeError):
    """The database cannot be opened or used (message says which and why)."""


@dataclass(frozen=True)
class Reanalysed:
    """One passage re-analysed with one model version: its diagnosis (``body``, the
    Diagnosis JSON, and ``verdict``) or why it could not be diagnosed (``error``)."""

    site_id: str
    passage_id: str
    model_version: str
    wheel_id: str | None
    timestamp: float | None
    verdict: str | None
    error: str | None
    body: str | None


_REANALYSIS_COLS = "site_id, passage_id, model_version, wheel_id, timestamp, verdict, error, body"


@dataclass(frozen=True)
class SiteRow:
    site_id: str
    last_timestamp: float
    last_passage_id: str
    last_verdict: str
    diagnoses: int


@dataclass(frozen=True)
class WheelRow:
    wheel_id: str
    vehicle_id: str
    wheelset: int
    side: str
    last_timestamp: float
    last_verdict: str
    alarmed_level: int
    episode: int


@dataclass(frozen=True)
class AlarmRow:
    wheel_id: str
    kind: str
    level: str
    episode: int
    raised_at: float
    data_time: float
    cleared_at: float | None
    body: str

    def json(self) -> dict[str, Any]:
        doc: dict[str, Any] = json.loads(self.body)
        doc["cleared_at"] = self.cleared_at
        return doc


class Store:
    """History, sites, wheels and alarms in one SQL database (see module doc)."""

    def __init__(self, conn: Any, dialect: Dialect, where: str) -> None:
        self._conn = conn
        self.dialect: Dialect = dialect
        self.where = where
        self._lock = threading.RLock()

    # --- low level ---------------------------------------------------------------------

    def _sql(self, sql: str) -> str:
        return sql.replace("?", "%s") if self.dialect == "postgresql" else sql

    def _rows(self, sql: str, params: Sequence[Any] = ()) -> list[tuple[Any, ...]]:
        with self._lock:
            cur = self._conn.execute(self._sql(sql), tuple(params))
            return list(cur.fetchall())

    @contextmanager
    def _transaction(self) -> Iterator[Any]:
        """A cursor inside one transaction (committed at the end, rolled back on error)."""
        with self._lock:
            if self.dialect == "sqlite":
                self._conn.execute("BEGIN IMMEDIATE")
                try:
                    yield self._conn
                except BaseException:
                    self._conn.execute("ROLLBACK")
                    raise
                self._conn.execute("COMMIT")
            else:
                with self._conn.transaction():
                    yield self._conn

    def _exec(self, cur: Any, sql: str, params: Sequence[Any] = ()) -> int:
        return int(cur.execute(self._sql(sql), tuple(params)).rowcount)

    # --- schema ------------------------------------------------------------------------

    def schema_version(self) -> int:
        rows = self._rows("SELECT MAX(version) FROM schema_migrations")
        return int(rows[0][0] or 0)

    def migrate(self, target: int = LATEST) -> list[int]:
        """Apply the missing migrations up to ``target``; the versions applied."""
        with self._lock:
            self._conn.execute(MIGRATIONS_TABLE)
            done = {int(r[0]) for r in self._rows("SELECT version FROM schema_migrations")}
            applied = []
            for m in MIGRATIONS:
                if m.version in done or m.version > target:
                    continue
                with self._transaction() as cur:
                    for stmt in m.statements:
                        self._exec(cur, stmt)
                    self._exec(
                        cur,
                        "INSERT INTO schema_migrations (version, description, "
                        "applied_at) VALUES (?, ?, ?)",
                        (m.version, m.description, time.time()),
                    )
                applied.append(m.version)
            if max(done | set(applied), default=0) > LATEST:
                raise StoreError(
                    f"{self.where}: database schema version {max(done)} is newer than this "
                    f"railtwin's ({LATEST}): upgrade railtwin"
                )
            return applied

    def close(self) -> None:
        with self._lock:
            self._conn.close()

    # --- writing -----------------------------------------------------------------------

    def insert(self, entries: Sequence[Entry]) -> list[Entry]:
        """Store ``entries`` in one transaction; the ones that were new (others: already
        stored under the same (site_id, passage_id), left as they were)."""
        new: list[Entry] = []
        with self._transaction() as cur:
            for e in entries:
                if self._exec(cur, _INSERT, [getattr(e, c) for c in ENTRY_COLUMNS]) != 1:
                    continue
                new.append(e)
                self._exec(cur, _SITE_UPSERT, (e.site_id, e.timestamp, e.passage_id, e.verdict))
                if e.wheel_id is not None:
                    self._exec(
                        cur,
                        _WHEEL_UPSERT,
                        (e.wheel_id, e.vehicle_id, e.wheelset, e.side, e.timestamp, e.verdict),
                    )
        return new

    def bulk_insert(self, entries: Sequence[Entry]) -> None:
        """Import many diagnoses at once (another store's, a benchmark's): the rows in one
        statement (PostgreSQL: COPY), then the site and wheel tables rebuilt from them
        (wheels keep their alarm state). No alarm is evaluated. Rows already stored are kept.
        """
        rows = [tuple(getattr(e, c) for c in ENTRY_COLUMNS) for e in entries]
        with self._transaction() as cur:
            if self.dialect == "sqlite":
                cur.executemany(_INSERT, rows)
            else:
                self._exec(
                    cur, "CREATE TEMP TABLE import_diagnosis (LIKE diagnosis) ON COMMIT DROP"
                )
                with cur.cursor().copy(f"COPY import_diagnosis ({_COLS}) FROM STDIN") as copy:
                    for r in rows:
                        copy.write_row(r)
                self._exec(
                    cur,
                    f"INSERT INTO diagnosis ({_COLS}) SELECT {_COLS} FROM "
                    "import_diagnosis ON CONFLICT (site_id, passage_id) DO NOTHING",
                )
            self._exec(cur, "DELETE FROM site")
            self._exec(cur, SITE_BACKFILL)
            self._exec(
                cur,
                "CREATE TEMP TABLE wheel_state AS SELECT wheel_id, alarmed_level, "
                "episode FROM wheel",
            )
            self._exec(cur, "DELETE FROM wheel")
            self._exec(cur, WHEEL_BACKFILL)
            self._exec(
                cur,
                "UPDATE wheel SET alarmed_level = (SELECT s.alarmed_level FROM "
                "wheel_state s WHERE s.wheel_id = wheel.wheel_id), episode = (SELECT "
                "s.episode FROM wheel_state s WHERE s.wheel_id = wheel.wheel_id) "
                "WHERE wheel_id IN (SELECT wheel_id FROM wheel_state)",
            )
            self._exec(cur, "DROP TABLE wheel_state")

    def add_reanalysed(self, rows: Sequence[Reanalysed], entries: Sequence[Entry] = ()) -> int:
        """Store re-analysed passages in one transaction, each once per (site, passage,
        model version); ``entries`` (their diagnoses) go to the history as ``insert`` puts
        them, where the passage has none yet. Returns how many rows were new."""
        now = time.time()
        new = 0
        with self._transaction() as cur:
            for r in rows:
                new += self._exec(
                    cur,
                    f"INSERT INTO reanalysis ({_REANALYSIS_COLS}, stored_at) VALUES "
                    "(?, ?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (site_id, passage_id, "
                    "model_version) DO NOTHING",
                    (
                        r.site_id,
                        r.passage_id,
                        r.model_version,
                        r.wheel_id,
                        r.timestamp,
                        r.verdict,
                        r.error,
                        r.body,
                        now,
                    ),
                )
        if entries:
            self.insert(entries)
        return new

    def reanalysed(self, site_id: str, model_version: str) -> list[Reanalysed]:
        """Every passage of ``site_id`` re-analysed with ``model_version``."""
        rows = self._rows(
            f"SELECT {_REANALYSIS_COLS} FROM reanalysis WHERE site_id = ? AND model_version = ? "
            "ORDER BY passage_id",
            (site_id, model_version),
        )
        return [Reanalysed(*r) for r in rows]

    def verdicts_before(self, site_id: str, model_version: str) -> dict[str, tuple[str, str]]:
        """passage id → (verdict, model version) of the latest diagnosis of each passage of
        ``site_id`` made with another model than ``model_version``: re-analysed, else the
        fleet's own (``"unversioned"`` when it predates schema 1.3)."""
        out: dict[str, tuple[str, str]] = {}
        for pid, verdict, body in self._rows(
            "SELECT passage_id, verdict, body FROM diagnosis WHERE site_id = ?", (site_id,)
        ):
            try:
                version = json.loads(body).get("model_version") or {}
            except (ValueError, AttributeError):
                version = {}
            key = "/".join(str(version.get(k)) for k in ("package", "track", "site"))
            if not version:
                key = "unversioned"
            if key != model_version:
                out[pid] = (verdict, key)
        for pid, verdict, version in self._rows(
            "SELECT passage_id, verdict, model_version FROM reanalysis WHERE site_id = ? AND "
            "model_version <> ? AND verdict IS NOT NULL ORDER BY stored_at",
            (site_id, model_version),
        ):
            out[pid] = (verdict, version)
        return out

    def set_speed(self, site_id: str, passage_id: str, speed: float) -> bool:
        """Fill a stored diagnosis's speed (from its PassageResult); True if one was."""
        with self._transaction() as cur:
            return (
                self._exec(
                    cur,
                    "UPDATE diagnosis SET speed = ? WHERE site_id = ? AND "
                    "passage_id = ? AND speed IS NULL",
                    (speed, site_id, passage_id),
                )
                == 1
            )

    def set_wheel_alarm_state(self, wheel_id: str, alarmed_level: int, episode: int) -> None:
        """The wheel's alarm state after an evaluation; its alarms are no longer due."""
        with self._transaction() as cur:
            self._exec(
                cur,
                "UPDATE wheel SET alarmed_level = ?, episode = ?, alarms_due = 0 "
                "WHERE wheel_id = ?",
                (alarmed_level, episode, wheel_id),
            )

    def wheels_due(self, limit: int = 10_000) -> list[str]:
        """Wheels with a diagnosis stored whose alarms were not evaluated (the service
        stopped between the two): the oldest first, at most ``limit``."""
        rows = self._rows(
            "SELECT wheel_id FROM wheel WHERE alarms_due = 1 ORDER BY last_timestamp LIMIT ?",
            (limit,),
        )
        return [str(r[0]) for r in rows]

    def add_alarm(self, row: AlarmRow) -> bool:
        """Record an alarm; False if this (wheel, kind, level, episode) was raised before."""
        with self._transaction() as cur:
            return (
                self._exec(
                    cur,
                    "INSERT INTO alarm (wheel_id, kind, level, episode, raised_at, data_time, "
                    "cleared_at, body) VALUES (?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT "
                    "(wheel_id, kind, level, episode) DO NOTHING",
                    (
                        row.wheel_id,
                        row.kind,
                        row.level,
                        row.episode,
                        row.raised_at,
                        row.data_time,
                        row.cleared_at,
                        row.body,
                    ),
                )
                == 1
            )

    def mark_published(self, wheel_id: str, kind: str, level: str, episode: int, at: float) -> None:
        """Record that the alarm (wheel_id, kind, level, episode) was published at ``at``
        (the outbox's second half)."""
        with self._transaction() as cur:
            self._exec(
                cur,
                "UPDATE alarm SET published_at = ? WHERE wheel_id = ? AND kind = ? AND "
                "level = ? AND episode = ? AND published_at IS NULL",
                (at, wheel_id, kind, level, episode),
            )

    def unpublished_alarms(self, limit: int = 1000) -> list[AlarmRow]:
        """Alarms stored but not yet published, oldest first (at most ``limit``)."""
        rows = self._rows(
            f"SELECT {_ALARM_COLS} FROM alarm WHERE published_at IS NULL "
            "ORDER BY raised_at LIMIT ?",
            [limit],
        )
        return [AlarmRow(*r) for r in rows]

    def clear_alarms(self, wheel_id: str, at: float) -> int:
        """Close the wheel's open alarms (its verdict went back to ok); how many."""
        with self._transaction() as cur:
            return self._exec(
                cur,
                "UPDATE alarm SET cleared_at = ? WHERE wheel_id = ? AND cleared_at IS NULL",
                (at, wheel_id),
            )

    # --- reading -----------------------------------------------------------------------

    def count(self) -> int:
        return int(self._rows("SELECT COUNT(*) FROM diagnosis")[0][0])

    def history(self, wheel_id: str, limit: int | None = None) -> list[Entry]:
        """The wheel's diagnoses, oldest first (the last ``limit`` if given)."""
        if limit is None:
            rows = self._rows(
                f"SELECT {_COLS} FROM diagnosis WHERE wheel_id = ? "
                "ORDER BY timestamp, site_id, passage_id",
                (wheel_id,),
            )
        else:
            rows = self._rows(
                f"SELECT {_COLS} FROM diagnosis WHERE wheel_id = ? "
                "ORDER BY timestamp DESC, site_id DESC, passage_id DESC LIMIT ?",
                (wheel_id, int(limit)),
            )[::-1]
        return [Entry(*r) for r in rows]

    def entry(self, site_id: str, passage_id: str) -> Entry | None:
        rows = self._rows(
            f"SELECT {_COLS} FROM diagnosis WHERE site_id = ? AND passage_id = ?",
            (site_id, passage_id),
        )
        return Entry(*rows[0]) if rows else None

    def latest_times(self) -> tuple[float, float] | None:
        """(latest passage timestamp, latest received_at) stored, None when empty."""
        t = self._rows("SELECT MAX(last_timestamp) FROM site")[0][0]
        r = self._rows("SELECT MAX(received_at) FROM diagnosis")[0][0]
        return None if t is None or r is None else (float(t), float(r))

    def sites(self) -> list[SiteRow]:
        return [
            SiteRow(*r)
            for r in self._rows(
                "SELECT site_id, last_timestamp, last_passage_id, last_verdict, diagnoses "
                "FROM site ORDER BY site_id"
            )
        ]

    def wheel(self, wheel_id: str) -> WheelRow | None:
        rows = self._rows(
            "SELECT wheel_id, vehicle_id, wheelset, side, last_timestamp, "
            "last_verdict, alarmed_level, episode FROM wheel WHERE wheel_id = ?",
            (wheel_id,),
        )
        return WheelRow(*rows[0]) if rows else None

    def wheels(self, vehicle_id: str | None = None, limit: int = 500) -> list[WheelRow]:
        """Wheels of ``vehicle_id`` (all if None; a prefix ending in ``*`` matches several)."""
        sql = (
            "SELECT wheel_id, vehicle_id, wheelset, side, last_timestamp, last_verdict, "
            "alarmed_level, episode FROM wheel"
        )
        params: list[Any] = []
        if vehicle_id is not None:
            if vehicle_id.endswith("*"):
                sql += " WHERE vehicle_id >= ? AND vehicle_id < ?"
                prefix = vehicle_id[:-1]
                params += [prefix, prefix + "\U0010ffff"]
            else:
                sql += " WHERE vehicle_id = ?"
                params.append(vehicle_id)
        sql += " ORDER BY vehicle_id, wheelset, side LIMIT ?"
        params.append(limit)
        return [WheelRow(*r) for r in self._rows(sql, params)]

    def alarms(
        self, open_only: bool = True, wheel_id: str | None = None, limit: int = 1000
    ) -> list[AlarmRow]:
        sql = f"SELECT {_ALARM_COLS} FROM alarm"
        cond, params = [], []
        if open_only:
            cond.append("cleared_at IS NULL")
        if wheel_id is not None:
            cond.append("wheel_id = ?")
            params.append(wheel_id)
        if cond:
            sql += " WHERE " + " AND ".join(cond)
        sql += " ORDER BY raised_at DESC LIMIT ?"
        return [AlarmRow(*r) for r in self._rows(sql, [*params, limit])]


def open_store(db: str, *, migrate: bool = True) -> Store:
    """The store at ``db``: ``postgresql://...`` (or ``postgres://``) or a SQLite path."""
    if db.startswith(("postgresql://", "postgres://")):
        try:
            import psycopg
        except ImportError:
            raise StoreError(
                "--db postgresql://... needs psycopg 3: pip install 'railtwin[postgres]'"
            ) from None
        try:
            conn = psycopg.connect(db, autocommit=True)
        except psycopg.Error as exc:
            raise StoreError(f"cannot connect to PostgreSQL: {str(exc).strip()}") from None
        store = Store(conn, "postgresql", db.split("@")[-1])
    else:
        try:
            lite = sqlite3.connect(db, check_same_thread=False, isolation_level=None)
            lite.execute("PRAGMA journal_mode=WAL")
            lite.execute("PRAGMA synchronous=NORMAL")
            lite.execute("PRAGMA busy_timeout=5000")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot open SQLite database {db}: {exc}") from None
        store = Store(lite, "sqlite", db)
    if migrate:
        store.migrate()
    return store
