"""The Rerun recording: read back with RrdReader, entities, values and the blueprint."""

from __future__ import annotations

import doctest
from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun.blueprint as rrb
import rerun.chunk as rc

import service.recording.rerun_recording
from schemas.messages import PassageResult, RailState
from schemas.result import Summary, Transition
from service.recording.rerun_recording import (
    SLOT_MM,
    RerunRecording,
    default_blueprint,
    entities,
)

INDEXES = ("x_mm", "passage", "diagnosis", "diagnosis_mm", "time", "passage_time")
"""Read as int64 (the timestamps ``time`` and ``passage_time`` in ns); -1 where absent."""


def rrd_columns(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """{entity: {column: values}} of the non-static scalar and index columns of a .rrd.

    Index columns an entity has in some chunks only are padded with -1."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for chunk in rc.RrdReader(str(path)).stream():
        batch: pa.RecordBatch = chunk.to_record_batch()
        if "Scalars:scalars" not in batch.schema.names:
            continue
        cols = out.setdefault(str(chunk.entity_path), {})
        before = len(cols.get("values", ()))
        for name in INDEXES:
            new = (
                np.asarray(batch[name].cast(pa.int64()))
                if name in batch.schema.names
                else np.full(batch.num_rows, -1, np.int64)
            )
            cols[name] = np.concatenate([cols.get(name, np.full(before, -1, np.int64)), new])
        values = np.asarray(batch["Scalars:scalars"].flatten())
        cols["values"] = np.concatenate([cols.get("values", np.empty(0)), values])
    return out


def rrd_texts(path: Path) -> dict[str, list[tuple[int, str]]]:
    """{entity: [(passage index or -1, text)]} of the TextLog and TextDocument rows."""
    out: dict[str, list[tuple[int, str]]] = {}
    for chunk in rc.RrdReader(str(path)).stream():
        batch: pa.RecordBatch = chunk.to_record_batch()
        column = next(
            (n for n in ("TextLog:text", "TextDocument:text") if n in batch.schema.names), None
        )
        if column is None:
            continue
        texts = batch[column].flatten().to_pylist()
        passages = (
            batch["passage"].cast(pa.int64()).to_pylist()
            if "passage" in batch.schema.names
            else [-1] * len(texts)
        )
        out.setdefault(str(chunk.entity_path), []).extend(zip(passages, texts, strict=True))
    return out


def rrd_entities(path: Path) -> set[str]:
    """Every entity path that has data (static or not), properties aside."""
    return {
        str(c.entity_path)
        for c in rc.RrdReader(str(path)).stream()
        if not str(c.entity_path).startswith("/__")
    }


def passage_indexes(path: Path, site_id: str) -> dict[str, int]:
    """{passage id: its index on the ``passage`` time line}, from the ``wheel`` documents."""
    docs = rrd_texts(path).get(entities(site_id)["wheel"], [])
    return {text.split("\n", 1)[0].removeprefix("### "): index for index, text in docs}


def of_passage(cols: dict[str, np.ndarray], index: int) -> dict[str, np.ndarray]:
    """The rows of one passage (``passage`` time line)."""
    keep = cols["passage"] == index
    return {k: v[keep] for k, v in cols.items()}


def result(pid: str, n: int = 50, load: float = 50e3, timestamp: float = 0.0) -> PassageResult:
    x = np.linspace(0.0, 2.0, n)
    force = load + 1e3 * np.sin(x)
    return PassageResult(
        site_id="s",
        passage_id=pid,
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=timestamp,
        speed=40.0,
        sample_rate=1000.0,
        t_start=0.0,
        site_length=2.0,
        x=x.tolist(),
        force=force.tolist(),
        indentation=(force * 1e-9).tolist(),
        y_c=[0.0] * n,
        y_ck=(x * 1e-6).tolist(),
        transitions=[
            Transition(t=0.01, kind="loss", x=0.4),
            Transition(t=0.02, kind="contact", x=0.8),
        ],
        summary=Summary(
            peak_force=float(force.max()),
            min_force=0.0,
            contact_losses=1,
            first_loss_time=0.01,
            time_out_of_contact=0.01,
            max_indentation=6e-5,
            max_dent=0.0,
        ),
        rail_revision=0,
        wall_time=0.001,
        steps=10,
    )


def dented(passages_done: int) -> RailState:
    return RailState(
        site_id="s",
        revision=1,
        passages_done=passages_done,
        x=[0.0, 1.0, 2.0],
        y=[0.0, -1e-6, 0.0],
        dent=[0.0, 1e-6, 0.0],
        max_dent=1e-6,
    )


T0 = 1_780_000_000.0
"""A passage's own time (UNIX s) in 2026."""


def record(path: Path, n: int, part_passages: int = 5000, t0: float = T0) -> list[PassageResult]:
    """``n`` passages (each with its own load, 10 s apart from ``t0``), a dent after the
    second."""
    rec = RerunRecording(path, "s", part_passages=part_passages)
    rec.log_rail(np.linspace(0.0, 2.0, 21), np.zeros(21))
    results = [result(f"p{i}", load=50e3 + 100.0 * i, timestamp=t0 + 10.0 * i) for i in range(n)]
    for i, r in enumerate(results):
        rec.log_passage(r)
        if i == 1:
            rec.log_dent(r.passage_id, dented(i + 1))
    rec.close()
    return results


def test_recording_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "run.rrd"
    a, b = record(path, 2)

    reader = rc.RrdReader(str(path))
    assert len(reader.blueprints()) == 1
    e = entities("s")
    cols = rrd_columns(path)
    for role in ("force", "indentation", "y_c", "y_ck", "transitions", "profile", "dent"):
        assert e[role] in cols, role
    f0 = of_passage(cols[e["force"]], 0)
    np.testing.assert_array_equal(f0["values"], np.asarray(a.force))  # SI: N
    np.testing.assert_array_equal(f0["x_mm"], np.rint(np.asarray(a.x) * 1000).astype(np.int64))
    f1 = of_passage(cols[e["force"]], 1)
    np.testing.assert_array_equal(f1["values"], np.asarray(b.force))
    np.testing.assert_array_equal(
        f1["x_mm"] - SLOT_MM, np.rint(np.asarray(b.x) * 1000).astype(np.int64)
    )
    np.testing.assert_array_equal(of_passage(cols[e["transitions"]], 0)["x_mm"], [400, 800])
    dent = cols[e["dent"]]
    assert set(dent["passage"]) == {1}
    np.testing.assert_allclose(dent["values"], [0.0, 1e-6, 0.0])  # m
    assert set(dent["passage_time"]) == {round(b.timestamp * 1e9)}
    np.testing.assert_array_equal(dent["x_mm"], SLOT_MM + np.array([0, 1000, 2000]))


def test_the_entity_set_does_not_grow_with_the_passages(tmp_path: Path) -> None:
    few, many = tmp_path / "few.rrd", tmp_path / "many.rrd"
    record(few, 3)
    results = record(many, 30)
    assert rrd_entities(few) == rrd_entities(many)
    assert rrd_entities(many) <= set(entities("s").values())

    cols = rrd_columns(many)
    texts = rrd_texts(many)
    e = entities("s")
    assert passage_indexes(many, "s") == {r.passage_id: i for i, r in enumerate(results)}
    wheels = dict(texts[e["wheel"]])
    lines = dict(texts[e["passages"]])
    slots = set()
    for index, r in enumerate(results):  # every wheel: by its index, with its id
        force = of_passage(cols[e["force"]], index)
        np.testing.assert_array_equal(force["values"], np.asarray(r.force))
        slots.add(int(force["x_mm"].min()) // SLOT_MM)
        assert wheels[index].startswith(f"### {r.passage_id}\n")
        assert f"peak F **{r.summary.peak_force:.4g} N**" in wheels[index]
        assert lines[index].startswith(f"#{index} {r.passage_id} (train t axle 0 right)")
    assert slots == set(range(len(results)))  # one slot each: wheels never overlap on x_mm


def test_a_long_run_goes_on_in_parts_of_one_recording(tmp_path: Path) -> None:
    results = record(tmp_path / "run.rrd", 25, part_passages=10)
    parts = [tmp_path / "run.rrd", tmp_path / "run-002.rrd", tmp_path / "run-003.rrd"]
    assert sorted(tmp_path.glob("*.rrd")) == sorted(parts)
    ids = {r.recording_id for p in parts for r in rc.RrdReader(str(p)).recordings()}
    assert len(ids) == 1  # the viewer shows the parts as one recording
    e = entities("s")
    found: dict[str, int] = {}
    for part, first in zip(parts, (0, 10, 20), strict=True):
        assert rrd_entities(part) == rrd_entities(parts[0])  # styles and rail in every part
        assert len(rc.RrdReader(str(part)).blueprints()) == 1
        index = passage_indexes(part, "s")
        assert sorted(index.values()) == list(range(first, min(first + 10, 25)))
        found |= index
        cols = rrd_columns(part)
        for pid, i in index.items():
            np.testing.assert_array_equal(
                of_passage(cols[e["force"]], i)["values"], np.asarray(results[i].force)
            )
            assert pid == results[i].passage_id
    assert len(found) == 25


def test_the_slot_example_holds() -> None:
    result = doctest.testmod(service.recording.rerun_recording)
    assert result.attempted >= 1 and result.failed == 0


def test_samples_lie_on_the_wall_clock_and_passages_continue_across_runs(tmp_path: Path) -> None:
    """``time``: the passage's own time + x/speed for every sample; ``passage_time``: the
    passage's time, so a second run's wheels come after the first run's (``passage``
    restarts at 0 in each run, these do not)."""
    first, second = tmp_path / "run1.rrd", tmp_path / "run2.rrd"
    a = record(first, 3)
    b = record(second, 2, t0=T0 + 3600.0)  # the next run, an hour later
    e = entities("s")
    stamps: list[int] = []
    for path, results in ((first, a), (second, b)):
        cols = rrd_columns(path)
        for index, r in enumerate(results):
            for role in ("force", "indentation", "y_c", "y_ck"):
                rows = of_passage(cols[e[role]], index)
                t = r.timestamp + np.asarray(r.x) / r.speed
                np.testing.assert_allclose(rows["time"] / 1e9, t, rtol=0, atol=1e-6)
                assert set(rows["passage_time"]) == {round(r.timestamp * 1e9)}
            tr = of_passage(cols[e["transitions"]], index)
            np.testing.assert_allclose(
                tr["time"] / 1e9, r.timestamp + np.array([0.4, 0.8]) / 40.0, rtol=0, atol=1e-6
            )
            stamps.append(int(of_passage(cols[e["force"]], index)["passage_time"][0]))
    assert stamps == sorted(stamps) and len(set(stamps)) == 5  # one time line over both runs
    assert list(of_passage(rrd_columns(second)[e["force"]], 0)["passage"][:1]) == [0]


def test_si_units_with_the_unit_in_every_name(tmp_path: Path) -> None:
    """N and m as in the messages; each series and each plot names its unit; no kN, no µm."""
    path = tmp_path / "run.rrd"
    results = record(path, 2)
    units = {}
    for chunk in rc.RrdReader(str(path)).stream():
        batch = chunk.to_record_batch()
        for column in ("SeriesLines:names", "SeriesPoints:names"):
            if column in batch.schema.names:
                units[str(chunk.entity_path)] = batch[column].to_pylist()[0][0]
    e = entities("s")
    expected = {
        "force": "[N]",
        "transitions": "[N]",
        "indentation": "[m]",
        "y_c": "[m]",
        "y_ck": "[m]",
        "profile": "[m]",
        "dent": "[m]",
        "measured": "[N]",
        "fit": "[N]",
        "impacts": "[N]",
    }
    for role, unit in expected.items():
        assert units[e[role]].endswith(unit), (role, units[e[role]])
    cols = rrd_columns(path)
    np.testing.assert_allclose(
        of_passage(cols[e["indentation"]], 1)["values"], results[1].indentation
    )
    texts = [t for lines in rrd_texts(path).values() for _, t in lines]

    def views(x: object) -> list[rrb.TimeSeriesView]:
        if isinstance(x, rrb.TimeSeriesView):
            return [x]
        return [v for c in getattr(x, "contents", None) or [] for v in views(c)]

    names = [str(v.name) for v in views(default_blueprint("s").root_container)]
    assert len(names) == 5
    assert all("[N]" in n or "[m]" in n for n in names), names
    assert not any(u in t for t in texts + names + list(units.values()) for u in ("kN", "µm"))


def test_a_diagnosis_lies_at_its_passage_time_recorded_in_this_run_or_not(tmp_path: Path) -> None:
    """Beside its wheel when the passage was recorded in this run (its time from there);
    otherwise at the time the diagnosis echoes (``Diagnosis.timestamp``)."""
    from schemas.diagnosis import Diagnosis

    path = tmp_path / "run.rrd"
    rec = RerunRecording(path, "s")
    r = result("p0", timestamp=T0)
    rec.log_passage(r)
    x = np.linspace(0.0, 2.0, 11)
    t = x / 40.0
    for pid, stamp in (("p0", None), ("elsewhere", T0 + 50.0)):
        diag = Diagnosis(
            site_id="s",
            passage_id=pid,
            flat=None,
            verdict="ok",
            reasons=[],
            peak_force_measured=6e4,
            peak_force_fit=6e4,
            fit_rms=1.0,
            peak_force_at_line_speed=None,
            wall_time=0.0,
            timestamp=stamp,
        )
        rec.log_diagnosis(diag, t, np.full(11, 6e4), np.full(11, 6e4), x, np.empty(0))
    rec.close()
    measured = rrd_columns(path)[entities("s")["measured"]]
    for d, stamp, passage in ((0, T0, 0), (1, T0 + 50.0, -1)):
        rows = {k: v[measured["diagnosis"] == d] for k, v in measured.items()}
        np.testing.assert_allclose(rows["time"] / 1e9, stamp + t, rtol=0, atol=1e-6)
        assert set(rows["passage_time"]) == {round(stamp * 1e9)}
        assert set(rows["passage"]) == {passage}  # -1: not a passage of this run
        np.testing.assert_array_equal(rows["values"], np.full(11, 6e4))  # N
