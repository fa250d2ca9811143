"""``railtwin calibrate``: the track of a detector site from its round wheels, and its answers
to bad input (one line naming the file and the field, exit 2, before any physics).

The data: three round wheels of site S02 of the independent solver's ``track-sites`` set
(``tests/data/calibration/README.md``): a slab whose nominal pad stiffness is 1.27 x the
truth; the fast wheel (139 km/h) shows it at 1.13 x its noise, the track does not show in the
slower ones.
"""

from __future__ import annotations

import gzip
import json
import shutil
import tomllib
from pathlib import Path

import pytest

from service.physics.model_version import foundation_fingerprint
from service.wire.site import load_site
from tests.conftest import EXAMPLES
from tests.test_cli import run_main

DATA = Path(__file__).parent / "data" / "calibration"
SITE = DATA / "S02.site.toml"
TRUTH = json.loads((DATA / "S02_truth.json").read_text())
WHEELS = ("S02_P01", "S02_P03", "S02_P11")


def _wheels(tmp_path: Path, names: tuple[str, ...] = WHEELS) -> Path:
    d = tmp_path / "wheels"
    d.mkdir()
    for n in names:
        shutil.copyfile(DATA / f"{n}.json", d / f"{n}.json")
        with gzip.open(DATA / f"{n}.csv.gz", "rb") as src, (d / f"{n}.csv").open("wb") as dst:
            shutil.copyfileobj(src, dst)
    return d


def _refused(argv: list[str], capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    code, out, err = run_main(argv, capsys)
    assert code == 2, err
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]


def _argv(d: Path, tmp_path: Path, site: Path = SITE) -> list[str]:
    return ["calibrate", "--site", str(site), str(d), "--out", str(tmp_path / "out.site.toml")]


def test_a_missing_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _refused(_argv(tmp_path / "nowhere", tmp_path), capsys, "nowhere", "not a directory")


def test_an_empty_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "empty").mkdir()
    _refused(_argv(tmp_path / "empty", tmp_path), capsys, "empty", "no NAME.json/NAME.csv pairs")


def test_a_passage_without_its_channels(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    (d / "S02_P11.csv").unlink()
    _refused(_argv(d, tmp_path), capsys, "S02_P11.json", "no S02_P11.csv")


def test_channels_without_their_passage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    (d / "S02_P11.json").rename(d / "other.json")
    shutil.copyfile(d / "S02_P11.csv", d / "other.csv")
    _refused(_argv(d, tmp_path), capsys, "S02_P11.csv", "no S02_P11.json")


def test_wrong_crib_ids(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    csv = d / "S02_P11.csv"
    lines = csv.read_text().splitlines()
    lines[0] = lines[0].replace("ch8", "ch9")
    csv.write_text("\n".join(lines) + "\n")
    _refused(_argv(d, tmp_path), capsys, "S02_P11.csv", "channels", "missing ch8", "extra ch9")


def test_an_unreadable_passage(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    (d / "S02_P11.json").write_text("{bad")
    _refused(_argv(d, tmp_path), capsys, "S02_P11.json")


def test_a_bad_number_in_the_channels(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    csv = d / "S02_P11.csv"
    lines = csv.read_text().splitlines()
    lines[5] = lines[5].replace(",", ",x", 1)
    csv.write_text("\n".join(lines) + "\n")
    _refused(_argv(d, tmp_path), capsys, "S02_P11.csv", "line 6")


def test_a_flat_wheel_is_not_for_calibration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    doc = json.loads((d / "S02_P11.json").read_text())
    doc["outline"] = {"kind": "flat", "length": 0.04}
    (d / "S02_P11.json").write_text(json.dumps(doc))
    _refused(_argv(d, tmp_path), capsys, "S02_P11.json", "outline", "round wheels only")


@pytest.mark.parametrize("name", ["site_compliant.toml"])
def test_a_site_without_a_track(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    _refused(_argv(d, tmp_path, EXAMPLES / name), capsys, name, "foundation.kind", "compliant")


def test_a_rigid_site(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = SITE.read_text()
    start = text.index("[foundation]")
    end = text.index("[detector]")
    rigid = tmp_path / "rigid.toml"
    rigid.write_text(text[:start] + '[foundation]\nkind = "rigid"\n' + text[end:])
    d = _wheels(tmp_path, ("S02_P11",))
    # a detector needs a track: the site file itself is refused, naming the field
    _refused(_argv(d, tmp_path, rigid), capsys, "rigid.toml")


def test_out_is_a_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path, ("S02_P11",))
    argv = _argv(d, tmp_path)
    argv[-1] = str(tmp_path)
    _refused(argv, capsys, "--out", "is a directory")


def test_calibrate_finds_the_slab_pad(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _wheels(tmp_path)
    out = tmp_path / "out.site.toml"
    code, stdout, err = run_main([*_argv(d, tmp_path), "--json"], capsys)
    assert code == 0, err
    report = json.loads(stdout)
    true = TRUTH["track_true"]
    k = next(p for p in report["parameters"] if p["name"] == "pad.stiffness")
    c = next(p for p in report["parameters"] if p["name"] == "pad.damping")
    # the nominal is 1.27 x the truth; the three wheels put it within 3 % (the 12 of the set
    # within 0.2 %, docs/service.md), with an interval that holds the truth
    assert k["nominal"] / true["k_p"] == pytest.approx(1.266, abs=1e-3)
    assert abs(k["estimate"] / true["k_p"] - 1.0) < 0.03
    assert k["low"] <= true["k_p"] <= k["high"]
    assert k["identifiable"] == "yes"
    assert c["low"] <= true["c_p"] <= c["high"]
    # the fast wheel: 1.13 x its noise on the nominal track, within 3 % of it calibrated
    fast = next(p for p in report["passages"] if p["name"] == "S02_P11")
    sigma_true = TRUTH["passages"]["S02_P11"]["noise_sigma_N"]
    assert abs(fast["noise_sigma"] / sigma_true - 1.0) < 0.02
    assert fast["rms_over_sigma_nominal"] > 1.08
    assert fast["rms_over_sigma_calibrated"] < 1.03
    # the site file: the estimates in the foundation, the [calibration] table naming them
    site = load_site(out)
    assert site.calibration is not None and site.calibration.source == "offline"
    assert site.calibration.id == foundation_fingerprint(site.foundation)
    assert site.calibration.wheels == 3
    assert site.foundation.pad.stiffness == pytest.approx(k["estimate"])  # type: ignore[union-attr]
    raw = tomllib.loads(out.read_text())
    assert [p["name"] for p in raw["calibration"]["parameters"]] == ["pad.stiffness", "pad.damping"]
    assert "wheels simulated" in err
