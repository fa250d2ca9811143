"""Dask scaling of the re-analysis: throughput on 1 and 2 workers, Dask's own cost per
task, and (``--archive N``) a whole generated archive re-analysed, with its wall time.

    .venv/bin/python -m benchmarks.dask_bench [--passages 400] [--archive 10000] [--quick]

The archive is written by the twin's MCAP writer on ``examples/site_compliant.toml``
(``service.distributed.archive_gen``: a pool of 16 measured wheels, every 8th with a
fresh flat, reused under new passage ids) and re-analysed into a scratch directory, each
run from nothing. Per-task overhead: 200 tasks that do nothing, on 2 workers. The numbers
are wall times on a shared machine: the load average is printed with them.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "examples" / "site_compliant.toml"


def _load() -> list[float]:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return []


def _reanalyse(workers: int, logs: Path, site: Any, batch: int | None = None) -> dict[str, Any]:
    from service.distributed.archive import read_archive
    from service.distributed.cluster import open_client
    from service.distributed.reanalysis import DirSink, reanalyse
    from service.distributed.tasks import WarmUp
    from service.physics.model_version import model_version

    t0 = time.perf_counter()
    archive = read_archive([logs], site.site_id, site.diagnosis.pairing_timeout)
    read_s = time.perf_counter() - t0
    version = model_version(site)
    with tempfile.TemporaryDirectory() as out:
        t1 = time.perf_counter()
        with open_client(workers=workers, warm=WarmUp(site.model_dump_json())) as (client, info):
            up = time.perf_counter() - t1
            sink = DirSink(Path(out), site.site_id, version.key)
            r = reanalyse(
                client, info, archive, site, version, sink, batch=batch, stream=sys.stderr
            )
    n = r.diagnosed + r.failed
    return {
        "workers": workers,
        "passages": n,
        "read_s": round(read_s, 2),
        "cluster_up_s": round(up, 2),
        "wall_s": round(r.wall_time, 2),
        "passages_per_s": round(n / r.wall_time, 1),
        "compute_s_per_passage_ms": round(1e3 * r.compute_time / max(n, 1), 2),
        "tasks": r.tasks,
        "batch": r.batch,
        "overhead_per_task_ms": round(1e3 * r.overhead_per_task, 1),
        "load": _load(),
    }


def _noop_overhead(tasks: int = 200) -> dict[str, Any]:
    from service.distributed.cluster import open_client, run_batches
    from service.distributed.tasks import noop_batch

    with open_client(workers=2) as (client, _):
        list(run_batches(client, noop_batch, [[i] for i in range(20)], in_flight=6))  # warm
        t0 = time.perf_counter()
        list(run_batches(client, noop_batch, [[i] for i in range(tasks)], in_flight=6))
        wall = time.perf_counter() - t0
    return {"tasks": tasks, "wall_s": round(wall, 3), "per_task_ms": round(1e3 * wall / tasks, 2)}


def run(passages: int = 400, archive: int = 0, quick: bool = False) -> dict[str, Any]:
    from service.distributed.archive_gen import templates, write_archive
    from service.wire.site import load_site

    site = load_site(SITE)
    if quick:
        passages, archive = 24, 0
    t0 = time.perf_counter()
    pool = templates(site, 16, flat_every=8)
    res: dict[str, Any] = {"pool_s": round(time.perf_counter() - t0, 2)}
    with tempfile.TemporaryDirectory() as d:
        logs = Path(d) / "small"
        write_archive(site, logs, passages, pool)
        res["scaling"] = [_reanalyse(1, logs, site), _reanalyse(2, logs, site)]
        one, two = res["scaling"]
        res["speed_up_2_workers"] = round(two["passages_per_s"] / one["passages_per_s"], 2)
        res["noop"] = _noop_overhead(40 if quick else 200)
        if archive:
            big = Path(d) / "big"
            t1 = time.perf_counter()
            files = write_archive(site, big, archive, pool, max_mb=64)
            res["archive"] = {
                "write_s": round(time.perf_counter() - t1, 1),
                "files": len(files),
                "mb": round(sum(f.stat().st_size for f in files) / 2**20, 1),
                **_reanalyse(2, big, site),
            }
    res["markdown"] = markdown(res)
    return res


def markdown(res: dict[str, Any]) -> str:
    rows = [
        "| run | passages | wall s | passages/s | diagnosis ms/passage | tasks x batch | "
        "overhead ms/task | load |",
        "|---|---|---|---|---|---|---|---|",
    ]
    runs = [(f"{r['workers']} worker(s)", r) for r in res["scaling"]]
    if "archive" in res:
        runs.append(("archive, 2 workers", res["archive"]))
    for name, r in runs:
        rows.append(
            f"| {name} | {r['passages']} | {r['wall_s']} | {r['passages_per_s']} | "
            f"{r['compute_s_per_passage_ms']} | {r['tasks']} x {r['batch']} | "
            f"{r['overhead_per_task_ms']} | {r['load']} |"
        )
    rows.append("")
    rows.append(
        f"speed-up on 2 workers: {res['speed_up_2_workers']}x; an empty task costs "
        f"{res['noop']['per_task_ms']} ms ({res['noop']['tasks']} tasks on 2 workers)"
    )
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0] if __doc__ else None)
    ap.add_argument("--passages", type=int, default=400)
    ap.add_argument("--archive", type=int, default=0, help="also re-analyse N passages")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    res = run(a.passages, a.archive, a.quick)
    print(res["markdown"])
    print(json.dumps({k: v for k, v in res.items() if k != "markdown"}), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
