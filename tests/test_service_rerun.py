"""The Rerun recording: read back with RrdReader, entities, values and the blueprint."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import rerun.chunk as rc

from schemas.messages import PassageResult, RailState
from schemas.result import Summary, Transition
from service.rerun_recording import RerunRecording


def rrd_columns(path: Path) -> dict[str, dict[str, np.ndarray]]:
    """{entity: {column: values}} of the non-static scalar and index columns of a .rrd."""
    out: dict[str, dict[str, np.ndarray]] = {}
    for chunk in rc.RrdReader(str(path)).stream():
        batch: pa.RecordBatch = chunk.to_record_batch()
        if "Scalars:scalars" not in batch.schema.names:
            continue
        cols = out.setdefault(str(chunk.entity_path), {})
        for name in ("x_mm", "passage"):
            if name in batch.schema.names:
                new = np.asarray(batch[name].cast(pa.int64()))
                cols[name] = np.concatenate([cols.get(name, np.empty(0, np.int64)), new])
        values = np.asarray(batch["Scalars:scalars"].flatten())
        cols["values"] = np.concatenate([cols.get("values", np.empty(0)), values])
    return out


def result(pid: str, n: int = 50) -> PassageResult:
    x = np.linspace(0.0, 2.0, n)
    force = 50e3 + 1e3 * np.sin(x)
    return PassageResult(
        site_id="s", passage_id=pid, train_id="t", axle_index=0, side="right", timestamp=0.0,
        speed=40.0, sample_rate=1000.0, t_start=0.0, site_length=2.0, x=x.tolist(),
        force=force.tolist(), indentation=(force * 1e-9).tolist(), y_c=[0.0] * n,
        y_ck=(x * 1e-6).tolist(),
        transitions=[Transition(t=0.01, kind="loss", x=0.4), Transition(t=0.02, kind="contact",
                                                                        x=0.8)],
        summary=Summary(peak_force=float(force.max()), min_force=0.0, contact_losses=1,
                        first_loss_time=0.01, time_out_of_contact=0.01,
                        max_indentation=6e-5, max_dent=0.0),
        rail_revision=0, wall_time=0.001, steps=10,
    )


def test_recording_reads_back(tmp_path: Path) -> None:
    path = tmp_path / "run.rrd"
    rec = RerunRecording(path, "s")
    rec.log_rail(np.linspace(0.0, 2.0, 21), np.zeros(21))
    a, b = result("p0"), result("p1")
    rec.log_passage(a)
    rec.log_passage(b)
    rec.log_dent("p1", RailState(site_id="s", revision=1, passages_done=2, x=[0.0, 1.0, 2.0],
                                 y=[0.0, -1e-6, 0.0], dent=[0.0, 1e-6, 0.0], max_dent=1e-6))
    rec.close()

    reader = rc.RrdReader(str(path))
    assert len(reader.blueprints()) == 1
    cols = rrd_columns(path)
    for pid in ("p0", "p1"):
        for entity in (f"/force/{pid}", f"/indentation/{pid}", f"/motion/y_c/{pid}",
                       f"/motion/y_ck/{pid}", f"/force/{pid}/transitions"):
            assert entity in cols, entity
    assert "/rail/profile" in cols and "/rail/dent/p1" in cols
    f0 = cols["/force/p0"]
    np.testing.assert_array_equal(f0["values"], np.asarray(a.force) * 1e-3)
    np.testing.assert_array_equal(f0["x_mm"], np.rint(np.asarray(a.x) * 1000).astype(np.int64))
    assert set(cols["/force/p1"]["passage"]) == {1}
    np.testing.assert_array_equal(cols["/force/p0/transitions"]["x_mm"], [400, 800])
    np.testing.assert_allclose(cols["/rail/dent/p1"]["values"], [0.0, 1.0, 0.0])
