"""The verdict: which limit from practice a wheel passed, and what must happen to it.

Levels, mildest first: ``ok`` < ``watch`` < ``inspect`` < ``remove``. Each limit passed
adds a reason naming the limit and the values; the verdict is the severest level any
limit reached. Forces are checked both as measured and as predicted at the line's full
speed (the twin's reason to exist: a flat measured at 40 km/h may condemn the wheel at
160 km/h).

    >>> limits = Limits(250e3, 350e3, 400e3, 0.03, 0.04, 0.06)
    >>> verdict(limits, 180e3, 420e3, 0.045, line_speed=44.4)
    ('remove', ['peak force at line speed 44.4 m/s 420 kN >= remove limit 400 kN (remove_force)', 'flat length 45.0 mm >= inspect limit 40.0 mm (inspect_length)'])
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["LEVELS", "Limits", "verdict"]

LEVELS = ("ok", "watch", "inspect", "remove")


@dataclass(frozen=True)
class Limits:
    """Force limits (N) and flat-length limits (m) per level."""

    watch_force: float
    inspect_force: float
    remove_force: float
    watch_length: float
    inspect_length: float
    remove_length: float


def _level(value: float, watch: float, inspect: float, remove: float) -> tuple[int, str, float]:
    for level, name, limit in ((3, "remove", remove), (2, "inspect", inspect), (1, "watch", watch)):
        if value >= limit:
            return level, name, limit
    return 0, "", 0.0


def verdict(
    limits: Limits,
    peak_force_measured: float,
    peak_force_line_speed: float | None,
    flat_length: float | None,
    line_speed: float | None = None,
    flat_length_upper: float | None = None,
) -> tuple[str, list[str]]:
    """(verdict, reasons) for one wheel.

    ``flat_length_upper``: the upper end of the flat's length interval. The remove limit
    is checked against it too: a wheel whose flat may be over the remove limit is taken
    out, whatever its best estimate (the one place where the interval, not the point,
    decides for a fit that explains its record; the wide validation's o024 of seed 777,
    60.03 mm fitted at 59.9 mm [55.7, 63.6], was otherwise sent on for inspection).

    >>> limits = Limits(250e3, 350e3, 400e3, 0.03, 0.04, 0.06)
    >>> verdict(limits, 180e3, None, 0.0599, flat_length_upper=0.0636)[0]
    'remove'
    """
    worst = 0
    reasons: list[str] = []
    L = limits
    forces = [("measured peak force", peak_force_measured)]
    if peak_force_line_speed is not None:
        forces.append((f"peak force at line speed {line_speed:g} m/s", peak_force_line_speed))
    for what, value in forces:
        lv, name, limit = _level(value, L.watch_force, L.inspect_force, L.remove_force)
        if lv:
            reasons.append(
                f"{what} {value / 1e3:.0f} kN >= {name} limit {limit / 1e3:.0f} kN ({name}_force)"
            )
            worst = max(worst, lv)
    if flat_length is not None:
        lv, name, limit = _level(flat_length, L.watch_length, L.inspect_length, L.remove_length)
        if lv:
            reasons.append(
                f"flat length {flat_length * 1e3:.1f} mm >= {name} limit "
                f"{limit * 1e3:.1f} mm ({name}_length)"
            )
            worst = max(worst, lv)
    if (
        flat_length_upper is not None
        and flat_length_upper >= L.remove_length
        and (flat_length is None or flat_length < L.remove_length)
    ):
        reasons.append(
            f"flat length up to {flat_length_upper * 1e3:.1f} mm (upper end of its interval) "
            f">= remove limit {L.remove_length * 1e3:.1f} mm (remove_length)"
        )
        worst = 3
    return LEVELS[worst], reasons
