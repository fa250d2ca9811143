"""The site case on a discrete track (issue: real time): one wheel through the scenario runner.

50 mm ideal flat, 160 km/h, 6 m of 0.5 mm-sampled rough rail, ballasted discrete track, 8
cribs, output at 10 kHz: the work of ``railtwin simulate`` on it in batch mode, as the first
wheel on its rail (the constraint table made; the track reduced cold, or read from the
disk cache as a repeated run or a restarted site reads it), and with the reduction in
memory (a running twin reduces its track once, at warm-up; a batch after its first scenario
keeps it). The peer in the same run is the same wheel on the paper's compliant foundation
(one mass on one spring), through the same path; real time is the passage's own duration
(0.135 s). The three are timed in turn, ``REPEATS`` rounds, so that the shared host's phases
fall on all of them; the best and the median of each are reported.

    .venv/bin/python -m benchmarks.track_bench
"""

from __future__ import annotations

import json
import os
import statistics
import time
from typing import Any

import numpy as np

from benchmarks.constraint_bench import site_rail

SPEED = 160 / 3.6
LENGTH = 6.0
REPEATS = 10


def site_scenario(foundation: dict[str, Any], cribs: bool) -> dict[str, Any]:
    rail = site_rail()
    sc: dict[str, Any] = {
        "wheel": {
            "mass": 700.0,
            "load": 85000.0,
            "radius": 0.46,
            "outline": {"kind": "flat", "length": 0.05},
            "phase": 1.0,
        },
        "rail": {
            "kind": "sampled",
            "x": np.asarray(rail.x).tolist(),
            "y": np.asarray(rail.y).tolist(),
        },
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
        "contact": "hertz",
        "foundation": foundation,
        "speed": SPEED,
        "duration": LENGTH / SPEED,
        "sample_rate": 10000.0,
    }
    if cribs:
        sc["detector"] = {
            "cribs": [
                {"id": f"ch{i + 1}", "x_a": 1.0 + 0.6 * i, "x_b": 1.4 + 0.6 * i} for i in range(8)
            ]
        }
    return sc


DISCRETE = {
    "kind": "discrete",
    "sleeper_spacing": 0.6,
    "first_sleeper": 0.3,
    "pad": {"stiffness": 2.0e8, "damping": 3.0e4},
    "sleeper_mass": 150.0,
    "ballast": {"stiffness": 1.2e8, "damping": 8.0e4},
}
COMPLIANT = {"kind": "compliant", "mass": 150.0, "stiffness": 2.0e8, "damping": 7.0e4}


def _one(scenario: dict[str, Any], fresh_track: bool) -> tuple[float, Any]:
    """One ``run_scenario`` of ``scenario`` (a new rail: its first wheel), timed; with
    ``fresh_track`` the reduction is not kept in memory (read from the disk cache or made)."""
    from schemas.scenario import Scenario
    from service.physics.scenario_runner import run_scenario
    from sim_core.track.modal import _reduce

    if fresh_track:
        _reduce.cache_clear()
    sc = Scenario.model_validate(scenario)
    t0 = time.perf_counter()
    res = run_scenario(sc)
    return time.perf_counter() - t0, res


def run(repeats: int = REPEATS) -> dict[str, Any]:
    """The cold reduction once; then the disk-cache, in-memory and peer cases in turn,
    ``repeats`` rounds of the three, so that the host's slow and fast phases (its speed moves
    by up to 1.6x within minutes) fall on all three alike; best and median of each."""
    duration = LENGTH / SPEED
    cases = (
        ("discrete, 8 cribs, first wheel, reduction from the disk cache", DISCRETE, True, True),
        ("discrete, 8 cribs, track in memory (a running twin)", DISCRETE, True, False),
        ("compliant (peer), no cribs", COMPLIANT, False, False),
    )
    old = os.environ.get("RAILTWIN_TRACK_CACHE")
    os.environ["RAILTWIN_TRACK_CACHE"] = "off"
    try:
        _one(site_scenario(DISCRETE, True), True)  # compiled and warm
        cold, res = _one(site_scenario(DISCRETE, True), True)
    finally:
        if old is None:
            os.environ.pop("RAILTWIN_TRACK_CACHE", None)
        else:
            os.environ["RAILTWIN_TRACK_CACHE"] = old
    results: dict[str, Any] = {
        "discrete, 8 cribs, first wheel, track reduced cold (no disk cache)": res
    }
    walls: dict[str, list[float]] = {
        "discrete, 8 cribs, first wheel, track reduced cold (no disk cache)": [cold]
    }
    scenarios = {name: site_scenario(found, cribs) for name, found, cribs, _ in cases}
    for name, _, _, fresh in cases:  # fill the disk cache, warm each path
        _one(scenarios[name], fresh)
        walls[name] = []
    for _ in range(repeats):
        for name, _, _, fresh in cases:
            wall, results[name] = _one(scenarios[name], fresh)
            walls[name].append(wall)
    rows = []
    for name, ts in walls.items():
        res = results[name]
        rows.append(
            {
                "case": name,
                "wall_ms": round(1e3 * min(ts), 1),
                "median_ms": round(1e3 * statistics.median(ts), 1),
                "runs": len(ts),
                "x_real_time": round(duration / min(ts), 2),
                "peak_kN": round(res.summary.peak_force / 1e3, 1),
                "losses": res.summary.contact_losses,
            }
        )
    peer = rows[-1]
    for r in rows:
        r["ratio_to_peer"] = round(r["wall_ms"] / peer["wall_ms"], 2)
        r["median_ratio_to_peer"] = round(r["median_ms"] / peer["median_ms"], 2)
    text = [
        "| case | runs | wall, best (ms) | median (ms) | × real time (best) | / compliant peer (best; median) | peak (kN) | losses |",
        "|---|---|---|---|---|---|---|---|",
    ]
    text += [
        f"| {r['case']} | {r['runs']} | {r['wall_ms']} | {r['median_ms']} | {r['x_real_time']} | "
        f"{r['ratio_to_peer']}; {r['median_ratio_to_peer']} | {r['peak_kN']} | {r['losses']} |"
        for r in rows
    ]
    return {"rows": rows, "markdown": "\n".join(text)}


if __name__ == "__main__":
    out = run()
    print(out["markdown"])
    print(json.dumps(out["rows"]))
