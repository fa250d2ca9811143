"""The fleet dashboard in a real headless browser (Chromium from the OS packages): the
pages load, the flat wheel is shown, its trend plot renders with the limits drawn; the plots'
date ticks fall on whole hours, days or months with unique labels, and no two labels in a
plot overlap (estimated, and as Chromium draws them)."""

from __future__ import annotations

import dataclasses
import html
import itertools
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from service.fleet import plot
from service.fleet.alarms import apply
from service.fleet.dashboard import Dashboard
from service.fleet.history import wheel_document
from service.fleet.limits import FleetLimits
from service.fleet.plot_layout import HOUR, MAX_TICKS, Box, text_box, text_width, time_ticks
from service.fleet.service import FleetService
from service.fleet.store import open_store
from tests.fleet_support import DAY, T0, make_entry


def _find_chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


@pytest.fixture(scope="session")
def chromium() -> str:
    """Chromium's path; installed from the OS packages when missing and run as root."""
    path = _find_chromium()
    if path is None and hasattr(os, "geteuid") and os.geteuid() == 0 and shutil.which("apt-get"):
        env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
        cmd = ["apt-get", "install", "-y", "--no-install-recommends", "chromium"]
        if subprocess.run(cmd, env=env, capture_output=True, check=False).returncode != 0:
            subprocess.run(["apt-get", "update"], env=env, capture_output=True, check=False)
            subprocess.run(cmd, env=env, capture_output=True, check=False)
        path = _find_chromium()
    if path is None:
        pytest.skip(
            "no Chromium here and it cannot be installed (needs root and apt-get: "
            "apt-get install chromium)"
        )
    return path


