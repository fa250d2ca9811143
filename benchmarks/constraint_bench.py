"""Benchmark tabulate_constraint: the fast paths (auto) against the general ψ-search.

    .venv/bin/python -m benchmarks.constraint_bench [--repeat N] [--no-general] [--only PART]

Prints one row per case: best-of-N time per table (auto), node and kink counts, and the
general ψ-search's time on the same case and the ratio (same run). Asserts nothing.

The *site* cases (issue 7): 6 m of rail sampled every 0.5 mm with 10 µm rms roughness
(``random_roughness`` with a power-law spectrum), wheels of R = 0.46 m (the tabulation does
not depend on the speed; at 160 km/h the 6 m take 135 ms). "first wheel" includes the
wheel-independent work on the rail (its polyline and the round wheel's table for this R);
"next wheel" is another wheel on the same rail (that work kept). The general ψ-search is
timed once on the same case in the same run. The site rows also time the whole next-wheel
passage, table and integration together (:func:`site_passage`).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sim_core import paper
from sim_core.constraint import tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.passage import PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.roughness import power_law_psd, random_roughness
from sim_core.wheel import WheelOutline
from sim_core.wheel_roughness import bundled_measurement, load_wheel_roughness

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _best(fn: Callable[[], ConstraintTable], repeat: int) -> tuple[float, ConstraintTable]:
    """Best of ``repeat`` timed calls after a warm call (``repeat`` 0: one timed call, no warm-up)."""
    if repeat == 0:
        t0 = time.perf_counter()
        t = fn()
        return time.perf_counter() - t0, t
    t = fn()  # compile / warm
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        t = fn()
        best = min(best, time.perf_counter() - t0)
    return best, t


def site_rail(
    length: float = 6.0, dx: float = 5e-4, rms: float = 1e-5, seed: int = 3
) -> RailProfile:
    """The issue's site: ``length`` m sampled every ``dx`` with ``rms`` roughness (power law)."""
    k = np.geomspace(2 * np.pi / 1.0, 0.99 * np.pi / dx, 400)
    r = random_roughness(length + 0.2, dx, k, power_law_psd(k, 1.0), seed)
    return RailProfile.sampled(r.x - 0.1, r.y * (rms / np.std(r.y)))


def site_rows(repeat: int = 5, general: bool = True) -> list[dict[str, float | str]]:
    """Out-of-round wheels on the sampled site rail: first wheel, next wheel, general, ratios."""
    R = 0.46
    measured = load_wheel_roughness(bundled_measurement("flat_0p3_01.dat")).to_outline()
    cases: list[tuple[str, WheelOutline, float]] = [
        ("site: ideal flat 50 mm, 6 m", WheelOutline.ideal_flat(R, 0.05), 6.0),
        (
            "site: rounded flat 80 mm, 6 m",
            WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R)),
            6.0,
        ),
        ("site: measured wheel, 0.5 m", measured, 0.5),
    ]
    rows: list[dict[str, float | str]] = []
    for name, wheel, length in cases:
        # warm the compiled code on another rail, then a fresh rail: the first wheel pays its work
        tabulate_constraint(wheel, site_rail(0.3, seed=9), 0.0, 0.1)
        rail = site_rail(length)
        t0 = time.perf_counter()
        tabulate_constraint(wheel, rail, 0.0, length)
        first = time.perf_counter() - t0
        nxt, tab = _best(partial(tabulate_constraint, wheel, rail, 0.0, length, phase=1.0), repeat)
        tg = 0.0
        if general:
            tg, _ = _best(
                partial(tabulate_constraint, wheel, rail, 0.0, length, phase=1.0, method="general"),
                0,
            )
        row: dict[str, float | str] = {
            "case": name,
            "first_wheel_ms": first * 1e3,
            "auto_ms": nxt * 1e3,
            "nodes": float(tab.x.size),
            "kinks": float(tab.kinks.size),
            "general_ms": tg * 1e3,
            "speedup": tg / nxt if tg > 0 else 0.0,
        }
        row.update(site_passage(wheel, rail, length, repeat))
        # the first wheel on its rail: its table (the rail's round table included) and the
        # integration, at 160 km/h
        duration = length / (160 / 3.6)
        row["first_wheel_passage_rtf"] = duration / (first + float(row["integration_ms"]) * 1e-3)
        rows.append(row)
    return rows


