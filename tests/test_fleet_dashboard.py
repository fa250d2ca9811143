"""The fleet dashboard in a real headless browser (Chromium from the OS packages): the
pages load, the flat wheel is shown, its trend plot renders with the limits drawn."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from service.fleet.alarms import apply
from service.fleet.dashboard import Dashboard
from service.fleet.limits import FleetLimits
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
    import json

    with urllib.request.urlopen(dashboard + "api/wheel/V1/1/left") as r:
        assert json.load(r)["wheel_id"] == "V1/1/left"
    for path, code in (("wheel/V1/x/left", 400), ("wheel/V9/1/left", 404), ("nope", 404)):
        try:
            urllib.request.urlopen(dashboard + path)
        except urllib.error.HTTPError as e:
            assert e.code == code
        else:
            raise AssertionError(f"{path} did not fail")