def _browser(chromium: str, *args: str) -> str:
    with tempfile.TemporaryDirectory(prefix="railtwin-chromium-") as profile:
        out = subprocess.run(
            [
                chromium,
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--no-first-run",
                f"--user-data-dir={profile}",
                *args,
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout


@pytest.fixture
def dashboard(tmp_path: Path) -> Iterator[str]:
    store = open_store(str(tmp_path / "fleet.sqlite"))
    for d, site, verdict, length in [
        (0, "km12", "watch", 0.032),
        (1, "km48", "watch", 0.038),
        (2, "km97", "inspect", 0.044),
    ]:
        store.insert(
            [
                make_entry(
                    site,
                    f"t{d}-a1-l",
                    day=d,
                    verdict=verdict,
                    length=length,
                    half_width=0.001,
                    force_line=300e3 + 20e3 * d,
                ),
                make_entry(site, f"t{d}-a1-r", wheel="V1/1/right", day=d),
            ]
        )
        apply(store, "V1/1/left", FleetLimits.defaults(), horizon=30 * DAY, now=T0 + d * DAY)
    session = zenoh.open(zenoh.Config())  # no endpoints: the pages read the store only
    svc = FleetService(session, store)
    dash = Dashboard(svc, "127.0.0.1", 0)
    dash.start()
    try:
        yield dash.url
    finally:
        dash.stop()
        session.close()
        store.close()


def test_pages_in_a_headless_browser(chromium: str, dashboard: str, tmp_path: Path) -> None:
    index = _browser(chromium, "--dump-dom", dashboard)
    assert "railtwin fleet" in index
    assert len(re.findall(r"<tr class=\"site\">", index)) == 3  # km12, km48, km97
    assert "V1/1/left" in index and "verdict escalated from watch to inspect" in index
    vehicle = _browser(chromium, "--dump-dom", dashboard + "vehicle?q=V1")
    assert "/wheel/V1/1/left" in vehicle and "/wheel/V1/1/right" in vehicle
    page = _browser(chromium, "--dump-dom", dashboard + "wheel/V1/1/left")
    assert "<h1>wheel V1/1/left</h1>" in page
    assert len(re.findall(r"<tr class=\"entry\">", page)) == 3
    svgs = re.findall(r"<svg class=\"plot\" data-quantity=\"(\w+)\".*?</svg>", page, re.S)
    assert svgs == ["flat_length", "peak_force_at_line_speed"]
    flat_svg = re.search(
        r"<svg class=\"plot\" data-quantity=\"flat_length\".*?</svg>", page, re.S
    ).group(0)  # type: ignore[union-attr]
    trend = re.search(r'class="trend" d="([^"]+)"', flat_svg).group(1)  # type: ignore[union-attr]
    assert trend.count("L") >= 20  # the fitted line and its forecast, drawn point by point
    assert flat_svg.count('class="point"') == 3
    assert {"watch", "inspect", "remove"} <= set(re.findall(r'data-level="(\w+)"', flat_svg))
    assert 'class="crossing"' in flat_svg  # the forecast date of the remove limit
    # the page renders as pixels: the plot area is not blank
    png = tmp_path / "wheel.png"
    _browser(
        chromium, f"--screenshot={png}", "--window-size=1000,900", dashboard + "wheel/V1/1/left"
    )
    from matplotlib.image import imread

    img = imread(str(png))
    assert img.shape[0] >= 800 and (img[..., :3] < 0.5).mean() > 0.002


def test_api_and_errors(dashboard: str) -> None:
    with urllib.request.urlopen(dashboard + "api/wheel/V1/1/left") as r:
        assert json.load(r)["wheel_id"] == "V1/1/left"
    for path, code in (("wheel/V1/x/left", 400), ("wheel/V9/1/left", 404), ("nope", 404)):
        try:
            urllib.request.urlopen(dashboard + path)
        except urllib.error.HTTPError as e:
            assert e.code == code
        else:
            raise AssertionError(f"{path} did not fail")


# --- the wheel page's plots: the date axis and the labels in the plot -----------------------

PLOT_WIDTH = plot.W - plot.LEFT - plot.RIGHT
TEXT = re.compile(
    r'<text class="(?P<cls>[\w-]+)"[^>]*? x="(?P<x>[\d.]+)" y="(?P<y>[\d.]+)"'
    r'[^>]*?text-anchor="(?P<anchor>\w+)"[^>]*>(?P<text>[^<]+)</text>'
)


def _wheel_doc(days: list[float], limits: FleetLimits | None = None) -> dict[str, Any]:
    """The wheel document of diagnoses of V1/1/left on these days after T0."""
    history = [
        make_entry(
            "km12",
            f"t{i}-a1-l",
            day=d,
            verdict="watch",
            length=0.032 + 0.004 * d,
            half_width=0.001,
            force_line=300e3 + 20e3 * d,
        )
        for i, d in enumerate(days)
    ]
    return wheel_document("V1/1/left", history, limits or FleetLimits.defaults())


def _panels(doc: dict[str, Any]) -> dict[str, str]:
    svg = plot.wheel_svg(doc)
    found = re.findall(r'(<svg class="plot" data-quantity="(\w+)".*?</svg>)', svg, re.S)
    return {quantity: panel for panel, quantity in found}


def _labels(svg: str, *classes: str) -> list[tuple[str, Box]]:
    return [
        (m["text"], text_box(float(m["x"]), float(m["y"]), m["text"], m["anchor"]))
        for m in TEXT.finditer(svg)
        if m["cls"] in classes
    ]


def _no_two_overlap(labels: list[tuple[str, Box]]) -> None:
    for (a, box_a), (b, box_b) in itertools.combinations(labels, 2):
        assert not box_a.overlaps(box_b), f"{a!r} {box_a} overlaps {b!r} {box_b}"


@pytest.mark.parametrize("days", [0.3, 1.0, 2.0, 3.0, 5.0, 12.0, 100.0, 400.0, 3000.0])
def test_date_ticks_fall_on_whole_hours_days_or_months_with_unique_labels(days: float) -> None:
    t0 = T0 + 0.37 * DAY  # a start at no boundary
    t1 = t0 + days * DAY
    ticks = time_ticks(t0, t1, PLOT_WIDTH)
    times, labels = [t for t, _ in ticks], [label for _, label in ticks]
    assert 2 <= len(ticks) <= MAX_TICKS, ticks
    assert len(set(labels)) == len(labels), labels  # never 11-19 twice
    assert all(t0 <= t <= t1 for t in times)
    for t, label in ticks:
        g = time.gmtime(t)
        assert t % HOUR == 0, label  # a whole hour at least
        if days >= 3.0:  # whole days (or months) over a span of days: no hours in the label
            assert g.tm_hour == 0 and ":" not in label, label
        if days >= 400.0:
            assert g.tm_mday == 1 and label == time.strftime("%Y-%m", g)
        elif ":" in label:
            assert label == time.strftime("%m-%d %H:%M", g)
        else:
            assert label == time.strftime("%m-%d", g)
    x = [plot.LEFT + (t - t0) / (t1 - t0) * PLOT_WIDTH for t in times]
    _no_two_overlap([(s, text_box(xi, 0.0, s, "middle")) for xi, s in zip(x, labels, strict=True)])


def test_three_days_of_diagnoses_are_ticked_by_day() -> None:
    for quantity, svg in _panels(_wheel_doc([0.0, 1.0, 2.0, 2.9])).items():
        ticks = [float(t) for t in re.findall(r'class="xtick" data-t="(\d+)"', svg)]
        labels = [text for text, _ in _labels(svg, "xtick-label")]
        assert len(ticks) == len(labels) >= 3, quantity
        assert all(t % DAY == 0 for t in ticks), quantity  # midnight UTC
        assert labels == [time.strftime("%m-%d", time.gmtime(t)) for t in ticks]
        assert len(set(labels)) == len(labels), labels


def test_close_limits_get_labels_that_do_not_overlap() -> None:
    limits = dataclasses.replace(
        FleetLimits.defaults(),
        watch_force=345e3,
        inspect_force=350e3,
        remove_force=360e3,
        watch_length=0.049,
        inspect_length=0.050,
        remove_length=0.052,
    )
    panels = _panels(_wheel_doc([0.0, 0.4, 1.1, 2.3, 2.9], limits))
    force = _labels(panels["peak_force_at_line_speed"], "limit-label")
    assert [t for t, _ in force] == ["watch 345", "inspect 350", "remove 360"]
    flat = panels["flat_length"]
    assert 'class="crossing-label"' in flat  # the forecast dates are labelled too
    for svg in panels.values():
        inside = _labels(svg, "limit-label", "crossing-label")
        _no_two_overlap(inside)
        assert all(box.y0 >= plot.TOP and box.y1 <= plot.H - plot.BOTTOM for _, box in inside)
        # the highest limit's label stays the highest
        ys = {t.split()[0]: box.y0 for t, box in _labels(svg, "limit-label")}
        assert ys["remove"] < ys["inspect"] < ys["watch"]


BBOX_SCRIPT = """<pre id="boxes"></pre><script>
const out = [];
for (const t of document.querySelectorAll("text[class]")) {
  const b = t.getBBox();
  out.push([t.closest("svg").dataset.quantity, t.getAttribute("class"), t.textContent,
            b.x, b.y, b.width, b.height]);
}
document.getElementById("boxes").textContent = JSON.stringify(out);
</script>"""


def test_labels_do_not_overlap_as_chromium_draws_them(chromium: str, tmp_path: Path) -> None:
    """The boxes Chromium measures (getBBox), not estimated: apart, and within the estimate."""
    limits = dataclasses.replace(
        FleetLimits.defaults(), inspect_force=350e3, remove_force=360e3, watch_force=345e3
    )
    page = tmp_path / "plots.html"
    doc = _wheel_doc([0.0, 0.4, 1.1, 2.3, 2.9], limits)
    page.write_text(f"<html><body>{plot.wheel_svg(doc)}{BBOX_SCRIPT}</body></html>")
    dom = _browser(chromium, "--dump-dom", page.as_uri())
    found = re.search(r'<pre id="boxes">(.*?)</pre>', dom, re.S)
    assert found is not None, dom[:2000]
    measured = json.loads(html.unescape(found.group(1)))
    assert {cls for _, cls, *_ in measured} >= {"xtick-label", "limit-label", "crossing-label"}
    for quantity in ("flat_length", "peak_force_at_line_speed"):
        for group in (("xtick-label",), ("limit-label", "crossing-label")):
            boxes = [
                (text, Box(x, y, x + w, y + h))
                for q, cls, text, x, y, w, h in measured
                if q == quantity and cls in group
            ]
            _no_two_overlap(boxes)
    for _, _, text, _, _, w, _ in measured:
        assert w <= text_width(text), (text, w)  # the estimate the layout uses is an upper bound
