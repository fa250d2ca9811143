"""Benchmark tabulate_constraint: the piece sweep (auto) against the general ψ-search.

    .venv/bin/python benchmarks/constraint_bench.py

Prints one row per case: best-of-N time per table (auto), node and kink counts, and the
general ψ-search's time on the same case and the ratio (same run). Asserts nothing.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

import numpy as np

from sim_core.constraint import tabulate_constraint
from sim_core.constraint_table import ConstraintTable
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from sim_core.wheel_roughness import bundled_measurement, load_wheel_roughness


def _best(fn: Callable[[], ConstraintTable], repeat: int) -> tuple[float, ConstraintTable]:
    t = fn()  # compile / warm
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        t = fn()
        best = min(best, time.perf_counter() - t0)
    return best, t


def run(repeat: int = 5, general: bool = True) -> list[dict[str, float | str]]:
    """Rows: case, auto_ms, nodes, kinks, general_ms, ratio (general/auto; 0 if not measured)."""
    w = load_wheel_roughness(bundled_measurement("flat_0p3_01.dat")).to_outline()
    rng = np.random.default_rng(11)
    x = np.arange(0.0, 10.0, 1e-4)
    y = np.cumsum(rng.normal(0.0, 1e-6, x.size))
    long_rail = RailProfile.sampled(x, y - y.mean())
    cases: list[tuple[str, WheelOutline, RailProfile, float, bool]] = [
        ("measured wheel, 6 m, flat rail", w, RailProfile.flat(), 6.0, general),
        (
            "measured wheel, 6 m, cosine 2 um / 6 cm",
            w,
            RailProfile.cosine(2e-6, 0.06),
            6.0,
            general,
        ),
        (
            "ideal flat 60 mm, 6 m, flat rail",
            WheelOutline.ideal_flat(0.475, 0.06),
            RailProfile.flat(),
            6.0,
            general,
        ),
        (
            "round wheel, 10 m sampled rail at 0.1 mm",
            WheelOutline.round(0.475),
            long_rail,
            10.0,
            False,
        ),
    ]
    rows: list[dict[str, float | str]] = []
    for name, wheel, rail, length, with_general in cases:
        ta, tab = _best(partial(tabulate_constraint, wheel, rail, 0.0, length), repeat)
        tg = 0.0
        if with_general:
            tg, _ = _best(
                partial(tabulate_constraint, wheel, rail, 0.0, length, method="general"), 1
            )
        rows.append(
            {
                "case": name,
                "auto_ms": ta * 1e3,
                "nodes": float(tab.x.size),
                "kinks": float(tab.kinks.size),
                "general_ms": tg * 1e3,
                "speedup": tg / ta if tg > 0 else 0.0,
            }
        )
    return rows


if __name__ == "__main__":
    print(
        f"{'case':44s} {'auto ms':>9s} {'nodes':>7s} {'kinks':>6s} {'general ms':>11s} {'speedup':>8s}"
    )
    for r in run():
        print(
            f"{r['case']!s:44s} {float(r['auto_ms']):9.2f} {int(r['nodes']):7d} {int(r['kinks']):6d} "
            f"{float(r['general_ms']):11.1f} {float(r['speedup']):8.0f}"
        )
