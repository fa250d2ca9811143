"""Where the wheel page's plots put their ticks and labels so that none collide.

The date axis has its ticks at whole hours, days, months or years, by the span, each label
naming its tick alone (``09-22``, ``09-22 06:00``, ``2026-10``): the finest step that gives
at most ``MAX_TICKS`` ticks with a gap between their labels, hours only when whole days give
fewer than ``MIN_DAY_TICKS``. Labels in the plot (the limits' at the right edge,
the forecast crossings' at the top) are moved apart when they would overlap: their boxes
are estimated from the font size (``text_box``: a sans-serif character is at most about
0.65 em wide in the digits and letters the labels use: 0.64 in DejaVu Sans).

    >>> [label for _, label in time_ticks(1_790_000_000.0, 1_790_000_000.0 + 3 * DAY, 680)]
    ['09-22', '09-23', '09-24']
    >>> spread([100.0, 95.0, 40.0], gap=12.0, low=20.0, high=200.0)
    [107.0, 95.0, 40.0]
"""

from __future__ import annotations

import calendar
import itertools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

from service.fleet.trend import DAY

HOUR = 3600.0
CHAR_EM = 0.65
"""Width of a label's character, in em (an upper bound for digits and most letters)."""
TICK_GAP = 12.0
"""Least space between two tick labels, px."""
MAX_TICKS = 7
MIN_DAY_TICKS = 3
"""Hours are ticked only when whole days would give fewer ticks than this."""

_SUB_DAY = (1, 2, 3, 6, 12)  # hours
_DAYS = (1, 2, 7, 14)
_MONTHS = (1, 2, 3, 6, 12, 24, 60, 120)


@dataclass(frozen=True)
class Box:
    """A label's box in px: x0 <= x1 left to right, y0 <= y1 top to bottom."""

    x0: float
    y0: float
    x1: float
    y1: float

    def overlaps(self, other: Box) -> bool:
        return (
            self.x0 < other.x1 and other.x0 < self.x1 and self.y0 < other.y1 and other.y0 < self.y1
        )


def text_width(text: str, size: float = 11.0) -> float:
    return CHAR_EM * size * len(text)


def text_box(x: float, y: float, text: str, anchor: str = "start", size: float = 11.0) -> Box:
    """The box of SVG text at (x, baseline y) with this ``text-anchor``."""
    w = text_width(text, size)
    x0 = {"start": x, "middle": x - w / 2, "end": x - w}[anchor]
    return Box(x0, y - size, x0 + w, y + 0.3 * size)


def _months(t0: float, t1: float, step: int) -> list[float]:
    """The first days of the months in [t0, t1] whose number since year 0 is a multiple of
    ``step`` (UTC)."""
    g = time.gmtime(t0)
    n = g.tm_year * 12 + g.tm_mon - 1
    n += -n % step
    out: list[float] = []
    while True:
        t = float(calendar.timegm((n // 12, n % 12 + 1, 1, 0, 0, 0)))
        if t > t1:
            return out
        if t >= t0:
            out.append(t)
        n += step


def _candidates(t0: float, t1: float) -> list[tuple[list[float], str]]:
    """(tick times, label format) of every step, the finest first; hours only when whole
    days would give fewer than ``MIN_DAY_TICKS`` ticks."""
    steps = [(h * HOUR, "%m-%d %H:%M") for h in _SUB_DAY] + [(d * DAY, "%m-%d") for d in _DAYS]
    out: list[tuple[list[float], str]] = []
    for seconds, fmt in steps:
        first = math.ceil(t0 / seconds) * seconds
        count = int((t1 - first) // seconds) + 1
        if count <= 200:  # far finer is not even listed
            out.append(([first + i * seconds for i in range(count)], fmt))
    days = [ticks for ticks, fmt in out if fmt == "%m-%d"]
    if days and len(days[0]) >= MIN_DAY_TICKS:
        out = [(ticks, fmt) for ticks, fmt in out if fmt == "%m-%d"]
    return out + [(_months(t0, t1, m), "%Y-%m") for m in _MONTHS]


def time_ticks(t0: float, t1: float, width: float, size: float = 11.0) -> list[tuple[float, str]]:
    """(UNIX s, label) of the date axis over [t0, t1] drawn ``width`` px wide: the finest
    step of whole hours, days or months that gives at most ``MAX_TICKS`` ticks whose labels
    keep ``TICK_GAP`` px apart."""
    per_s = width / (t1 - t0)
    last: list[tuple[float, str]] = []
    for ticks, fmt in _candidates(t0, t1):
        if not ticks:
            continue
        last = [(t, time.strftime(fmt, time.gmtime(t))) for t in ticks]
        room = min((b - a for a, b in itertools.pairwise(ticks)), default=t1 - t0)
        widest = max(text_width(label, size) for _, label in last)
        if len(ticks) <= MAX_TICKS and room * per_s >= widest + TICK_GAP:
            return last
    return last[:1]


def spread(ys: Sequence[float], gap: float, low: float, high: float) -> list[float]:
    """The baselines ``ys`` moved as little as simple passes can so that any two are ``gap``
    apart, within [``low``, ``high``] when there is room (the order of ``ys`` kept)."""
    order = sorted(range(len(ys)), key=lambda i: ys[i])
    placed = [max(low, ys[i]) for i in order]
    for k in range(1, len(placed)):  # downwards: each at least a gap below the one above
        placed[k] = max(placed[k], placed[k - 1] + gap)
    if placed and placed[-1] > high:  # then back up from the bottom
        placed[-1] = high
        for k in range(len(placed) - 2, -1, -1):
            placed[k] = min(placed[k], placed[k + 1] - gap)
    out = [0.0] * len(ys)
    for k, i in enumerate(order):
        out[i] = placed[k]
    return out


def free_row(
    x: float, text: str, anchor: str, rows: Sequence[float], taken: Sequence[Box]
) -> float:
    """The first of ``rows`` (baselines) where the label meets none of ``taken`` (the last
    row when none is free)."""
    for y in rows:
        if not any(text_box(x, y, text, anchor).overlaps(b) for b in taken):
            return y
    return rows[-1]
