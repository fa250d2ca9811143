"""The fleet's store, on SQLite and on a real PostgreSQL server: idempotent history,
sites and wheels, migrations of an old database, alarm state that survives a restart."""

from __future__ import annotations

import json
import time

import pytest

from service.fleet.alarms import apply
from service.fleet.limits import FleetLimits
from service.fleet.migrations import LATEST
from service.fleet.store import AlarmRow, Store, open_store
from tests.fleet_support import DAY, T0, make_entry


def test_a_diagnosis_is_stored_once(store: Store) -> None:
    a = make_entry("km12", "t1-a0-l", day=0, verdict="watch", length=0.035)
    b = make_entry("km48", "t1-a0-l", day=1, verdict="inspect", length=0.045)
    assert [e.diagnosis_id for e in store.insert([a, b])] == ["km12/t1-a0-l", "km48/t1-a0-l"]
    # the same (site_id, passage_id) again, even with other content, changes nothing
    again = make_entry("km12", "t1-a0-l", day=5, verdict="remove", length=0.09)
    assert store.insert([again, a]) == []
    hist = store.history("V1/1/left")
    assert [(e.site_id, e.verdict, e.flat_length) for e in hist] == [
        ("km12", "watch", 0.035),
        ("km48", "inspect", 0.045),
    ]
    assert store.count() == 2
    sites = {s.site_id: s for s in store.sites()}
    assert sites["km12"].diagnoses == 1 and sites["km48"].last_verdict == "inspect"
    w = store.wheel("V1/1/left")
    assert w is not None and (w.last_verdict, w.last_timestamp) == ("inspect", T0 + DAY)
    assert store.latest_times() is not None


def test_history_order_limit_and_speed(store: Store) -> None:
    # arrives out of order (a late catch-up): the history is by passage time
    store.insert([make_entry("s", f"p{d}", day=d, length=0.03 + d * 1e-3) for d in (3, 1, 2, 0)])
    assert [e.passage_id for e in store.history("V1/1/left")] == ["p0", "p1", "p2", "p3"]
    assert [e.passage_id for e in store.history("V1/1/left", limit=2)] == ["p2", "p3"]
    assert store.set_speed("s", "p1", 22.2) and not store.set_speed("s", "nope", 1.0)
    assert store.entry("s", "p1").speed == 22.2  # type: ignore[union-attr]
    assert store.wheel("V1/1/left").last_timestamp == T0 + 3 * DAY  # type: ignore[union-attr]
    # a diagnosis without a wheel counts for its site only
    store.insert([make_entry("s", "anon", wheel=None, day=9)])
    assert store.sites()[0].last_passage_id == "anon" and len(store.wheels()) == 1
    assert [w.wheel_id for w in store.wheels("V*")] == ["V1/1/left"]
    assert store.wheels("W") == []


def test_migrating_an_old_database_keeps_and_backfills_its_data(db_url: str) -> None:
    old = open_store(db_url, migrate=False)
    assert old.migrate(target=1) == [1]
    assert old.schema_version() == 1
    e1 = make_entry("km12", "p1", day=0, verdict="watch", length=0.035)
    e2 = make_entry("km12", "p2", wheel="V2/3/right", day=2, verdict="inspect", length=0.045)
    e3 = make_entry("km48", "p1", day=1, verdict="inspect", length=0.041)
    cols = (
        "site_id, passage_id, wheel_id, vehicle_id, wheelset, side, timestamp, verdict, "
        "flat_length, peak_force_measured, received_at, body"
    )
    with old._transaction() as cur:  # rows as the version-1 railtwin wrote them
        for e in (e1, e2, e3):
            old._exec(
                cur,
                f"INSERT INTO diagnosis ({cols}) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
                (
                    e.site_id,
                    e.passage_id,
                    e.wheel_id,
                    e.vehicle_id,
                    e.wheelset,
                    e.side,
                    e.timestamp,
                    e.verdict,
                    e.flat_length,
                    e.peak_force_measured,
                    e.received_at,
                    e.body,
                ),
            )
    old.close()
    new = open_store(db_url)  # opening migrates
    try:
        assert new.schema_version() == LATEST
        assert new.count() == 3
        sites = {s.site_id: (s.diagnoses, s.last_passage_id) for s in new.sites()}
        assert sites == {"km12": (2, "p2"), "km48": (1, "p1")}
        w = new.wheel("V1/1/left")
        assert w is not None and (w.last_verdict, w.alarmed_level) == ("inspect", 0)
        assert new.wheel("V2/3/right") is not None
        # the migrated database works as a new one: idempotent, alarms table present
        assert new.insert([e1]) == []
        assert new.migrate() == []
    finally:
        new.close()


