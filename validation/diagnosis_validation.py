"""Validation of the wheel-flat diagnosis (``make validate``) on two sources:

(a) the independent wide set (``validation/measured-wide``: 40 passages from another
    solver, README there), through the same path as ``railtwin diagnose``;
(b) the project's own generator with fresh seeds over the same space
    (``validation.own_generator``).

    .venv/bin/python -m validation.diagnosis_validation [--own 40]
        [--seeds 20261201,777] [--no-cli] [--out validation/diagnosis_results.json]

Prints, per source, the table per kind × speed band × damping band (length error
median/worst, within max(5 mm, 10 %), kind, length-interval coverage, line-speed forecast
within ±20 % and its interval's coverage, wall time), then false alarms, missed
``remove``, unexplained fits and timings; what bounds the forecast (the true flat rolled by
the twin, ``validation.forecast_bound``) and each length or kind miss (the truth's cost on
the fit's windows, ``validation.fit_bound``); the own generator's line-speed truth, where
the forecast missed it, re-integrated by the test suite's slow reference solver
(``validation.line_truth_reference``); then ``railtwin diagnose`` as a command, timed on
every wide-set passage (``validation.cli_timing``). Writes every case to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

SPEED_BANDS = ((20.0, 70.0), (70.0, 115.0), (115.0, 161.0))
DAMPING_BANDS = ((0.0, 0.08), (0.08, 1.0))
"""Damping ratio: below 0.08 a wheel still rings from the last impact (docs/diagnosis.md)."""


def within(r: dict[str, Any]) -> bool:
    tl = float(r["true_length"])
    return abs(float(r["found_length"]) - tl) <= max(0.005, 0.1 * tl)


def covered(r: dict[str, Any]) -> bool:
    lo, hi = r["length_low"], r["length_high"]
    return lo is not None and float(lo) <= float(r["true_length"]) <= float(hi)


def line_ok(r: dict[str, Any]) -> bool | None:
    if r["line_truth"] is None or r["line_point"] is None:
        return None
    return abs(float(r["line_point"]) / float(r["line_truth"]) - 1.0) <= 0.2


def line_covered(r: dict[str, Any]) -> bool | None:
    if r["line_truth"] is None or r["line_low"] is None:
        return None
    return float(r["line_low"]) <= float(r["line_truth"]) <= float(r["line_high"])


def _frac(xs: list[bool | None]) -> str:
    v = [x for x in xs if x is not None]
    return f"{sum(v)}/{len(v)}" if v else "-"


def table(rows: list[dict[str, Any]]) -> str:
    out = [
        "| kind | speed km/h | damping ratio | cases | length error median / worst (mm) "
        "| within max(5 mm, 10 %) | kind right | interval covers | forecast ±20 % "
        "| forecast interval covers | wall s median / worst |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for kind in ("flat", "rounded_flat"):
        for s0, s1 in SPEED_BANDS:
            for z0, z1 in DAMPING_BANDS:
                sel = [
                    r
                    for r in rows
                    if r["kind"] == kind
                    and s0 <= r["speed_kmh"] < s1
                    and z0 <= r["true_damping_ratio"] < z1
                ]
                if not sel:
                    continue
                err = np.array([abs(r["found_length"] - r["true_length"]) for r in sel]) * 1e3
                wall = np.array([r["wall_time"] for r in sel])
                out.append(
                    f"| {kind} | {s0:.0f}-{min(s1, 160):.0f} | {z0:.2f}-{min(z1, 0.4):.2f} "
                    f"| {len(sel)} | {np.median(err):.1f} / {err.max():.1f} "
                    f"| {_frac([within(r) for r in sel])} "
                    f"| {_frac([r['found_kind'] == kind for r in sel])} "
                    f"| {_frac([covered(r) for r in sel])} "
                    f"| {_frac([line_ok(r) for r in sel])} "
                    f"| {_frac([line_covered(r) for r in sel])} "
                    f"| {np.median(wall):.2f} / {wall.max():.2f} |"
                )
    flats = [r for r in rows if r["kind"] != "round"]
    rounds = [r for r in rows if r["kind"] == "round"]
    fa = [r["case"] for r in rounds if r["found_kind"] is not None]
    due = [r for r in flats if r["true_length"] >= 0.06 or r["true_peak"] >= 400e3]
    missed = [r["case"] for r in due if r["verdict"] != "remove"]
    widths = [
        float(r["length_high"]) - float(r["length_low"])
        for r in flats
        if r["length_low"] is not None
    ]
    line_err = [
        abs(r["line_point"] / r["line_truth"] - 1)
        for r in flats
        if r["line_truth"] and r["line_point"]
    ]
    too_low = [
        r["case"]
        for r in flats
        if r["line_truth"] and r["line_high"] is not None and r["line_high"] < 0.8 * r["line_truth"]
    ]
    unexpl = [r for r in rows if r["explained"] is False]
    wrong_expl = [r["case"] for r in flats if r["explained"] and not within(r)]
    cpu = np.array([r["cpu_time"] for r in rows])
    wall_f = np.array([r["wall_time"] for r in flats])
    wall_r = np.array([r["wall_time"] for r in rounds]) if rounds else np.zeros(1)
    out += [
        "",
        f"- flats: {len(flats)}; within tolerance {sum(within(r) for r in flats)}, kind right "
        f"{sum(r['found_kind'] == r['kind'] for r in flats)}, interval covers "
        f"{sum(covered(r) for r in flats)} (median width {np.median(widths) * 1e3:.1f} mm)",
        f"- misses (length): {', '.join(r['case'] for r in flats if not within(r)) or 'none'}",
        f"- round wheels: {len(rounds)}; reported a flat: {len(fa)} {fa if fa else ''}",
        f"- `remove` due (true flat >= 60 mm or true peak >= 400 kN): {len(due)}; missed: "
        f"{len(missed)} {missed if missed else ''}",
        f"- line-speed forecast: within ±20 % {_frac([line_ok(r) for r in flats])}, median error "
        f"{np.median(line_err) * 100:.0f} %; interval covers {_frac([line_covered(r) for r in flats])}; "
        f"upper end below 0.8 × truth (dangerous): {too_low or 'none'}",
        f"- not explained: {len(unexpl)} ({', '.join(r['case'] for r in unexpl)}); explained but "
        f"length out of tolerance: {wrong_expl or 'none'}",
        f"- time per wheel (diagnose: fit + re-simulations + forecast band): flat wall median "
        f"{np.median(wall_f):.2f} s, worst {wall_f.max():.2f} s; round wall median "
        f"{np.median(wall_r) * 1e3:.0f} ms, worst {wall_r.max() * 1e3:.0f} ms; CPU median "
        f"{np.median(cpu):.2f} s, worst {cpu.max():.2f} s (one core, in this process)",
    ]
    return "\n".join(out)


def bounds(rows: list[dict[str, Any]]) -> str:
    """What bounds the source's forecast misses (``validation.forecast_bound``) and its
    length and kind misses (``validation.fit_bound``), from the rows' truth fields."""
    from validation import fit_bound, forecast_bound

    forecast_misses = [str(r["case"]) for r in rows if line_ok(r) is False]
    return "\n".join(
        [
            "\n### What bounds the forecast: the true flat rolled by the twin "
            "(validation.forecast_bound)\n",
            forecast_bound.summary(forecast_bound.bound_rows(rows), forecast_misses),
            "\n### What bounds each length and kind miss: the truth's cost on the fit's "
            "windows (validation.fit_bound)\n",
            fit_bound.summary(fit_bound.fit_rows(rows)),
        ]
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m validation.diagnosis_validation", description=__doc__.split("\n")[0]
    )
    p.add_argument("--own", type=int, default=40, help="cases from the own generator")
    p.add_argument(
        "--seeds",
        default="20261201,777",
        help="the own generator's seeds, comma-separated (one table each)",
    )
    p.add_argument("--no-cli", action="store_true", help="skip timing the command")
    p.add_argument("--out", type=Path, default=Path("validation/diagnosis_results.json"))
    a = p.parse_args(argv)
    try:
        seeds = [int(x) for x in a.seeds.split(",") if x.strip()]
    except ValueError:
        p.error(f"--seeds must be comma-separated integers, got {a.seeds!r}")
    # compile the kernels first (a cold numba cache takes minutes): the timings are the fits'
    from service.physics.diagnosis import Diagnoser
    from validation import cli_timing, line_truth_reference, own_generator, wide_set

    Diagnoser(wide_set.load_case(wide_set.case_ids()[0]).site).warm_up()
    start = time.perf_counter()
    wide = wide_set.run_all(wide_set.case_ids())
    results: dict[str, list[dict[str, Any]]] = {"wide": wide}
    print("## (a) the independent wide set (validation/measured-wide, 40 passages)\n")
    print(table(wide))
    print(bounds(wide))
    for k, seed in enumerate(seeds if a.own > 0 else []):
        own = own_generator.run_all(a.own, seed)
        results["own" if k == 0 else f"own_{seed}"] = own
        print(
            f"\n## (b{k + 1}) the project's own generator, {a.own} fresh cases over the same "
            f"space (seed {seed})\n"
        )
        print(table(own))
        print(bounds(own))
    a.out.write_text(json.dumps(results, indent=1))
    n = sum(len(v) for v in results.values())
    print(f"\n({n} passages in {time.perf_counter() - start:.0f} s)")
    # the own generator's line-speed truth where the fit's forecast missed it: the same
    # passage by the test suite's slow reference solver (SciPy), two at a time
    keys = [
        (int(r["seed"]), int(r["index"]))
        for k, seed in enumerate(seeds if a.own > 0 else [])
        for r in results["own" if k == 0 else f"own_{seed}"]
        if r["line_truth"] is not None and line_ok(r) is False
    ]
    if keys:
        print(
            "\n## The own generator's line-speed truth by the test suite's slow reference "
            "solver, where the forecast missed it (validation.line_truth_reference)\n"
        )
        print(line_truth_reference.summary(line_truth_reference.reference_rows(keys)))
    if not a.no_cli:
        print("\n## `railtwin diagnose` as a command, on every wide-set passage\n")
        rows = cli_timing.time_all(wide_set.case_ids())
        print(cli_timing.summary(rows, cli_timing.peer_time()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
