"""``railtwin diagnose`` as a user runs it, timed on every passage of the wide set.

Issue 14's "done when": the command answers within 1 s on any ``Wxx``. Each passage is
diagnosed by the installed ``railtwin`` script in a fresh process (imports, the numba
cache's loading, the fit, the line-speed band, the output), as a person or a script would
call it; the wall time includes all of it. Beside it, in the same run, the same script's
``diagnose --help`` (the interpreter, the CLI and the schemas, nothing of the physics), so
that a slower machine can be read off as a ratio.

    python -m validation.cli_timing [--only W06,W39] [--repeat 1]
"""

from __future__ import annotations

import argparse
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from validation.wide_set import WIDE_DIR, case_ids, load_case

LIMIT = 1.0
"""s: the issue's target for one passage."""


def _script() -> list[str]:
    """The ``railtwin`` console script beside this interpreter (else ``python -m``)."""
    exe = Path(sys.executable).parent / "railtwin"
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "service.cli"]


def _timed(cmd: list[str]) -> tuple[float, float]:
    """(wall s, CPU s of the child) of one command, which must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr[-500:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def time_all(ids: list[str], repeat: int = 1) -> list[dict[str, float | str]]:
    """One row per passage: the best of ``repeat`` runs' wall and CPU time."""
    rows: list[dict[str, float | str]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for cid in ids:
            case = load_case(cid)
            passage = Path(tmp) / f"{cid}.passage.json"
            passage.write_text(case.passage.model_dump_json(), encoding="utf-8")
            cmd = [
                *_script(),
                "diagnose",
                "--site",
                str(WIDE_DIR / f"{cid}.site.toml"),
                "--passage",
                str(passage),
                "--measured",
                str(WIDE_DIR / f"{cid}.csv"),
            ]
            runs = [_timed(cmd) for _ in range(repeat)]
            wall, cpu = min(runs)
            kind = case.truth["kind"] or "round"
            rows.append({"case": cid, "kind": kind, "wall": wall, "cpu": cpu})
            print(f"{cid} {kind:12s} {wall:5.2f} s wall {cpu:5.2f} s CPU", file=sys.stderr)
    return rows


def summary(rows: list[dict[str, float | str]], peer: float) -> str:
    walls = [float(r["wall"]) for r in rows]
    flats = [float(r["wall"]) for r in rows if r["kind"] != "round"]
    rounds = [float(r["wall"]) for r in rows if r["kind"] == "round"]
    worst = max(rows, key=lambda r: float(r["wall"]))
    lines = [
        f"- `railtwin diagnose` on {len(rows)} wide-set passages: within {LIMIT:g} s "
        f"{sum(w <= LIMIT for w in walls)}/{len(walls)}; worst {float(worst['wall']):.2f} s "
        f"({worst['case']})",
    ]
    if flats:
        lines.append(
            f"- flat wheels: median {statistics.median(flats):.2f} s, "
            f"{min(flats):.2f}-{max(flats):.2f} s"
        )
    if rounds:
        lines.append(
            f"- round wheels: median {statistics.median(rounds):.2f} s, "
            f"{min(rounds):.2f}-{max(rounds):.2f} s"
        )
    lines.append(
        f"- peer in the same run, `railtwin diagnose --help`: {peer:.2f} s (worst passage "
        f"{float(worst['wall']) / peer:.1f}x it)"
    )
    return "\n".join(lines)


def peer_time() -> float:
    return min(_timed([*_script(), "diagnose", "--help"])[0] for _ in range(3))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m validation.cli_timing", description=__doc__.split("\n")[0]
    )
    p.add_argument("--only", default=None, help="comma-separated case ids")
    p.add_argument("--repeat", type=int, default=1, help="runs per passage (the best kept)")
    a = p.parse_args(argv)
    if a.repeat < 1:
        p.error("--repeat must be at least 1")
    ids = a.only.split(",") if a.only else case_ids()
    rows = time_all(ids, a.repeat)
    print(summary(rows, peer_time()))
    return 0 if all(float(r["wall"]) <= LIMIT for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
