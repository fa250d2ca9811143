"""``make bench``: every benchmark, a markdown table per section, ``benchmarks/results.json``.

    .venv/bin/python -m benchmarks.run_all [--quick] [--service-wheels N] [--skip SECTION ...]

Sections, each failing soft (the error is printed and the next one runs):

1. ``core``: ``benchmarks.core_bench`` (simulation core vs SciPy ``solve_ivp``);
2. ``constraint``: ``benchmarks.constraint_bench.run()`` if that module exists;
   ``track``: ``benchmarks.track_bench`` (the discrete site case against real time);
3. ``service``: ``benchmarks/service_bench.py`` in a child process (it starts the
   streaming service in a process of its own) under a timeout;
4. ``dask``: ``benchmarks.dask_bench`` (re-analysis on 1 and 2 Dask workers, per-task
   overhead; the 10 000-passage archive is ``make bench-reanalyse``).

Exit code 0 if every present section ran, 1 otherwise. The machine's load
average is recorded around each section: the numbers are wall times on a
shared machine.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import platform
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results.json"
SERVICE_SCRIPT = ROOT / "benchmarks" / "service_bench.py"
SERVICE_WHEELS = 200
SERVICE_TIMEOUT = 240.0


def _load() -> list[float]:
    try:
        return [round(v, 2) for v in os.getloadavg()]
    except OSError:
        return []


def _jsonable(obj: Any) -> Any:
    return json.loads(json.dumps(obj, default=lambda o: o.item() if hasattr(o, "item") else str(o)))


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def _records_table(rows: list[dict[str, Any]]) -> str:
    """A markdown table of a list of flat records (columns in first-seen order)."""
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols]
    out = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    out += ["| " + " | ".join(_cell(r.get(c, "")) for c in cols) + " |" for r in rows]
    return "\n".join(out)


def section_core(quick: bool) -> tuple[str, Any]:
    from benchmarks import core_bench

    res = core_bench.run(quick=quick, repeats=1 if quick else core_bench.REPEATS)
    return core_bench.markdown(res), res


def section_constraint(quick: bool) -> tuple[str, Any] | None:
    if importlib.util.find_spec("benchmarks.constraint_bench") is None:
        return None
    mod = importlib.import_module("benchmarks.constraint_bench")
    res = mod.run()
    if isinstance(res, str):
        return res, {"text": res}
    if isinstance(res, dict) and isinstance(res.get("markdown"), str):
        return res["markdown"], res
    if hasattr(mod, "markdown"):
        return str(mod.markdown(res)), res
    if isinstance(res, list) and res and all(isinstance(r, dict) for r in res):
        return _records_table(res), res
    return "```\n" + json.dumps(_jsonable(res), indent=1) + "\n```", res


def section_track(quick: bool) -> tuple[str, Any]:
    from benchmarks import track_bench

    res = track_bench.run(repeats=2 if quick else track_bench.REPEATS)
    return str(res["markdown"]), res


def section_service(quick: bool, wheels: int, timeout: float) -> tuple[str, Any]:
    cmd = [sys.executable, str(SERVICE_SCRIPT), "--wheels", str(8 if quick else wheels)]
    env = dict(os.environ)
    env.setdefault("RERUN_ANALYTICS", "0")
    try:
        p = subprocess.run(
            cmd, cwd=ROOT, capture_output=True, text=True, timeout=timeout, env=env, check=False
        )
    except subprocess.TimeoutExpired as e:
        raw = e.stdout or ""
        tail = (raw.decode(errors="replace") if isinstance(raw, bytes) else raw)[-2000:]
        raise RuntimeError(
            f"service benchmark timed out after {timeout:g} s; output: {tail}"
        ) from e
    out = p.stdout.strip()
    if p.returncode != 0:
        raise RuntimeError(
            f"service benchmark exited with {p.returncode}\n{out[-2000:]}\n{p.stderr.strip()[-3000:]}"
        )
    rows = [ln for ln in out.splitlines() if ln.startswith("|")]
    start = next(
        (i for i, ln in enumerate(out.splitlines()) if ln.startswith("railtwin service")), 0
    )
    text = "\n".join(out.splitlines()[start:])
    return text, {"command": cmd[1:], "stdout": out, "table_rows": rows}


def section_dask(quick: bool) -> tuple[str, Any]:
    from benchmarks import dask_bench

    res = dask_bench.run(quick=quick)
    return str(res["markdown"]), res


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="run every railtwin benchmark")
    ap.add_argument(
        "--quick", action="store_true", help="tiny cases (a smoke run, numbers meaningless)"
    )
    ap.add_argument("--service-wheels", type=int, default=SERVICE_WHEELS)
    ap.add_argument("--service-timeout", type=float, default=SERVICE_TIMEOUT)
    ap.add_argument(
        "--skip", nargs="*", default=[], choices=("core", "constraint", "track", "service", "dask")
    )
    ap.add_argument("--out", type=Path, default=RESULTS)
    a = ap.parse_args(argv)

    sections: list[tuple[str, str, Callable[[], tuple[str, Any] | None]]] = [
        ("core", "Simulation core vs SciPy solve_ivp", lambda: section_core(a.quick)),
        (
            "constraint",
            "Constraint tabulation (benchmarks.constraint_bench)",
            lambda: section_constraint(a.quick),
        ),
        (
            "track",
            "The site case on a discrete track (benchmarks.track_bench)",
            lambda: section_track(a.quick),
        ),
        (
            "service",
            "Streaming service (benchmarks/service_bench.py)",
            lambda: section_service(a.quick, a.service_wheels, a.service_timeout),
        ),
        (
            "dask",
            "Re-analysis on a Dask cluster (benchmarks.dask_bench)",
            lambda: section_dask(a.quick),
        ),
    ]
    t_all = time.perf_counter()
    report: dict[str, Any] = {
        "started": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "machine": {
            "cpus": os.cpu_count(),
            "platform": platform.platform(),
            "python": platform.python_version(),
            "load_average_at_start": _load(),
        },
        "sections": {},
    }
    failed: list[str] = []
    for key, title, fn in sections:
        print(f"\n## {title}\n", flush=True)
        if key in a.skip:
            print("(skipped)")
            report["sections"][key] = {"status": "skipped"}
            continue
        load0 = _load()
        t0 = time.perf_counter()
        entry: dict[str, Any] = {"load_average_before": load0}
        try:
            got = fn()
        except BaseException as e:  # fail soft: report and go on (Ctrl-C still stops the run)
            if isinstance(e, KeyboardInterrupt):
                raise
            traceback.print_exc()
            print(f"\n**{key}: FAILED** — {type(e).__name__}: {e}", flush=True)
            entry.update(status="failed", error=f"{type(e).__name__}: {e}")
            failed.append(key)
        else:
            if got is None:
                print("(not present: nothing to run)")
                entry["status"] = "absent"
            else:
                text, data = got
                print(text, flush=True)
                entry.update(status="ok", markdown=text, result=_jsonable(data))
        entry["seconds"] = round(time.perf_counter() - t0, 2)
        entry["load_average_after"] = _load()
        report["sections"][key] = entry
        print(
            f"\n({key}: {entry['seconds']:.1f} s wall; load average before/after "
            f"{load0} / {entry['load_average_after']} on {os.cpu_count()} CPUs)",
            flush=True,
        )
    report["total_seconds"] = round(time.perf_counter() - t_all, 2)
    report["failed"] = failed
    a.out.parent.mkdir(parents=True, exist_ok=True)
    a.out.write_text(json.dumps(report, indent=1) + "\n")
    print(
        f"\nbenchmarks: {report['total_seconds']:.0f} s in all; results in {a.out}"
        + (f"; FAILED: {', '.join(failed)}" if failed else "")
    )
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