SITE_RTOL = 1e-9
"""The site passage's tolerance (the ``PassageSpec`` default)."""
REFERENCE_RTOL = 1e-12
"""The tolerance of the untimed run the site passage's error is measured against."""


def site_passage(
    wheel: WheelOutline, rail: RailProfile, length: float, repeat: int, rtol: float = SITE_RTOL
) -> dict[str, float]:
    """The issue's whole site case for the next wheel: table and integration together.

    The paper's wheel (m, P, Hertz) at 160 km/h over ``length`` on a rigid foundation,
    ``rtol`` (1e-9), 10 kHz output. Returns the best integration time, the best table +
    integration time, its real-time factor, the integrator's accepted and rejected
    steps (on a rough sampled rail the exact constraint has a kink at about every concave
    vertex and a curvature jump at every arc's end: each is a stop), and the error
    against an untimed run at ``REFERENCE_RTOL``: max |F - F_ref|/P over the samples and
    the largest difference of a transition's time (s; NaN if the transitions differ)."""
    speed = 160 / 3.6
    spec = PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=speed,
        duration=length / speed,
        sample_rate=10_000.0,
        contact=paper.contact_model(ContactLaw.HERTZ),
        rtol=rtol,
    )
    out = simulate_passage(tabulate_constraint(wheel, rail, 0.0, length, phase=1.0), spec)
    best_int = best_all = math.inf
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        table = tabulate_constraint(wheel, rail, 0.0, length, phase=1.0)
        t1 = time.perf_counter()
        out = simulate_passage(table, spec)
        t2 = time.perf_counter()
        best_int, best_all = min(best_int, t2 - t1), min(best_all, t2 - t0)
    ref = simulate_passage(table, replace(spec, rtol=REFERENCE_RTOL))
    same = [t.kind for t in out.transitions] == [t.kind for t in ref.transitions]
    dt = [abs(a.t - b.t) for a, b in zip(out.transitions, ref.transitions, strict=False)]
    return {
        "rtol": rtol,
        "integration_ms": best_int * 1e3,
        "table_and_integration_ms": best_all * 1e3,
        "passage_rtf": spec.duration / best_all,
        "steps": float(out.steps),
        "rejected": float(out.rejected_steps),
        "force_error_vs_ref": float(np.max(np.abs(out.force - ref.force))) / paper.LOAD,
        "transition_error_s": max(dt, default=0.0) if same else math.nan,
    }


FIG4_FREQUENCY = 280.0
FIG4_PERIODS = 300


def fig4_scenario() -> Any:
    """The issue's Fig. 4 resonance case as a scenario (CONTRACT.md): ``examples/cosine_hertz.json``
    (round wheel R = 0.475 m on a = 0.1 mm, λ = 5 cm, Hertz, rigid) at 280 Hz for 300 periods
    (14 m/s, 15 m of rail, 1.071 s), 20 samples a period."""
    from schemas import scenario as sc

    data = json.loads((EXAMPLES / "cosine_hertz.json").read_text())
    data["speed"] = FIG4_FREQUENCY * 0.05
    data["duration"] = FIG4_PERIODS / FIG4_FREQUENCY
    data["sample_rate"] = 20 * FIG4_FREQUENCY
    return sc.Scenario.model_validate(data)