def test_alarm_state_survives_a_restart(db_url: str) -> None:
    limits = FleetLimits.defaults()
    s = open_store(db_url)
    s.insert([make_entry("a", "p0", day=0, verdict="watch", length=0.032)])
    raised = apply(s, "V1/1/left", limits, horizon=30 * DAY, now=T0)
    assert [(a.kind, a.level) for a in raised] == [("verdict_escalated", "watch")]
    s.close()
    s = open_store(db_url)  # restarted: the same state must not raise again
    try:
        s.insert([make_entry("b", "p1", day=1, verdict="watch", length=0.033)])
        assert apply(s, "V1/1/left", limits, horizon=30 * DAY, now=T0 + DAY) == []
        assert len(s.alarms()) == 1
        assert not s.add_alarm(
            AlarmRow("V1/1/left", "verdict_escalated", "watch", 0, time.time(), T0, None, "{}")
        )
    finally:
        s.close()


def test_store_refuses_a_newer_schema(tmp_path: pytest.TempPathFactory) -> None:
    path = str(tmp_path / "x.sqlite")  # type: ignore[operator]
    s = open_store(path)
    with s._transaction() as cur:
        s._exec(cur, "INSERT INTO schema_migrations VALUES (99, 'future', 0)")
    s.close()
    from service.fleet.store import StoreError

    with pytest.raises(StoreError, match="newer"):
        open_store(path)
    assert json.dumps(FleetLimits.defaults().to_json())


def test_the_alarm_table_is_an_outbox(db_url: str) -> None:
    """An alarm is stored unpublished until the service records its publication; alarms
    stored by a railtwin before migration 4 count as published (they were, when raised)."""
    limits = FleetLimits.defaults()
    old = open_store(db_url, migrate=False)
    assert old.migrate(target=3) == [1, 2, 3]
    # the alarm a railtwin before migration 4 stored (made here by today's code, in memory:
    # today's insert needs the later migrations' columns)
    ref = open_store(":memory:")
    ref.insert([make_entry("a", "p0", day=0, verdict="watch", length=0.032)])
    assert len(apply(ref, "V1/1/left", limits, horizon=30 * DAY, now=T0)) == 1
    assert old.add_alarm(ref.alarms()[0])
    ref.close()
    old.close()
    s = open_store(db_url)  # migration 4
    try:
        assert s.schema_version() == LATEST >= 4
        assert s.unpublished_alarms() == []  # raised before the outbox: published then
        s.insert([make_entry("b", "p1", day=1, verdict="inspect", length=0.045)])
        raised = apply(s, "V1/1/left", limits, horizon=0.5 * DAY, now=T0 + DAY)
        assert [(a.kind, a.level) for a in raised] == [("verdict_escalated", "inspect")]
        pending = s.unpublished_alarms()
        assert [(r.kind, r.level, r.episode) for r in pending] == [
            ("verdict_escalated", "inspect", 0)
        ]
        a = raised[0]
        s.mark_published(a.wheel_id, a.kind, a.level, a.episode, T0 + DAY + 1.0)
        assert s.unpublished_alarms() == []
        assert len(s.alarms()) == 2  # published or not, both are listed
    finally:
        s.close()
