"""The wheel page's plots, drawn on the server as inline SVG (nothing to download).

One panel per quantity (flat length in mm, peak force at line speed in kN) against the
date: each diagnosis a dot (with its 95 % interval when known), the trend's line and its
95 % band extended to the forecast crossing of the remove limit (at most ``MAX_FORECAST``
ahead), and the watch/inspect/remove limits as dashed lines.
"""

from __future__ import annotations

import html
import math
import time
from typing import Any

from service.fleet.plot_layout import Box, free_row, spread, text_box, time_ticks
from service.fleet.trend import DAY, Z95

W, H = 760, 250
LEFT, RIGHT, TOP, BOTTOM = 60, 20, 28, 36
MAX_FORECAST = 365 * DAY
LIMIT_COLOURS = {"watch": "#c9a400", "inspect": "#e07000", "remove": "#c00000"}
LABEL_ROW = 15.0
"""Baseline to baseline of two labels that must not touch (11 px text), px."""
HALO = 'stroke="white" stroke-width="3" paint-order="stroke" '
"""A label in the plot stays legible over the lines it crosses."""
CROSSING_ROWS = tuple(TOP + 12 + LABEL_ROW * k for k in range(8))
"""Where a forecast crossing's label may go, the first free row from the top."""


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    span = hi - lo
    if span <= 0:
        return [lo]
    raw = span / n
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 5, 10) if m * mag >= raw)
    start = math.ceil(lo / step) * step
    return [start + i * step for i in range(int((hi - start) / step) + 1)]


