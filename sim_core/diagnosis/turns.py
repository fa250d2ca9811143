"""Once per wheel turn: finding the flat's impacts in a measured record.

A flat meets the rail once per turn, every T = 2πR/V. Before any fit the diagnosis
needs to know roughly *where* in the record it does so. The *disturbance* of the
measured force, |F - P| averaged over ``SMOOTHING`` s, is folded over the turn: for a
grid of phases and of speed factors (the reported speed may be off by a few per cent,
and over three turns at 30 km/h 1 % is 10 ms), the sum of the disturbance at the
predicted times is largest where the flat hits. Each turn's *anchor* is then the
local maximum of the disturbance near its predicted time: the first impact for a flat
that makes the wheel jump, the bottom of the dip for one that does not. Where that
maximum is a landing after the impact threw the wheel (a long fresh flat at speed), the
estimate walks it back to the first impact after rolling
(``first_impact_after_rolling``).

The anchors fix the windows the fit compares and, with two or more turns, the
measured turn period (and so the speed) to about 0.1 %.

    >>> import numpy as np
    >>> t = np.arange(0.0, 0.2, 1e-4)
    >>> f = np.full(t.size, 60e3)
    >>> for tk in (0.031, 0.096, 0.161):          # impacts every 65 ms
    ...     f += 140e3 * np.clip(1 - np.abs(t - tk) / 3e-4, 0, None)
    >>> a = find_anchors(t, f, 60e3, 0.46, 2 * np.pi * 0.46 / 0.065)
    >>> np.round(a.times, 4).tolist(), round(a.period, 4)
    ([0.031, 0.096, 0.161], 0.065)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.wheel import TWO_PI

__all__ = ["Anchors", "disturbance", "find_anchors", "first_impact_after_rolling"]

SMOOTHING = 1e-3
"""s: width of the moving average of |F - P| (an impact and its dip are 1-20 ms long)."""

SPEED_FACTORS = np.linspace(0.97, 1.03, 13)
"""Speed factors tried in the fold (the reported speed may be off by up to 3 %)."""

PHASES = 720
"""Phase grid points of the fold."""


@dataclass(frozen=True)
class Anchors:
    """One anchor time (s) per turn whose disturbance peak lies inside the record, the turn
    period (s) they imply, how far the disturbance stands out (peak / median), and how long
    before its anchor a turn's first impact may be (``lead``, s: ``first_impact_lead``; off
    in the fit)."""

    times: NDArray[np.float64]
    period: float
    prominence: float
    lead: float = 0.0


def disturbance(t: NDArray[np.float64], f: NDArray[np.float64], load: float) -> NDArray[np.float64]:
    """|F - P| averaged over ``SMOOTHING`` (s), same samples as ``f``."""
    rate = (t.size - 1) / (t[-1] - t[0]) if t.size > 1 else 1.0
    n = 2 * round(0.5 * SMOOTHING * rate) + 1  # odd: centred
    kernel = np.ones(n) / n
    return np.convolve(np.abs(f - load), kernel, mode="same")


def find_anchors(
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    load: float,
    radius: float,
    speed: float,
    contact_floor: float | None = None,
) -> Anchors:
    """The per-turn anchors of a record ``f`` at times ``t`` (see the module docstring).

    With ``contact_floor`` (N: the wheel is in contact while the record is above it), an
    anchor that is a landing after a bounce is moved back to the turn's first impact after
    rolling (``first_impact_after_rolling``); where that moves some turns' anchors and not
    the others' (a wheel arriving bouncing keeps its landing), the period is the fold's,
    not the anchors' spacing."""
    g = disturbance(t, f, load)
    rate = (t.size - 1) / (t[-1] - t[0])
    best = (-1.0, 0.0, 1.0)
    for factor in SPEED_FACTORS:
        period = TWO_PI * radius / (speed * factor)
        n_turns = math.floor((t[-1] - t[0]) / period) + 1
        phases = np.arange(PHASES) / PHASES * period
        times = t[0] + phases[:, None] + period * np.arange(n_turns)[None, :]
        idx = np.clip(np.rint((times - t[0]) * rate).astype(np.int64), 0, t.size - 1)
        inside = times <= t[-1]
        score = np.where(inside, g[idx], 0.0).sum(axis=1) / np.maximum(inside.sum(axis=1), 1)
        k = int(np.argmax(score))
        if score[k] > best[0]:
            best = (float(score[k]), float(phases[k]), float(period))
    _, first, period = best
    half = min(0.25 * period, 0.02)
    picks: list[int] = []
    moved = 0
    tk = t[0] + first
    while tk <= t[-1] + half:
        lo = np.searchsorted(t, tk - half)
        hi = np.searchsorted(t, tk + half)
        if hi - lo > 2:
            j = lo + int(np.argmax(g[lo:hi]))
            # the smoothed peak is flat-topped: the anchor is the raw peak under it
            a, b = np.searchsorted(t, t[j] - SMOOTHING), np.searchsorted(t, t[j] + SMOOTHING)
            j = a + int(np.argmax(np.abs(f[a:b] - load)))
            if contact_floor is not None:
                back = round(min(LEAD_BACK[0] * period, LEAD_BACK[1]) * rate)
                walked = first_impact_after_rolling(
                    f, j, contact_floor, back, round(ROLLING * rate)
                )
                moved += walked != j
                j = walked
            picks.append(j)
        tk += period
    anchors = [float(t[j]) for j in picks if 0 < j < t.size - 1]
    times = np.array(anchors)
    if times.size >= 2:
        k = np.rint((times - times[0]) / period)
        if np.all(np.diff(k) > 0):
            fitted = float(np.polyfit(k, times, 1)[0])
            # a turn walked back to its impact and one kept at its landing time different
            # events: their spacing is not the period, the fold's is
            if not 0 < moved < len(picks):
                period = fitted
    med = float(np.median(g))
    peak = float(np.min(g[np.searchsorted(t, times)])) if times.size else 0.0
    lead = first_impact_lead(t, g, times, period)
    return Anchors(times, period, peak / med if med > 0 else math.inf, lead)