def fig4_cli_row(repeat: int = 5) -> dict[str, float | str]:
    """The Fig. 4 case through the CLI's path (``service.physics.scenario_runner.run_scenario``, as
    ``railtwin simulate`` runs each scenario of a batch: compiled code loaded, the table made
    per scenario), best of ``repeat`` (>= 1) of its own ``wall_time`` (tabulation, integration,
    summaries; not the JSON writing). Peers in the same run: the integration alone on the same
    table (``simulate_passage``), and the ψ-search's table of the same case (the path before
    the closed form). The trajectory is chaotic over 300 periods (MODEL.md §7): a table within
    1e-13 m of another takes a different number of steps; the steps are reported."""
    from service.physics.inputs import contact_model
    from service.physics.scenario_runner import build_spec, run_scenario

    scenario = fig4_scenario()
    run_scenario(scenario)  # warm
    best = math.inf
    result = None
    for _ in range(max(repeat, 1)):
        result = run_scenario(scenario)
        assert result.stats is not None
        best = min(best, result.stats.wall_time)
    assert result is not None and result.stats is not None
    w = scenario.wheel
    contact, _ = contact_model(
        scenario.contact, scenario.material, radius=w.radius, load=w.load, mass=w.mass
    )
    spec = build_spec(scenario, contact)
    wheel, rail = WheelOutline.round(w.radius), RailProfile.cosine(1e-4, 0.05)
    length = spec.speed * spec.duration
    t_tab, table = _best(partial(tabulate_constraint, wheel, rail, 0.0, length), repeat)
    best_int = math.inf
    out = simulate_passage(table, spec)
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        out = simulate_passage(table, spec)
        best_int = min(best_int, time.perf_counter() - t0)
    t_gen, _ = _best(partial(tabulate_constraint, wheel, rail, 0.0, length, method="general"), 1)
    return {
        "case": "Fig. 4 through the CLI path: round wheel, cosine 0.1 mm / 5 cm, 300 periods",
        "cli_wall_ms": best * 1e3,
        "cli_rtf": spec.duration / best,
        "table_ms": t_tab * 1e3,
        "integration_ms": best_int * 1e3,
        "integration_rtf": spec.duration / best_int,
        "cli_over_integration": best / best_int,
        "steps": float(result.stats.steps),
        "psi_search_table_ms": t_gen * 1e3,
        "psi_search_over_table": t_gen / t_tab,
        "rtf_with_psi_search_table": spec.duration / (t_gen + best_int),
        "integration_steps": float(out.steps),
    }


def flat_cosine_passage_row(repeat: int = 5, general: bool = True) -> dict[str, float | str]:
    """The 80 mm, l²/16R-deep rounded flat on the paper's cosine (its hollow partly certified),
    6 m at 160 km/h: the table with the windows solved in boxes (auto), with the windows solved
    by the ψ-search (the former path) and by the ψ-search alone; each also as a whole passage
    (table and integration, Hertz), best of ``repeat`` after a warm call, same run."""
    from sim_core.constraint.cosine_hybrid import WindowSolve, tabulate_cosine_hybrid
    from sim_core.constraint.nodes import resolution

    R = 0.46
    wheel = WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R))
    rail = RailProfile.cosine(1e-4, 0.05)
    speed = 160 / 3.6
    spec = PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=speed,
        duration=6.0 / speed,
        sample_rate=10_000.0,
        contact=paper.contact_model(ContactLaw.HERTZ),
    )
    res = resolution(wheel, rail)

    def table(windows: WindowSolve) -> ConstraintTable:
        return tabulate_cosine_hybrid(wheel, rail, 0.0, 6.0, 1.0, None, res, windows=windows)

    def passage(make: Callable[[], ConstraintTable]) -> Callable[[], ConstraintTable]:
        def run_once() -> ConstraintTable:
            t = make()
            simulate_passage(t, spec)
            return t

        return run_once

    def general_table() -> ConstraintTable:
        return tabulate_constraint(wheel, rail, 0.0, 6.0, phase=1.0, method="general")

    tb, tab = _best(partial(table, "boxes"), repeat)
    ts, _ = _best(partial(table, "search"), repeat)
    pb, _ = _best(passage(partial(table, "boxes")), repeat)
    ps, _ = _best(passage(partial(table, "search")), repeat)
    tg = pg = 0.0
    if general:
        tg, _ = _best(general_table, 1)
        pg, _ = _best(passage(general_table), 0)
    return {
        "case": "rounded flat 80 mm, 6 m, cosine 0.1 mm / 5 cm: windows in boxes",
        "auto_ms": tb * 1e3,
        "nodes": float(tab.x.size),
        "kinks": float(tab.kinks.size),
        "general_ms": tg * 1e3,
        "speedup": tg / tb if tg > 0 else 0.0,
        "table_ms_window_search": ts * 1e3,
        "passage_ms": pb * 1e3,
        "passage_ms_window_search": ps * 1e3,
        "passage_ms_general": pg * 1e3,
        "passage_speedup_vs_window_search": ps / pb,
        "passage_speedup_vs_general": pg / pb if pg > 0 else 0.0,
    }