def panel(doc: dict[str, Any], quantity: str, title: str, scale: float, unit: str) -> str:
    """One SVG panel; quantity ``flat_length`` or ``peak_force_at_line_speed``."""
    pts: list[tuple[float, float, float | None, float | None]] = []
    for h in doc["history"]:
        if quantity == "flat_length":
            f = h["flat"]
            if f is not None:
                pts.append((h["timestamp"], f["length"], f["length_low"], f["length_high"]))
        elif h[quantity] is not None:
            pts.append((h["timestamp"], h[quantity], None, None))
    trend = doc["trend"][quantity]
    limits = {
        lv: doc["limits"][f"{lv}_{'length' if quantity == 'flat_length' else 'force'}"]
        for lv in ("watch", "inspect", "remove")
    }
    times = [p[0] for p in pts] or [h["timestamp"] for h in doc["history"]] or [time.time()]
    t0, t1 = min(times), max(times)
    if trend is not None:
        ends = [
            c["at"] for c in trend["crossings"] if c["at"] is not None and c["status"] != "reached"
        ]
        if ends:
            t1 = max(t1, min(max(ends), t1 + MAX_FORECAST))
    if t1 - t0 < DAY:
        t0, t1 = t0 - DAY / 2, t1 + DAY / 2
    pad = (t1 - t0) * 0.04
    t0, t1 = t0 - pad, t1 + pad
    values = [p[1] for p in pts] + [p[3] for p in pts if p[3] is not None] + list(limits.values())
    v0, v1 = 0.0, max(values) * 1.1

    def px(t: float) -> float:
        return LEFT + (t - t0) / (t1 - t0) * (W - LEFT - RIGHT)

    def py(v: float) -> float:
        return H - BOTTOM - (v - v0) / (v1 - v0) * (H - TOP - BOTTOM)

    out = [
        f'<svg class="plot" data-quantity="{quantity}" xmlns="http://www.w3.org/2000/svg" '
        f'width="{W}" height="{H}" viewBox="0 0 {W} {H}" role="img">',
        f'<text x="{LEFT}" y="16" font-size="13" font-weight="bold">{html.escape(title)} '
        f"({unit})</text>",
        f'<rect x="{LEFT}" y="{TOP}" width="{W - LEFT - RIGHT}" height="{H - TOP - BOTTOM}" '
        'fill="none" stroke="#888"/>',
    ]
    for v in _ticks(v0 * scale, v1 * scale):
        y = py(v / scale)
        out.append(
            f'<line x1="{LEFT - 4}" y1="{y:.1f}" x2="{LEFT}" y2="{y:.1f}" stroke="#888"/>'
            f'<text x="{LEFT - 6}" y="{y + 4:.1f}" font-size="11" text-anchor="end">'
            f"{v:g}</text>"
        )
    for t, label in time_ticks(t0, t1, W - LEFT - RIGHT):
        x = px(t)
        out.append(
            f'<line class="xtick" data-t="{t:.0f}" x1="{x:.1f}" y1="{H - BOTTOM}" x2="{x:.1f}" '
            f'y2="{H - BOTTOM + 4}" stroke="#888"/><text class="xtick-label" x="{x:.1f}" '
            f'y="{H - BOTTOM + 16}" font-size="11" text-anchor="middle">{label}</text>'
        )
    out.append(
        f'<text x="{W - RIGHT}" y="{H - 4}" font-size="11" text-anchor="end">date (UTC)</text>'
    )
    texts = {lv: f"{lv} {lim * scale:g}" for lv, lim in limits.items()}
    at = spread([py(lim) - 4 for lim in limits.values()], LABEL_ROW, TOP + 12, H - BOTTOM - 4)
    taken: list[Box] = []  # the labels placed in the plot, that the next ones must miss
    labels: list[str] = []  # drawn last, over the lines and points
    for (lv, lim), y in zip(limits.items(), at, strict=True):
        taken.append(text_box(W - RIGHT - 4, y, texts[lv], "end"))
        out.append(
            f'<line class="limit" data-level="{lv}" x1="{LEFT}" y1="{py(lim):.1f}" '
            f'x2="{W - RIGHT}" y2="{py(lim):.1f}" stroke="{LIMIT_COLOURS[lv]}" '
            f'stroke-dasharray="6 4"/>'
        )
        labels.append(
            f'<text class="limit-label" data-level="{lv}" x="{W - RIGHT - 4}" y="{y:.1f}" '
            f'font-size="11" text-anchor="end" {HALO}fill="{LIMIT_COLOURS[lv]}">{texts[lv]}</text>'
        )
    if trend is not None:
        ta, tb = trend["t_first"], t1 - pad
        n = 40
        ts = [ta + (tb - ta) * i / n for i in range(n + 1)]

        def line(t: float) -> tuple[float, float]:
            x = (t - trend["t_ref"]) / DAY
            se = math.hypot(trend["value_se"], x * trend["slope_se_per_day"])
            return trend["value_at_ref"] + trend["slope_per_day"] * x, se

        upper = [(px(t), py(min(v1, line(t)[0] + Z95 * line(t)[1]))) for t in ts]
        lower = [(px(t), py(max(v0, line(t)[0] - Z95 * line(t)[1]))) for t in ts]
        band = " ".join(
            f"{'M' if i == 0 else 'L'}{x:.1f},{y:.1f}"
            for i, (x, y) in enumerate(upper + lower[::-1])
        )
        out.append(
            f'<path class="band" d="{band} Z" fill="#3060c0" fill-opacity="0.15" stroke="none"/>'
        )
        mid = " ".join(
            f"{'M' if i == 0 else 'L'}{px(t):.1f},{py(min(v1, max(v0, line(t)[0]))):.1f}"
            for i, t in enumerate(ts)
        )
        out.append(f'<path class="trend" d="{mid}" fill="none" stroke="#3060c0" stroke-width="2"/>')
        for c in trend["crossings"]:
            if c["status"] == "forecast" and c["at"] is not None and c["at"] <= tb:
                x = px(c["at"])
                right = x > W - RIGHT - 140  # near the right edge: label to the left
                text = f"{c['level']} {time.strftime('%Y-%m-%d', time.gmtime(c['at']))}"
                lx, anchor = (x - 3, "end") if right else (x + 3, "start")
                y = free_row(lx, text, anchor, CROSSING_ROWS, taken)
                taken.append(text_box(lx, y, text, anchor))
                colour = LIMIT_COLOURS[c["level"]]
                out.append(
                    f'<line class="crossing" x1="{x:.1f}" y1="{TOP}" x2="{x:.1f}" '
                    f'y2="{H - BOTTOM}" stroke="{colour}" stroke-width="1"/>'
                )
                labels.append(
                    f'<text class="crossing-label" x="{lx:.1f}" y="{y:.1f}" font-size="11" '
                    f'text-anchor="{anchor}" {HALO}fill="{colour}">{text}</text>'
                )
    for t, v, lo, hi in pts:
        x = px(t)
        if lo is not None and hi is not None:
            out.append(
                f'<line x1="{x:.1f}" y1="{py(lo):.1f}" x2="{x:.1f}" y2="{py(hi):.1f}" '
                'stroke="#222"/>'
            )
        out.append(
            f'<circle class="point" cx="{x:.1f}" cy="{py(v):.1f}" r="4" fill="#222">'
            f"<title>{time.strftime('%Y-%m-%d %H:%M', time.gmtime(t))}: "
            f"{v * scale:.3g} {unit}</title></circle>"
        )
    if not pts:
        out.append(f'<text x="{W / 2}" y="{H / 2}" text-anchor="middle" fill="#888">no data</text>')
    out += labels
    out.append("</svg>")
    return "\n".join(out)


def wheel_svg(doc: dict[str, Any]) -> str:
    return (
        panel(doc, "flat_length", "flat length", 1e3, "mm")
        + "\n"
        + panel(doc, "peak_force_at_line_speed", "peak force at line speed", 1e-3, "kN")
    )
