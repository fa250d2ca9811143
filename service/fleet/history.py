"""A wheel's history document: its diagnoses, oldest first, and its growth trends.

This is what ``railtwin/fleet/wheel/<vehicle_id>/<wheelset>/<side>`` answers and
``railtwin fleet wheel`` prints::

    {"wheel_id": "V1/2/left", "vehicle_id": "V1", "wheelset": 2, "side": "left",
     "last_verdict": "inspect",
     "history": [{"site_id", "passage_id", "timestamp", "verdict", "flat" (as in
                  Diagnosis), "reasons", "peak_force_measured", "peak_force_at_line_speed",
                  "speed", "distance_run"}, ...],
     "trend": {"flat_length": TREND | null, "peak_force_at_line_speed": TREND | null,
               "since": UNIX s | null},
     "limits": {...}}

TREND is ``service.fleet.trend.Trend`` as JSON (``slope_per_day`` in m/day or N/day,
its standard error ``slope_se_per_day``) plus ``crossings``: for ``inspect`` and
``remove`` the predicted date (UNIX s) and its 95 % interval.

The trend is fitted to the diagnoses since the last one that found no flat (a wheel
found round has been turned or was never flat: an older flat's growth says nothing
about the new one). Flat lengths are weighted by their 95 % intervals; the peak force
at line speed by its interval when the diagnosis gives one
(``peak_force_at_line_speed_low``/``_high``), else unweighted (3 points needed).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from typing import Any

from service.fleet.entry import Entry
from service.fleet.limits import FleetLimits
from service.fleet.trend import Z95, Trend, crossing, fit_trend

FORECAST_LEVELS = ("inspect", "remove")


def trend_entries(history: Sequence[Entry]) -> list[Entry]:
    """The entries the trend is fitted to: those after the last one without a flat."""
    start = 0
    for i, e in enumerate(history):
        if e.flat_length is None:
            start = i + 1
    return list(history[start:])


def _force_sigma(e: Entry) -> float | None:
    body = json.loads(e.body)
    lo, hi = body.get("peak_force_at_line_speed_low"), body.get("peak_force_at_line_speed_high")
    if isinstance(lo, int | float) and isinstance(hi, int | float) and hi > lo:
        return max((hi - lo) / (2 * Z95), 1.0)
    return None


def length_trend(entries: Sequence[Entry]) -> Trend | None:
    pts = [
        (e.timestamp, e.flat_length, e.length_sigma)
        for e in entries
        if e.flat_length is not None and e.length_sigma is not None
    ]
    if not pts:
        return None
    return fit_trend([p[0] for p in pts], [p[1] for p in pts], [p[2] for p in pts])


def force_trend(entries: Sequence[Entry]) -> Trend | None:
    pts = [
        (e.timestamp, e.peak_force_at_line_speed, _force_sigma(e))
        for e in entries
        if e.peak_force_at_line_speed is not None
    ]
    if not pts:
        return None
    sigmas = [p[2] for p in pts]
    t = [p[0] for p in pts]
    y = [float(p[1]) for p in pts]
    if all(s is not None for s in sigmas):
        return fit_trend(t, y, sigmas)  # type: ignore[arg-type]
    return fit_trend(t, y, None)


def trend_json(trend: Trend | None, limit_of: Any, unit: str) -> dict[str, Any] | None:
    if trend is None:
        return None
    doc = trend.to_json()
    doc["unit"] = unit
    doc["growing"] = trend.growing
    doc["crossings"] = [crossing(trend, lv, limit_of(lv)).to_json() for lv in FORECAST_LEVELS]
    return doc


def wheel_document(
    wheel_id: str, history: Sequence[Entry], limits: FleetLimits, last_verdict: str | None = None
) -> dict[str, Any]:
    """The wheel's history and trend as the queryable answers (see module doc)."""
    vehicle, wheelset, side = wheel_id.rsplit("/", 2)
    fit = trend_entries(history)
    return {
        "wheel_id": wheel_id,
        "vehicle_id": vehicle,
        "wheelset": int(wheelset),
        "side": side,
        "last_verdict": last_verdict or (history[-1].verdict if history else None),
        "history": [e.history_json() for e in history],
        "trend": {
            "since": fit[0].timestamp if fit else None,
            "flat_length": trend_json(length_trend(fit), limits.length, "m"),
            "peak_force_at_line_speed": trend_json(force_trend(fit), limits.force, "N"),
        },
        "limits": limits.to_json(),
    }
