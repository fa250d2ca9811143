"""Compile time of the physics, per compiled function, on a cold and then a warm numba cache.

    .venv/bin/python -m benchmarks.compile_times [--cache-dir DIR] [--top N] [--json FILE]

Runs the service's warm-up (``SitePhysics.warm_up`` and ``Diagnoser.warm_up`` on
``examples/site_compliant.toml``: every tabulation path, a passage, the dent press, a diagnosis)
twice, each in a fresh child process with ``NUMBA_CACHE_DIR`` pointed at one
directory (a new temporary one unless ``--cache-dir`` is given):

1. cold: nothing cached; every compiled function numba compiles is timed through
   numba's event API (``numba:compile``, one event per dispatcher and signature,
   nested when typing a caller compiles its callees). *Inclusive* is the whole event,
   *self* the event less the compiles nested in it: a function's own typing, lowering
   and LLVM optimisation, into which its ``inline="always"`` callees and the linked
   callees' IR are folded (wall and CPU seconds);
2. warm: the same warm-up loading from the cache; any compile event there is a
   function whose cache is missed (listed: it is compiled again in every process).

The table is printed largest self time first. On a shared machine compare the CPU
column; wall times only between runs made under the same load (the load average is
printed).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SITE = ROOT / "examples" / "site_compliant.toml"


@dataclass
class Compiled:
    """One compiled (function, signature): where it is and what its compile cost (s)."""

    function: str
    signature: str
    inclusive: float
    self_time: float
    self_cpu: float
    depth: int


def _child(site_file: Path) -> dict[str, Any]:
    """Import and warm the physics in this process; the compile events and phase times."""
    t_start = time.perf_counter()
    from numba.core import event as ev

    compiled: list[Compiled] = []
    stack: list[list[float]] = []  # [start, nested wall, start CPU, nested CPU]

    class Recorder(ev.Listener):
        def on_start(self, event: Any) -> None:
            stack.append([time.perf_counter(), 0.0, time.process_time(), 0.0])

        def on_end(self, event: Any) -> None:
            start, nested, start_cpu, nested_cpu = stack.pop()
            dur = time.perf_counter() - start
            cpu = time.process_time() - start_cpu
            if stack:
                stack[-1][1] += dur
                stack[-1][3] += cpu
            disp = event.data["dispatcher"]
            fn = disp.py_func
            args = ", ".join(str(a) for a in event.data["args"])
            compiled.append(
                Compiled(
                    f"{fn.__module__}.{fn.__qualname__}",
                    f"({args})",
                    dur,
                    dur - nested,
                    cpu - nested_cpu,
                    len(stack),
                )
            )

    ev.register("numba:compile", Recorder())
    phases: dict[str, float] = {}
    t0 = time.perf_counter()
    from service.physics.diagnosis import Diagnoser
    from service.physics.site_physics import SitePhysics
    from service.wire.site import load_site

    phases["import"] = time.perf_counter() - t0
    site = load_site(site_file)
    t0 = time.perf_counter()
    physics = SitePhysics(site)
    phases["site physics (rail, tables)"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    physics.warm_up()
    phases["physics warm-up"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    Diagnoser(site, physics=physics).warm_up()
    phases["diagnoser warm-up"] = time.perf_counter() - t0
    phases["total"] = time.perf_counter() - t_start
    return {"phases": phases, "compiled": [asdict(c) for c in compiled]}


def _run_child(cache_dir: Path, site_file: Path) -> dict[str, Any]:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        cmd = [
            sys.executable,
            "-m",
            "benchmarks.compile_times",
            "--child",
            out.name,
            "--site",
            str(site_file),
        ]
        t0 = time.perf_counter()
        subprocess.run(cmd, cwd=ROOT, env=env, check=True)
        wall = time.perf_counter() - t0
        data: dict[str, Any] = json.loads(Path(out.name).read_text())
    data["process_wall"] = wall
    return data


def _table(compiled: list[dict[str, Any]], top: int) -> str:
    """Per function (all its signatures together): compiles, self and inclusive seconds."""
    per: dict[str, dict[str, Any]] = {}
    for c in compiled:
        row = per.setdefault(
            c["function"], {"n": 0, "self": 0.0, "cpu": 0.0, "incl": 0.0, "sigs": set()}
        )
        row["n"] += 1
        row["self"] += c["self_time"]
        row["cpu"] += c.get("self_cpu", float("nan"))
        row["incl"] = max(row["incl"], c["inclusive"])
        row["sigs"].add(c["signature"])
    rows = sorted(per.items(), key=lambda kv: -kv[1]["self"])
    lines = [
        "| function | signatures | self s | self CPU s | inclusive s (largest) |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, r in rows[:top]:
        short = name.removeprefix("sim_core.")
        lines.append(
            f"| {short} | {len(r['sigs'])} | {r['self']:.2f} | {r['cpu']:.2f} | {r['incl']:.2f} |"
        )
    rest = rows[top:]
    if rest:
        lines.append(
            f"| ({len(rest)} more) | {sum(len(r['sigs']) for _, r in rest)} | "
            f"{sum(r['self'] for _, r in rest):.2f} | "
            f"{sum(r['cpu'] for _, r in rest):.2f} | |"
        )
    total_self = sum(c["self_time"] for c in compiled)
    total_cpu = sum(c.get("self_cpu", float("nan")) for c in compiled)
    lines.append(
        f"| **all {len(per)} functions** | {len(compiled)} | {total_self:.2f} | {total_cpu:.2f} | |"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="compile_times", description=__doc__.split("\n")[0])
    p.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        help="numba cache directory (default: a new temporary one, removed after)",
    )
    p.add_argument("--site", type=Path, default=SITE)
    p.add_argument("--top", type=int, default=40, help="rows of the table (default 40)")
    p.add_argument("--json", type=Path, default=None, help="also write the raw events here")
    p.add_argument("--child", type=Path, default=None, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child is not None:
        args.child.write_text(json.dumps(_child(args.site)))
        return 0
    with tempfile.TemporaryDirectory(prefix="railtwin-numba-cold-") as tmp:
        cache = args.cache_dir if args.cache_dir is not None else Path(tmp)
        load0 = os.getloadavg()
        cold = _run_child(cache, args.site)
        warm = _run_child(cache, args.site)
        load1 = os.getloadavg()
    print(
        f"# numba compile times, warm-up of {args.site.name} "
        f"(load average {load0[0]:.2f} before, {load1[0]:.2f} after; {os.cpu_count()} CPUs)\n"
    )
    print(_table(cold["compiled"], args.top))
    for name, run in (("cold", cold), ("warm", warm)):
        ph = ", ".join(f"{k} {v:.1f} s" for k, v in run["phases"].items())
        print(f"\n{name} cache: process {run['process_wall']:.1f} s ({ph})")
    missed = sorted({c["function"] for c in warm["compiled"]})
    print(
        f"warm cache: {len(warm['compiled'])} compiles (cache misses)"
        + (": " + ", ".join(missed) if missed else "")
    )
    if args.json is not None:
        args.json.write_text(json.dumps({"cold": cold, "warm": warm}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