ROLLING = 3e-3
"""s of unbroken contact that make a wheel *rolling* (an impact's contact lasts 1-2 ms)."""


def first_impact_after_rolling(
    f: NDArray[np.float64], j: int, floor: float, back: int, rolling: int
) -> int:
    """The sample of the first impact after the wheel last rolled, walking back from the
    peak at sample ``j`` at most ``back`` samples (``j`` itself if it finds no rolling).

    A long fresh flat at speed throws the wheel: it leaves the rail at the leading corner,
    hits the trailing corner, flies, and can land harder than it hit (the wide set's W30
    lands at 24 P, 19 ms after a 7.9 P impact). The largest peak of such a turn is a
    landing, and a window ending there holds no flat. A peak is a landing when its contact
    began after a flight (record at or below ``floor``) that began from a contact shorter
    than ``rolling`` samples: the walk goes back to that contact's peak and asks again,
    until the flight began from rolling (the peak is the first impact) or the peak was
    reached in unbroken contact. A wheel that arrives bouncing from the last turn has no
    rolling to walk back to within ``back``, and keeps its largest peak.

        >>> f = np.array([1.0] * 8 + [0.0] * 2 + [5.0] + [0.0] * 6 + [9.0] + [0.0] * 3)
        >>> first_impact_after_rolling(f, 17, 0.1, 20, 4)
        10
    """
    if f[j] <= floor:
        return j  # a dip, not an impact
    lo = max(j - back, 0)
    i = j
    while True:
        k = i  # back to the start of the contact the peak is in
        while k > lo and f[k - 1] > floor and i - k + 1 < rolling:
            k -= 1
        if i - k + 1 >= rolling:
            return i  # reached in unbroken contact
        m = k - 1  # back through the flight before it
        while m > lo and f[m] <= floor:
            m -= 1
        if m <= lo or k <= lo:
            return j
        s = m  # the contact the flight began from
        while s > lo and f[s - 1] > floor and m - s + 1 < rolling:
            s -= 1
        if m - s + 1 >= rolling:
            return i  # the flight began from rolling: i is its first impact
        i = s + int(np.argmax(f[s : m + 1]))


LEAD_SHARE = 0.5
"""A peak of the disturbance may be a turn's first impact from this share of its largest."""

LEAD_BACK = (0.3, 0.04)
"""How far before a turn's largest peak its first impact is looked for: this fraction of a
turn, at most this many s (a lightly damped wheel bounces for tens of ms after an impact)."""


def first_impact_lead(
    t: NDArray[np.float64], g: NDArray[np.float64], times: NDArray[np.float64], period: float
) -> float:
    """s: how long before its anchor (the turn's largest peak, or its first impact after
    rolling: ``first_impact_after_rolling``) a turn's first impact may be.

    On a lightly damped foundation a flat's first impact sets the wheel bouncing for tens
    of ms and a later bounce can hit harder than the first impact: the largest peak is then
    not where the flat is, and a window ending there can miss the flat's dip altogether.
    The first impact is among the peaks of the disturbance that reach ``LEAD_SHARE`` of the
    turn's largest, up to ``LEAD_BACK`` before it; the lead is the earliest of those over
    all turns, so that the windows reach back to it and the fit places the flat.
    """
    back = min(LEAD_BACK[0] * period, LEAD_BACK[1])
    lead = 0.0
    for a in times:
        ia = min(int(np.searchsorted(t, a)), t.size - 1)
        lo = max(int(np.searchsorted(t, a - back)), 1)
        hi = min(ia + 1, t.size - 1)
        seg = g[lo - 1 : hi + 1]
        peak = (seg[1:-1] >= seg[:-2]) & (seg[1:-1] > seg[2:]) & (seg[1:-1] >= LEAD_SHARE * g[ia])
        at = np.nonzero(peak)[0]
        if at.size:
            lead = max(lead, float(a - t[lo + at[0]]))
    return lead
