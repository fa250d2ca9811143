"""The fleet database's schema, as numbered migrations (SQLite and PostgreSQL alike).

Each migration runs once, in its own transaction, and is recorded in
``schema_migrations(version, description, applied_at)``; ``migrate`` applies the
missing ones in order, so a database made by an older railtwin is brought up to date
on open. The SQL is the common subset of both dialects (``DOUBLE PRECISION``,
``ON CONFLICT``); placeholders are written ``?`` (``store`` turns them into ``%s``
for PostgreSQL).

Version history:

1. ``diagnosis``: one row per Diagnosis, primary key (site_id, passage_id): nothing is
   stored twice; the wheel's columns, time, verdict, flat, peak forces, speed,
   ``distance_run`` (m; NULL: no message carries an odometer reading yet) and the
   Diagnosis JSON as received; index on (wheel_id, timestamp) for a wheel's history.
2. ``site`` and ``wheel``: per site its last passage and count, per wheel its last
   passage, verdict and alarm state; filled from the diagnoses already stored.
3. ``alarm``: every alarm raised, keyed by (wheel_id, kind, level, episode) so that a
   restarted service never raises the same one again.
4. ``alarm.published_at``: when the alarm was published (NULL: stored, not yet
   published). The alarm table is an outbox: a service that stopped between storing an
   alarm and publishing it publishes it when it starts again. Alarms stored before this
   version count as published at their ``raised_at``.
5. ``reanalysis``: the diagnoses of ``railtwin reanalyse``, one row per (site_id,
   passage_id, model_version): a re-analysis killed and started again stores nothing
   twice, and one model's verdicts can be compared with another's. A passage the new
   model could not diagnose has a row too, with its ``error`` (and no verdict).
"""

from __future__ import annotations

from dataclasses import dataclass

SITE_BACKFILL = """INSERT INTO site (site_id, last_timestamp, last_passage_id, last_verdict, diagnoses)
SELECT d.site_id, d.timestamp, d.passage_id, d.verdict, c.n
FROM diagnosis d
JOIN (SELECT site_id, MAX(timestamp) AS t, COUNT(*) AS n FROM diagnosis GROUP BY site_id) c
  ON d.site_id = c.site_id AND d.timestamp = c.t
WHERE d.passage_id = (SELECT MIN(p.passage_id) FROM diagnosis p
                      WHERE p.site_id = c.site_id AND p.timestamp = c.t)"""
"""Each site's row from the diagnoses stored (its latest passage, its count)."""

WHEEL_BACKFILL = """INSERT INTO wheel (wheel_id, vehicle_id, wheelset, side, last_timestamp, last_verdict,
  alarmed_level, episode)
SELECT d.wheel_id, d.vehicle_id, d.wheelset, d.side, d.timestamp, d.verdict, 0, 0
FROM diagnosis d
JOIN (SELECT wheel_id, MAX(timestamp) AS t FROM diagnosis WHERE wheel_id IS NOT NULL
      GROUP BY wheel_id) m
  ON d.wheel_id = m.wheel_id AND d.timestamp = m.t
WHERE d.site_id || '/' || d.passage_id = (
    SELECT MIN(p.site_id || '/' || p.passage_id) FROM diagnosis p
    WHERE p.wheel_id = m.wheel_id AND p.timestamp = m.t)"""
"""Each wheel's row from the diagnoses stored (its latest passage; no alarm yet)."""


@dataclass(frozen=True)
class Migration:
    version: int
    description: str
    statements: tuple[str, ...]


