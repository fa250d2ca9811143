"""Fleet alarms: raised once per escalation, forecasts within the horizon only, a new
episode after the wheel is found round again."""

from __future__ import annotations

from pathlib import Path

from service.fleet.alarms import apply, evaluate_due
from service.fleet.limits import FleetLimits
from service.fleet.store import Store, open_store
from tests.fleet_support import DAY, T0, make_entry

LIMITS = FleetLimits.defaults()  # inspect 40 mm, remove 60 mm


def _store() -> Store:
    return open_store(":memory:")


def test_escalation_is_raised_once_per_level() -> None:
    s = _store()
    got = []
    for d, verdict, length in [
        (0, "watch", 0.031),
        (1, "watch", 0.032),
        (2, "inspect", 0.041),
        (3, "watch", 0.039),
        (4, "inspect", 0.042),
    ]:
        s.insert(
            [make_entry(f"s{d}", f"p{d}", day=d, verdict=verdict, length=length, half_width=0.01)]
        )
        got += [
            (a.kind, a.level, a.severity, a.evidence[-1])
            for a in apply(s, "V1/1/left", LIMITS, horizon=1.0, now=T0)
        ]
    # 1 mm/day with ±10 mm intervals: no significant trend, so escalations only
    assert got == [
        ("verdict_escalated", "watch", "info", "s0/p0"),
        ("verdict_escalated", "inspect", "warning", "s2/p2"),
    ]
    a = next(r.json() for r in s.alarms() if r.level == "inspect")
    assert a["wheel"] == {"vehicle_id": "V1", "wheelset": 1, "side": "left"}
    assert "inspect reason" in a["reason"] and a["evidence"] == ["s2/p2"]


def test_forecast_alarm_within_the_horizon_only() -> None:
    s = _store()
    # 5 mm/day from 20 mm, tight intervals: remove (60 mm) on day 8, inspect on day 4
    for d in range(3):
        s.insert(
            [
                make_entry(
                    "a", f"p{d}", day=d, verdict="ok", length=0.020 + 0.005 * d, half_width=0.0005
                )
            ]
        )
    far = apply(s, "V1/1/left", LIMITS, horizon=1 * DAY, now=T0)
    assert far == []  # inspect is 2 days after the latest diagnosis: beyond 1 day
    s.insert([make_entry("a", "p3", day=3, verdict="ok", length=0.035, half_width=0.0005)])
    near = apply(s, "V1/1/left", LIMITS, horizon=3 * DAY, now=T0)
    assert [(a.kind, a.level, a.severity) for a in near] == [
        ("forecast_flat_length", "inspect", "info")
    ]
    f = near[0].forecast
    assert f is not None and abs(f["at"] - (T0 + 4 * DAY)) < 0.05 * DAY
    assert f["earliest"] < f["at"] < f["latest"]
    assert near[0].evidence == ["a/p0", "a/p1", "a/p2", "a/p3"]
    # the same forecast is not raised again by the next passage
    s.insert([make_entry("a", "p4", day=3.5, verdict="ok", length=0.0375, half_width=0.0005)])
    assert apply(s, "V1/1/left", LIMITS, horizon=3 * DAY, now=T0) == []


def test_a_wheel_found_round_starts_a_new_episode() -> None:
    s = _store()
    s.insert([make_entry("a", "p0", day=0, verdict="inspect", length=0.045)])
    assert len(apply(s, "V1/1/left", LIMITS, horizon=1.0, now=T0)) == 1
    s.insert([make_entry("a", "p1", day=5, verdict="ok", length=None)])  # turned
    assert apply(s, "V1/1/left", LIMITS, horizon=1.0, now=T0 + 5 * DAY) == []
    assert s.alarms() == [] and len(s.alarms(open_only=False)) == 1  # cleared
    s.insert([make_entry("a", "p2", day=9, verdict="inspect", length=0.044)])
    again = apply(s, "V1/1/left", LIMITS, horizon=1.0, now=T0 + 9 * DAY)
    assert [(a.level, a.episode) for a in again] == [("inspect", 1)]


def test_a_stop_between_storing_and_evaluating_skips_no_escalation(tmp_path: Path) -> None:
    """The fleet stores a diagnosis, then evaluates its wheel's alarms: a kill -9 between the
    two leaves the wheel marked due, and the next start evaluates it before anything else, so
    a later, higher verdict does not jump over the ``watch`` it missed."""
    db = str(tmp_path / "fleet.db")
    s = open_store(db)
    s.insert([make_entry("s0", "p0", day=0, verdict="watch", length=0.031, half_width=0.01)])
    assert s.wheels_due() == ["V1/1/left"]  # stored; the process dies before ``apply``
    s.close()

    s = open_store(db)  # the next start
    restarted = evaluate_due(s, LIMITS, horizon=1.0, now=T0)
    assert [(a.kind, a.level) for a in restarted] == [("verdict_escalated", "watch")]
    assert s.wheels_due() == []
    s.insert([make_entry("s1", "p1", day=1, verdict="inspect", length=0.041, half_width=0.01)])
    later = apply(s, "V1/1/left", LIMITS, horizon=1.0, now=T0)
    assert [(a.kind, a.level) for a in later] == [("verdict_escalated", "inspect")]
    assert evaluate_due(s, LIMITS, horizon=1.0, now=T0) == []  # evaluated once, not twice
    s.close()