PARTS = ("tables", "site", "fig4")


def run(
    repeat: int = 5, general: bool = True, only: str | None = None
) -> list[dict[str, float | str]]:
    """Rows: case, auto_ms, nodes, kinks, general_ms, ratio (general/auto; 0 if not measured);
    then the site rows (:func:`site_rows`) and the Fig. 4 CLI row (:func:`fig4_cli_row`).
    ``only``: one of :data:`PARTS`."""
    if only == "site":
        return site_rows(repeat, general)
    if only == "fig4":
        return [fig4_cli_row(repeat)]
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
            "ideal flat 50 mm, 6 m, cosine 2 um / 6 cm",
            WheelOutline.ideal_flat(0.46, 0.05),
            RailProfile.cosine(2e-6, 0.06),
            6.0,
            general,
        ),
        (
            "rounded flat 80 mm, 6 m, cosine 2 um / 6 cm",
            WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46)),
            RailProfile.cosine(2e-6, 0.06),
            6.0,
            general,
        ),
        (
            "ideal flat 50 mm, 1 m, cosine 0.1 mm / 5 cm",
            WheelOutline.ideal_flat(0.475, 0.05),
            RailProfile.cosine(1e-4, 0.05),
            1.0,
            general,
        ),
        (
            "rounded flat 80 mm, 6 m, cosine 0.1 mm / 5 cm (partly certified)",
            WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46)),
            RailProfile.cosine(1e-4, 0.05),
            6.0,
            general,
        ),
        (
            "rounded flat 80 mm, 6 m, cosine -0.2 mm / 8 cm (partly certified)",
            WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46)),
            RailProfile.cosine(-2e-4, 0.08),
            6.0,
            general,
        ),
        (
            "rounded flat 80 mm, 1 m, 0.1 mm step rail",
            WheelOutline.rounded_flat(0.46, 0.08, 0.08**2 / (16 * 0.46)),
            RailProfile.step(1e-4, 0.5),
            1.0,
            general,
        ),
        (
            "round wheel, 15 m, cosine 0.1 mm / 5 cm (Fig. 4: one period, closed form)",
            WheelOutline.round(0.475),
            RailProfile.cosine(1e-4, 0.05),
            15.0,
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
    rows.append(flat_cosine_passage_row(repeat, general))
    if only == "tables":
        return rows
    return rows + site_rows(repeat, general) + [fig4_cli_row(repeat)]


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="best of N timed calls (default 5)")
    ap.add_argument("--no-general", action="store_true", help="skip the ψ-search peers")
    ap.add_argument(
        "--only", choices=PARTS, default=None, help="one part: tables, site or fig4 (default all)"
    )
    args = ap.parse_args(argv)
    for r in run(args.repeat, not args.no_general, args.only):
        if "auto_ms" in r:
            first = float(r.get("first_wheel_ms", float("nan")))
            print(
                f"{r['case']!s:60s} first {first:9.2f} ms, auto {float(r['auto_ms']):9.3f} ms, "
                f"{int(r['nodes']):7d} nodes, {int(r['kinks']):6d} kinks, general "
                f"{float(r['general_ms']):9.1f} ms, speedup {float(r['speedup']):6.0f}"
            )
            extra = {
                k: v
                for k, v in r.items()
                if "passage" in k or k in ("first_wheel_rtf", "table_ms_window_search")
            }
        else:
            print(r["case"])
            extra = {k: v for k, v in r.items() if k != "case"}
        if extra:
            print("    " + ", ".join(f"{k} {float(v):.4g}" for k, v in extra.items()))


if __name__ == "__main__":
    main()