MIGRATIONS: tuple[Migration, ...] = (
    Migration(
        1,
        "diagnoses keyed by (site_id, passage_id), indexed by wheel",
        (
            """CREATE TABLE diagnosis (
            site_id TEXT NOT NULL,
            passage_id TEXT NOT NULL,
            wheel_id TEXT,
            vehicle_id TEXT,
            wheelset INTEGER,
            side TEXT,
            timestamp DOUBLE PRECISION NOT NULL,
            verdict TEXT NOT NULL,
            flat_kind TEXT,
            flat_length DOUBLE PRECISION,
            flat_length_low DOUBLE PRECISION,
            flat_length_high DOUBLE PRECISION,
            peak_force_measured DOUBLE PRECISION NOT NULL,
            peak_force_at_line_speed DOUBLE PRECISION,
            speed DOUBLE PRECISION,
            distance_run DOUBLE PRECISION,
            received_at DOUBLE PRECISION NOT NULL,
            body TEXT NOT NULL,
            PRIMARY KEY (site_id, passage_id)
        )""",
            "CREATE INDEX diagnosis_wheel_time ON diagnosis (wheel_id, timestamp)",
            "CREATE INDEX diagnosis_received ON diagnosis (received_at)",
        ),
    ),
    Migration(
        2,
        "sites and wheels: last passage, verdict and alarm state",
        (
            """CREATE TABLE site (
            site_id TEXT PRIMARY KEY,
            last_timestamp DOUBLE PRECISION NOT NULL,
            last_passage_id TEXT NOT NULL,
            last_verdict TEXT NOT NULL,
            diagnoses BIGINT NOT NULL
        )""",
            """CREATE TABLE wheel (
            wheel_id TEXT PRIMARY KEY,
            vehicle_id TEXT NOT NULL,
            wheelset INTEGER NOT NULL,
            side TEXT NOT NULL,
            last_timestamp DOUBLE PRECISION NOT NULL,
            last_verdict TEXT NOT NULL,
            alarmed_level INTEGER NOT NULL DEFAULT 0,
            episode INTEGER NOT NULL DEFAULT 0
        )""",
            "CREATE INDEX wheel_vehicle ON wheel (vehicle_id)",
            SITE_BACKFILL,
            WHEEL_BACKFILL,
        ),
    ),
    Migration(
        3,
        "alarms raised, once per (wheel, kind, level, episode)",
        (
            """CREATE TABLE alarm (
            wheel_id TEXT NOT NULL,
            kind TEXT NOT NULL,
            level TEXT NOT NULL,
            episode INTEGER NOT NULL,
            raised_at DOUBLE PRECISION NOT NULL,
            data_time DOUBLE PRECISION NOT NULL,
            cleared_at DOUBLE PRECISION,
            body TEXT NOT NULL,
            PRIMARY KEY (wheel_id, kind, level, episode)
        )""",
            "CREATE INDEX alarm_open ON alarm (cleared_at, raised_at)",
        ),
    ),
    Migration(
        4,
        "alarms: when each was published (the alarm table as an outbox)",
        (
            "ALTER TABLE alarm ADD COLUMN published_at DOUBLE PRECISION",
            "UPDATE alarm SET published_at = raised_at",
            "CREATE INDEX alarm_unpublished ON alarm (published_at, raised_at)",
        ),
    ),
    Migration(
        5,
        "re-analysed diagnoses keyed by (site_id, passage_id, model_version)",
        (
            """CREATE TABLE reanalysis (
            site_id TEXT NOT NULL,
            passage_id TEXT NOT NULL,
            model_version TEXT NOT NULL,
            wheel_id TEXT,
            timestamp DOUBLE PRECISION,
            verdict TEXT,
            error TEXT,
            stored_at DOUBLE PRECISION NOT NULL,
            body TEXT,
            PRIMARY KEY (site_id, passage_id, model_version)
        )""",
            "CREATE INDEX reanalysis_version ON reanalysis (site_id, model_version)",
        ),
    ),
    Migration(
        6,
        "wheels whose alarms are due: a diagnosis stored, its alarms not yet evaluated",
        ("ALTER TABLE wheel ADD COLUMN alarms_due INTEGER NOT NULL DEFAULT 0",),
    ),
)

LATEST = MIGRATIONS[-1].version

MIGRATIONS_TABLE = """CREATE TABLE IF NOT EXISTS schema_migrations (
    version INTEGER PRIMARY KEY,
    description TEXT NOT NULL,
    applied_at DOUBLE PRECISION NOT NULL
)"""
