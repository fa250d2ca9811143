"""Channels in, everywhere (issue 26, item 1): a measured passage of a detector's crib
channels in the contract, read from a CSV, checked against the site's cribs by
``railtwin diagnose``, ``railtwin feed-measured`` and the twin's pairing, and refused
clearly (the diagnosis from crib channels is not available yet), never diagnosed.

Fast: no physics runs here (the twin runs the stand-in ``StubPhysics``). The real channel
record is site S01's passage P01 of the handed-over ``track-sites`` data
(``tests/data/track-sites/README.md``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from pydantic import ValidationError

from schemas.diagnosis import MAX_MEASURED_SAMPLES, MeasuredPassage
from schemas.messages import MESSAGE_SCHEMA_VERSION
from service.clients.measured_io import MeasuredFileError, read_measured, read_measured_csv
from service.wire.measured_channels import (
    channel_mismatch,
    channels_mismatch,
)
from service.wire.site import load_site

DATA = Path(__file__).parent / "data" / "track-sites"
SITE = DATA / "S01.site.toml"
CSV = DATA / "S01_P01.csv"
PASSAGE = DATA / "S01_P01.passage.json"
CRIBS = [f"ch{i}" for i in range(1, 9)]


def channels(ids: list[str], n: int = 32) -> dict[str, list[float]]:
    return {c: [float(k + i) for k in range(n)] for i, c in enumerate(ids)}


def measured(**fields: Any) -> MeasuredPassage:
    return MeasuredPassage.model_validate(
        {"passage_id": "p1", "sample_rate": 1e4, "t_start": 0.0, **fields}
    )


def write_csv(path: Path, ids: list[str], n: int = 40, rate: float = 1e4, t0: float = 0.0) -> Path:
    rows = [",".join(["t_s", *ids])]
    rows += [
        ",".join([f"{t0 + k / rate:.6f}", *(f"{1000.0 * (k + i):.2f}" for i in range(len(ids)))])
        for k in range(n)
    ]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


# -- the contract -------------------------------------------------------------------------


def test_a_measured_passage_carries_channels_or_force_and_the_version_is_1_4() -> None:
    m = measured(channels=channels(["ch1", "ch2"]))
    assert m.force is None and m.channel_ids == ("ch1", "ch2")
    assert m.samples == 32 and m.duration == pytest.approx(31e-4)
    assert MeasuredPassage.model_validate_json(m.model_dump_json()) == m
    assert MESSAGE_SCHEMA_VERSION == "1.4" and m.schema_version == "1.4"
    f = measured(force=[6e4] * 20)  # the contact-force sensor keeps working
    assert f.channels is None and f.samples == 20 and f.channel_ids == ()
    # a 1.3 producer's force measurement (no channels key) still reads
    old = '{"schema_version": "1.3", "passage_id": "p", "sample_rate": 1e4, "t_start": 0,'
    assert MeasuredPassage.model_validate_json(old + '"force": ' + str([1.0] * 16) + "}").samples


@pytest.mark.parametrize(
    ("fields", "where", "fragment"),
    [
        ({}, "force", "exactly one of force"),
        ({"force": [1.0] * 16, "channels": channels(["a"])}, "force", "exactly one of force"),
        ({"channels": {}}, "channels", "1 to 32"),
        ({"channels": channels([f"c{i}" for i in range(33)])}, "channels", "1 to 32"),
        ({"channels": {"a": [1.0] * 16, "b": [1.0] * 17}}, "channels.b", "same samples"),
        ({"channels": channels(["a"], n=15)}, "channels.a", "at least 16"),
        ({"channels": {"a/b": [1.0] * 16}}, "channels.a/b", "pattern"),
        ({"channels": {"a": [1.0] * 15 + [float("nan")]}}, "channels.a.15", "finite"),
        (
            {"channels": channels(["a", "b"], n=MAX_MEASURED_SAMPLES // 2 + 1)},
            "channels",
            "values in all",
        ),
    ],
)
def test_bad_channels_are_refused_naming_the_field(
    fields: dict[str, Any], where: str, fragment: str
) -> None:
    with pytest.raises(ValidationError) as info:
        measured(**fields)
    e = info.value.errors()[0]
    path = ".".join(map(str, e["loc"])) or str((e.get("ctx") or {}).get("field"))
    assert path.startswith(where), e
    assert fragment in e["msg"], e["msg"]


def test_channel_ids_must_be_exactly_the_sites_cribs() -> None:
    site = load_site(SITE)
    assert channels_mismatch(measured(channels=channels(CRIBS)), site) is None
    assert channels_mismatch(measured(channels=channels(CRIBS[::-1])), site) is None  # any order
    assert channels_mismatch(measured(force=[1.0] * 16), site) is None
    bad = channels_mismatch(measured(channels=channels([*CRIBS[:6], "ch9", "x"])), site)
    assert bad is not None and "missing ch7, ch8; extra ch9, x" in bad
    assert "ch1, ch2, ch3, ch4, ch5, ch6, ch7, ch8" in bad
    assert channel_mismatch(["ch1"], ()) is not None
    assert "no detector" in (channel_mismatch(["ch1"], ()) or "")


# -- the measured CSV ---------------------------------------------------------------------


def test_the_handed_over_channel_csv_is_read_at_the_sites_rate() -> None:
    site = load_site(SITE)
    m = read_measured(CSV, "S01_P01", sample_rate=site.diagnosis.sample_rate)
    assert m.channel_ids == tuple(CRIBS) and m.force is None
    assert m.sample_rate == 1e4 and m.t_start == 0.0 and m.samples == 2167
    raw = np.loadtxt(CSV, delimiter=",", skiprows=1)
    assert np.array_equal(np.asarray(m.channels["ch5"]), raw[:, 5])  # type: ignore[index]
    assert channels_mismatch(m, site) is None
    assert read_measured_csv(CSV, "x").sample_rate == pytest.approx(1e4)  # no rate given


def test_a_force_csv_reads_as_before(tmp_path: Path) -> None:
    p = write_csv(tmp_path / "f.csv", ["force_N"], n=20, rate=2e4, t0=-0.001)
    m = read_measured_csv(p, "p1", speed=30.0, sample_rate=2e4)
    assert m.channels is None and m.samples == 20 and m.t_start == pytest.approx(-0.001)
    assert m.force is not None and m.force[3] == 3000.0 and m.speed == 30.0


def _edited(path: Path, line: int, text: str) -> Path:
    lines = path.read_text(encoding="utf-8").splitlines()
    lines[line - 1] = text
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("line", "text", "fragment"),
    [
        (1, "time,ch1,ch2", "line 1: header must be 't_s,force_N'"),
        (1, "t_s", "line 1: header must be"),
        (1, "t_s,ch1,ch1", "line 1, column 3: crib id 'ch1' repeated"),
        (1, "t_s,ch1,c/2", "line 1, column 3: 'c/2' is not a crib id"),
        (1, "t_s,force_N,ch2", "line 1, column 2: 'force_N' is the contact force's only"),
        (7, "0.000500,1.0", "line 7: expected 3 values (t_s,ch1,ch2), got 2"),
        (7, "0.000500,1.0,2.0,3.0", "line 7: expected 3 values"),
        (9, "0.000700,,2.0", "line 9, column 2 (ch1): not a number: ''"),
        (9, "0.000700,1.0,abc", "line 9, column 3 (ch2): not a number: 'abc'"),
        (12, "0.001000,1.0,nan", "line 12, column 3 (ch2): must be finite, got 'nan'"),
        (12, "inf,1.0,2.0", "line 12, column 1 (t_s): must be finite"),
        (12, "0.000900,1.0,2.0", "line 12, column 1 (t_s): time must increase"),
        (12, "0.001050,1.0,2.0", "line 12, column 1 (t_s): 0.00105 s is 0.00015 s after"),
    ],
)
def test_a_bad_csv_is_refused_naming_file_line_and_column(
    tmp_path: Path, line: int, text: str, fragment: str
) -> None:
    p = _edited(write_csv(tmp_path / "m.csv", ["ch1", "ch2"], n=40), line, text)
    with pytest.raises(MeasuredFileError) as info:
        read_measured_csv(p, "p1")
    msg = str(info.value)
    assert msg.startswith(f"{p}: ") and "\n" not in msg
    assert fragment in msg, msg


def test_time_must_keep_the_sites_sample_rate(tmp_path: Path) -> None:
    p = write_csv(tmp_path / "m.csv", CRIBS, n=40, rate=2e4)
    with pytest.raises(MeasuredFileError, match=r"line 3, column 1 \(t_s\): .*site's sample rate"):
        read_measured_csv(p, "p1", sample_rate=1e4)
    assert read_measured_csv(p, "p1", sample_rate=2e4).sample_rate == 2e4


def test_a_short_or_empty_csv_is_refused(tmp_path: Path) -> None:
    with pytest.raises(MeasuredFileError, match="15 samples, at least 16"):
        read_measured_csv(write_csv(tmp_path / "s.csv", ["ch1"], n=15), "p1")
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(MeasuredFileError, match="line 1: header"):
        read_measured_csv(tmp_path / "e.csv", "p1")
    with pytest.raises(MeasuredFileError, match="passage_id"):
        read_measured_csv(write_csv(tmp_path / "b.csv", ["ch1"], n=16), "not/an id")
