"""Fleet alarms: when a wheel's verdict escalates, or its trend predicts a limit soon.

Rules, evaluated for a wheel each time one of its diagnoses is stored (its latest
diagnosis by passage time is the wheel's state):

- ``verdict_escalated``: the latest verdict is above every level already alarmed in
  this episode (``watch`` < ``inspect`` < ``remove``). Evidence: the diagnoses of the
  episode at or above that level. Severity: watch ``info``, inspect ``warning``,
  remove ``critical``.
- ``forecast_flat_length`` / ``forecast_peak_force``: the trend (``service.fleet.history``)
  grows significantly (slope > 1.96 se) and its predicted crossing of the ``inspect`` or
  ``remove`` limit lies within ``horizon`` seconds of the latest diagnosis, for a level the
  verdict has not reached yet. Evidence: the diagnoses fitted. Severity: ``info`` for
  inspect, ``warning`` for remove.

An alarm is raised once per (wheel, kind, level, episode): the store's primary key, so a
restarted service does not raise it again. An episode ends when the wheel's latest
verdict is ``ok`` again (turned, or replaced): its open alarms are cleared and the next
escalation raises anew.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from schemas.fleet import AlarmKind, AlarmWheel, FleetAlarm, Severity
from service.fleet.entry import Entry
from service.fleet.history import FORECAST_LEVELS, force_trend, length_trend, trend_entries
from service.fleet.limits import LEVELS, FleetLimits, level_index
from service.fleet.store import AlarmRow, Store, WheelRow
from service.fleet.trend import crossing

DEFAULT_HORIZON_DAYS = 30.0
MAX_EVIDENCE = 50

_ESCALATION_SEVERITY: dict[str, Severity] = {
    "watch": "info",
    "inspect": "warning",
    "remove": "critical",
}
_FORECAST_SEVERITY: dict[str, Severity] = {"inspect": "info", "remove": "warning"}


@dataclass(frozen=True)
class Decision:
    alarms: list[FleetAlarm]
    alarmed_level: int
    episode: int
    cleared: bool


def _day(t: float) -> str:
    return time.strftime("%Y-%m-%d", time.gmtime(t))


def decide(
    wheel: WheelRow, history: Sequence[Entry], limits: FleetLimits, horizon: float, now: float
) -> Decision:
    """The alarms the wheel's state calls for (before de-duplication by the store)."""
    if not history:
        return Decision([], wheel.alarmed_level, wheel.episode, False)
    latest = max(history, key=lambda e: (e.timestamp, e.site_id, e.passage_id))
    level = level_index(latest.verdict)
    alarmed, episode, cleared = wheel.alarmed_level, wheel.episode, False
    if level == 0 and alarmed > 0:
        alarmed, episode, cleared = 0, episode + 1, True
    ref = {"vehicle_id": wheel.vehicle_id, "wheelset": wheel.wheelset, "side": wheel.side}
    out: list[FleetAlarm] = []

    def alarm(
        kind: AlarmKind,
        lv: str,
        severity: Severity,
        reason: str,
        evidence: list[str],
        forecast: dict[str, Any] | None = None,
    ) -> None:
        out.append(
            FleetAlarm(
                alarm_id=f"{wheel.wheel_id}:{kind}:{lv}:{episode}",
                wheel_id=wheel.wheel_id,
                wheel=AlarmWheel.model_validate(ref),
                kind=kind,
                level=lv,  # type: ignore[arg-type]
                severity=severity,
                reason=reason,
                evidence=evidence[-MAX_EVIDENCE:],
                data_time=latest.timestamp,
                raised_at=now,
                episode=episode,
                forecast=forecast,
            )
        )

    if level > alarmed:
        name = LEVELS[level]
        ev = [e.diagnosis_id for e in history if level_index(e.verdict) >= level]
        why = "; ".join(_reasons(latest)) or name
        alarm(
            "verdict_escalated",
            name,
            _ESCALATION_SEVERITY[name],
            f"verdict escalated from {LEVELS[alarmed]} to {name} at {latest.site_id} on "
            f"{_day(latest.timestamp)}: {why}",
            ev,
        )
        alarmed = level
    fit = trend_entries(history)
    forecasts: tuple[tuple[AlarmKind, Any, Any, str, float], ...] = (
        ("forecast_flat_length", length_trend(fit), limits.length, "mm", 1e3),
        ("forecast_peak_force", force_trend(fit), limits.force, "kN", 1e-3),
    )
    for kind, trend, limit_of, unit, scale in forecasts:
        if trend is None or not trend.growing:
            continue
        for lv in FORECAST_LEVELS:
            if level_index(lv) <= max(alarmed, level):
                continue
            c = crossing(trend, lv, limit_of(lv))
            if c.status != "forecast" or c.at is None or c.at - latest.timestamp > horizon:
                continue
            span = ""
            if c.earliest is not None:
                span = f" (95 % from {_day(c.earliest)}" + (
                    f" to {_day(c.latest)})" if c.latest is not None else " on)"
                )
            what = "flat length" if kind == "forecast_flat_length" else "peak force at line speed"
            alarm(
                kind,
                lv,
                _FORECAST_SEVERITY[lv],
                f"{what} grows {trend.slope_per_day * scale:.3g} ± "
                f"{trend.slope_se_per_day * scale:.2g} {unit}/day over {trend.points} "
                f"diagnoses: {lv} limit {limit_of(lv) * scale:g} {unit} predicted on "
                f"{_day(c.at)}{span}, within the {horizon / 86400:g}-day horizon",
                [e.diagnosis_id for e in fit],
                c.to_json(),
            )
            break  # the nearer limit is enough per kind
    return Decision(out, alarmed, episode, cleared)


def _reasons(e: Entry) -> list[str]:
    import json

    r = json.loads(e.body).get("reasons", [])
    return [str(x) for x in r] if isinstance(r, list) else []


def apply(
    store: Store, wheel_id: str, limits: FleetLimits, horizon: float, now: float | None = None
) -> list[FleetAlarm]:
    """Evaluate the wheel, persist its alarm state; the alarms newly raised (to publish)."""
    wheel = store.wheel(wheel_id)
    if wheel is None:
        return []
    history = store.history(wheel_id)
    d = decide(wheel, history, limits, horizon, time.time() if now is None else now)
    if d.cleared:
        store.clear_alarms(wheel_id, time.time() if now is None else now)
    raised = []
    for a in d.alarms:  # alarms first: a crash before the state update re-decides them,
        row = AlarmRow(
            a.wheel_id,
            a.kind,
            a.level,
            a.episode,
            a.raised_at,
            a.data_time,
            None,
            a.model_dump_json(),
        )  # and the primary key keeps them single
        if store.add_alarm(row):
            raised.append(a)
    # always: it also records that the wheel's alarms were evaluated (no longer due)
    store.set_wheel_alarm_state(wheel_id, d.alarmed_level, d.episode)
    return raised


def evaluate_due(
    store: Store, limits: FleetLimits, horizon: float, now: float | None = None
) -> list[FleetAlarm]:
    """Evaluate every wheel whose diagnosis was stored and whose alarms were not (the
    service stopped between ``Store.insert`` and ``apply``), oldest first, so that no
    escalation is skipped: a ``watch`` stored before a kill -9 is raised at the next start,
    not jumped over by the ``inspect`` that follows. The alarms newly raised."""
    raised: list[FleetAlarm] = []
    for wheel_id in store.wheels_due():
        raised += apply(store, wheel_id, limits, horizon, now)
    return raised
