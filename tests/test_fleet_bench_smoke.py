"""Smoke test of ``make fleet-bench``: a tiny run stores every diagnosis published through
the router and answers every history query (no timing asserted)."""

from __future__ import annotations

import json
from pathlib import Path

from benchmarks import fleet_bench


def test_tiny_fleet_bench_runs_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "r.json"
    assert (
        fleet_bench.main(
            [
                "--sites",
                "4",
                "--diagnoses",
                "40",
                "--rows",
                "400",
                "--wheels",
                "20",
                "--skip-postgres",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    r = json.loads(out.read_text())
    ing, q = r["ingest"][0], r["query"][0]
    assert (ing["db"], ing["diagnoses"], ing["stored"]) == ("sqlite", 40, 40)
    assert ing["fleet_rss_mb"] > 0
    assert (q["rows"], q["per_wheel"]) == (400, 20)
    assert 0 < q["history_p50_ms"] <= q["history_p99_ms"]
    assert 0 < q["zenoh_p50_ms"] <= q["zenoh_p99_ms"]
