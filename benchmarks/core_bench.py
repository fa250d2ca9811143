"""Benchmark of the simulation core against SciPy ``solve_ivp`` on the same cases, same run.

    .venv/bin/python -m benchmarks.core_bench [--quick] [--repeats N]

Cases (MODEL.md's paper wheel: m = 400 kg, P = 10·m·g, R = 0.475 m,
E = 2.14e11 Pa, ν = 0.3; exact rigid constraint):

(a) Fig. 4 resonance: Hertz, round wheel on a cosine rail a = 0.1 mm,
    λ = 5 cm, f = V/λ = 280 Hz, 300 periods, rigid foundation.
(b) compliant foundation (k = linearised contact stiffness/5, M = 10m),
    60 mm ideal flat at 100 km/h on a flat rail, a few wheel turns.
(c) 20 wheels in sequence, Hertzian–perfectly plastic (Y = 600 MPa): the start
    of Fig. 8 (flat rail, static equilibrium with ẏ_C = -0.3 m/s, 100 km/h,
    60 ms per wheel), each wheel on the rail dented by those before; the
    whole pipeline (tabulation of the dented rail, passage, dents) is timed.
(d) tabulation of the exact constraint of a round wheel on a 10 m random
    ("measured-like") rail sampled every 0.1 mm.

Our real-time factor is simulated seconds per wall second, one core, the best
of ``repeats`` runs after a warm-up run that compiles everything. The SciPy
peers (``benchmarks.scipy_peer``) run once each (they take seconds): DOP853
with event location and a restart at every transition and kink, and, for
scale, one call without events. Agreement: peak force (relative), number of
transitions, largest difference of transition times (transitions paired in
order when both lists have the same kinds in the same order).

For (c) the peer runs the first ``peer_wheels`` wheels only, on the tables our
pipeline built for them, and the cost is compared per wheel (integration only
on both sides, plus our whole-pipeline cost per wheel). For (d) the peer is a
vectorised numpy brute force over the bounded search window (the only rail
samples that can carry the wheel) on a subset of points, extrapolated to every
0.1 mm of the 10 m.

Asserts nothing about speed: numbers depend on the machine and its load.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from benchmarks import scipy_peer
from sim_core import paper
from sim_core.constraint import tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.multipass import simulate_passes
from sim_core.passage import Foundation, InitialState, PassageOutput, PassageSpec, simulate_passage
from sim_core.rail import RailProfile
from sim_core.rail_pass import ConstraintTables, DentedRail, rail_pass
from sim_core.roughness import power_law_psd, random_roughness
from sim_core.wheel import WheelOutline

RTOL = 1e-9
"""railtwin's accuracy setting in every case (``PassageSpec.rtol``, its default); SciPy gets the same."""

LOOSE_RTOL = {"a": 1e-7, "b": 1e-8}
"""A second setting per case; whether it holds the issue's accuracy (1e-4 in force, 1e-7 s
in transition times) is the ``agreement_tight`` row: against railtwin at ``REFERENCE_RTOL``.
Measured: (a) holds it to rtol 1e-7 (5.7e-5, 8e-8 s), (b) only to 1e-9 (6e-4 at 1e-8).

Why (b) misses at 1e-8: no single event is off. Restarted from the rtol-1e-12 state, one
flight costs < 5e-12 m/s and each contact (landing, interior, loss) ~1e-9 m/s of wheel
velocity, a tolerance-level error of the same sign at every bounce; over the ~40 bounces
between flat impacts it adds up to a drift of 1.3e-7 s in the transition times (3.7e-9 s a
bounce), and the last flat impact's force, rising at ~1e9 N/s, is 6e-4 off. Locating the
landings on the redone step (Newton on δ at its end) or rtol-1e-9 singular steps at 1e-8
change neither; 3e-8 happens to give 1.6e-4, 1e-7 4.4e-4."""

REFERENCE_RTOL = 1e-12
"""The tight solution the accuracy of each setting is measured against."""

RESONANCE_FREQUENCY = 280.0
RESONANCE_PERIODS = 300
FLAT_LENGTH = 0.06
FLAT_SPEED = 100.0 / 3.6
FLAT_TURNS = 4
FOUNDATION_MASS_RATIO = 10.0
STIFFNESS_DIVISOR = 5.0
MULTIPASS_WHEELS = 20
MULTIPASS_PEER_WHEELS = 2
MULTIPASS_YIELD = 6e8
MULTIPASS_DURATION = 0.02
"""Window per wheel (s): Fig. 8's first 0.56 m, two dents (the whole 60 ms costs ~3× more per wheel)."""
AGREEMENT_PERIODS = 20
"""(a) is chaotic over 300 periods (MODEL.md §7): agreement is also checked on this short window."""
TAB_LENGTH = 10.0
TAB_DX = 1e-4
TAB_SEED = 7
ROUGHNESS_LEVEL = 3e-9
"""S(k = 1 rad/m) of the power-law roughness (m²/(rad/m)): an rms of ~12 µm between 2 m and 5 mm wavelength."""
BRUTE_POINTS = 200
REPEATS = 5


# --------------------------------------------------------------------------------------
# case builders
# --------------------------------------------------------------------------------------
def resonance_case(periods: int = RESONANCE_PERIODS) -> tuple[ConstraintTable, PassageSpec]:
    """(a) Fig. 4 at 280 Hz: exact constraint of the round wheel on the cosine rail."""
    f = RESONANCE_FREQUENCY
    spec = PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=f * paper.WAVELENGTH,
        duration=periods / f,
        sample_rate=f * 20,
        contact=paper.contact_model(ContactLaw.HERTZ),
        rtol=RTOL,
    )
    return paper.cosine_constraint("exact"), spec


def flat_compliant_case(turns: float = FLAT_TURNS) -> tuple[ConstraintTable, PassageSpec]:
    """(b) 60 mm ideal flat, 100 km/h, flat rail, compliant foundation M = 10m, k = k_lin/5."""
    d = paper.derived()
    wheel = WheelOutline.ideal_flat(paper.RADIUS, FLAT_LENGTH)
    duration = turns * 2.0 * math.pi * paper.RADIUS / FLAT_SPEED
    table = tabulate_constraint(wheel, RailProfile.flat(), 0.0, FLAT_SPEED * duration, phase=0.5)
    spec = PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=FLAT_SPEED,
        duration=duration,
        sample_rate=1e4,
        contact=paper.contact_model(ContactLaw.HERTZ),
        foundation=Foundation.compliant(
            FOUNDATION_MASS_RATIO * paper.MASS, d.contact_stiffness / STIFFNESS_DIVISOR
        ),
        rtol=RTOL,
    )
    return table, spec


def multipass_case(
    duration: float = MULTIPASS_DURATION,
) -> tuple[WheelOutline, RailProfile, PassageSpec]:
    """(c) Fig. 8's start (Y = 600 MPa) for every wheel: round wheel, flat rail, ẏ_C = -0.3 m/s."""
    spec = PassageSpec(
        mass=paper.MASS,
        load=paper.LOAD,
        speed=paper.FIG8_SPEED,
        duration=duration,
        sample_rate=1e4,
        contact=paper.contact_model(ContactLaw.HERTZ_PLASTIC, MULTIPASS_YIELD),
        initial=InitialState(v_c=paper.FIG8_VELOCITY),
        rtol=RTOL,
    )
    return WheelOutline.round(paper.RADIUS), RailProfile.flat(), spec


def tabulation_case(
    length: float = TAB_LENGTH, dx: float = TAB_DX
) -> tuple[WheelOutline, RailProfile]:
    """(d) a round wheel and a random power-law rail (2 m … 5 mm wavelengths) sampled every ``dx``."""
    k = np.geomspace(2 * math.pi / 2.0, 2 * math.pi / 0.005, 600)
    rail = random_roughness(length, dx, k, power_law_psd(k, ROUGHNESS_LEVEL), seed=TAB_SEED)
    return WheelOutline.round(paper.RADIUS), rail


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------
def _best_of(fn: Callable[[], Any], repeats: int) -> tuple[float, list[float], Any]:
    walls = []
    out = None
    for _ in range(max(1, repeats)):
        t = time.perf_counter()
        out = fn()
        walls.append(time.perf_counter() - t)
    return min(walls), walls, out


def agreement(
    ours: PassageOutput, peer: scipy_peer.PeerResult, *, by: str = "force"
) -> dict[str, Any]:
    """Peak (force or indentation) relative difference, transition counts, largest |Δt|."""
    if by == "force":
        a, b = ours.peak_force, peer.peak_force
    else:
        a, b = ours.max_indentation, peer.peak_delta
    ok = [(tr.t, tr.kind) for tr in ours.transitions]
    pk = peer.transitions
    same = [k for _, k in ok] == [k for _, k in pk]
    n = min(len(ok), len(pk))
    dts = [abs(ok[i][0] - pk[i][0]) for i in range(n)]
    first_mismatch = next((i for i in range(n) if ok[i][1] != pk[i][1]), n)
    upto = dts[:first_mismatch]
    return {
        "peak_of": by,
        "peak_rel_diff": abs(a - b) / abs(b) if b else math.nan,
        "transitions_ours": len(ok),
        "transitions_scipy": len(pk),
        "same_sequence": same,
        "max_dt": max(upto) if upto else 0.0,
        "paired": len(upto),
    }


def _log(msg: str) -> None:
    print(f"[core_bench] {msg}", file=sys.stderr, flush=True)


def _passage_stats(out: PassageOutput, sim: float, wall: float) -> dict[str, Any]:
    return {
        "wall_per_step_us": wall / max(out.steps, 1) * 1e6,
        "steps_per_sim_s": out.steps / sim,
        "rejected_per_sim_s": out.rejected_steps / sim,
        "rhs_per_sim_s": out.rhs_evaluations / sim,
        "transitions": len(out.transitions),
        "peak_force_over_load": out.peak_force / paper.LOAD,
    }


def _peer_entry(res: scipy_peer.PeerResult, sim: float, our_wall: float) -> dict[str, Any]:
    return {
        "wall_s": res.wall,
        "rtf": sim / res.wall,
        "ratio": res.wall / our_wall,
        "nfev_per_sim_s": res.nfev / sim,
        "steps_per_sim_s": res.steps / sim,
        "segments": res.segments,
        "rtol": res.extra.get("rtol"),
        "max_step_s": res.extra.get("max_step"),
    }


def bench_passage(
    key: str, title: str, table: ConstraintTable, spec: PassageSpec, repeats: int, peer: bool = True
) -> dict[str, Any]:
    """Best-of-``repeats`` wall time of one passage (after a warm-up run; with peers, timed
    again after them) and its SciPy peers."""
    simulate_passage(table, spec)  # warm-up (compiles on a cold cache)
    best, walls, out = _best_of(lambda: simulate_passage(table, spec), repeats)
    sim = spec.duration
    res: dict[str, Any] = {
        "key": key,
        "case": title,
        "simulated_s": sim,
        "wall_s": best,
        "walls_s": walls,
        "rtf": sim / best,
        "rtol": spec.rtol,
        **_passage_stats(out, sim, best),
    }
    _log(f"{key}: railtwin {best * 1e3:.2f} ms for {sim:.4g} s simulated")
    res["agreement_tight"] = tight_agreement(key, table, spec, out)
    if peer:
        ev = scipy_peer.solve_events(table, spec)
        res["agreement"] = agreement(out, ev)
        _log(f"{key}: scipy with events {ev.wall:.2f} s")
        if key.startswith("a") and spec.duration > AGREEMENT_PERIODS / RESONANCE_FREQUENCY * 1.001:
            short = replace(spec, duration=AGREEMENT_PERIODS / RESONANCE_FREQUENCY)
            ev_s = scipy_peer.solve_events(table, short)
            res["agreement_short"] = agreement(simulate_passage(table, short), ev_s)
            res["agreement_short"]["window"] = f"first {AGREEMENT_PERIODS} periods"
        pl = scipy_peer.solve_plain(table, spec)
        # railtwin again after its peers, which take seconds: the host's speed moves by up to
        # 1.6x within minutes, and railtwin's milliseconds timed only before them could fall
        # in a slow phase the peer's seconds average out (a seed's ratio moved 419-721x)
        again, walls_after, _ = _best_of(lambda: simulate_passage(table, spec), repeats)
        best = min(best, again)
        res.update(
            wall_s=best,
            walls_s=walls + walls_after,
            rtf=sim / best,
            **_passage_stats(out, sim, best),
        )
        _log(f"{key}: railtwin again after its peers {again * 1e3:.2f} ms (best {best * 1e3:.2f})")
        res["scipy_events"] = _peer_entry(ev, sim, best)
        res["scipy_plain"] = _peer_entry(pl, sim, best)
        res["scipy_plain"]["peak_rel_diff"] = abs(out.peak_force - pl.peak_force) / out.peak_force
    return res


def tight_agreement(
    key: str, table: ConstraintTable, spec: PassageSpec, out: PassageOutput
) -> dict[str, Any]:
    """``out`` against railtwin at ``REFERENCE_RTOL``; (a) on its first ``AGREEMENT_PERIODS``
    (over 300 periods it is chaotic: rtol 1e-9 and 1e-12 differ by 12 % in peak force)."""
    window = ""
    if key.startswith("a") and spec.duration > AGREEMENT_PERIODS / RESONANCE_FREQUENCY * 1.001:
        spec = replace(spec, duration=AGREEMENT_PERIODS / RESONANCE_FREQUENCY)
        out = simulate_passage(table, spec)
        window = f", first {AGREEMENT_PERIODS} periods"
    ref = simulate_passage(table, replace(spec, rtol=REFERENCE_RTOL))
    as_peer = scipy_peer.PeerResult(
        wall=0.0,
        transitions=[(tr.t, tr.kind) for tr in ref.transitions],
        peak_delta=ref.max_indentation,
        peak_force=ref.peak_force,
        nfev=ref.rhs_evaluations,
        segments=0,
        steps=ref.steps,
    )
    res = agreement(out, as_peer)
    res["window"] = f"rtol {spec.rtol:g} vs railtwin at rtol {REFERENCE_RTOL:g}{window}"
    return res


def bench_multipass(
    wheels: int = MULTIPASS_WHEELS,
    peer_wheels: int = MULTIPASS_PEER_WHEELS,
    duration: float = MULTIPASS_DURATION,
    repeats: int = 1,
    peer: bool = True,
) -> dict[str, Any]:
    """(c): ``wheels`` wheels through ``simulate_passes``; the peer on the first ``peer_wheels``."""
    wheel, rail, spec = multipass_case(duration)
    simulate_passes(wheel, rail, spec, passes=2)  # warm-up: flat and dented-rail paths
    best, walls, mp = _best_of(lambda: simulate_passes(wheel, rail, spec, passes=wheels), repeats)
    _log(f"c: railtwin {best:.2f} s for {wheels} wheels")
    # cost of each wheel along the run: flat as the dents accumulate (base + dent overlay,
    # round tables spliced where a dent changed the rail)
    stamps = [time.perf_counter()]
    simulate_passes(
        wheel, rail, spec, passes=wheels, progress=lambda *_: stamps.append(time.perf_counter())
    )
    per_wheel = np.diff(stamps)
    fifth = max(1, wheels // 5)
    sim = wheels * spec.duration
    res: dict[str, Any] = {
        "key": "c",
        "case": f"(c) {wheels} wheels, HPP Y = {MULTIPASS_YIELD / 1e6:.0f} MPa, Fig. 8 start "
        f"({duration * 1e3:g} ms each)",
        "wheels": wheels,
        "simulated_s": sim,
        "wall_s": best,
        "walls_s": walls,
        "rtf": sim / best,
        "wall_per_wheel_s": best / wheels,
        "wall_per_wheel_first_fifth_s": float(np.median(per_wheel[1 : fifth + 1])),
        "wall_per_wheel_last_fifth_s": float(np.median(per_wheel[-fifth:])),
        "rtol": spec.rtol,
        "max_dent_m": [s.max_dent for s in mp.summaries],
        "losses": [s.contact_losses for s in mp.summaries],
        "peak_force_over_load": max(s.peak_force for s in mp.summaries) / paper.LOAD,
    }
    if not peer:
        return res
    x0 = spec.speed * spec.t0
    x1 = x0 + spec.speed * spec.duration
    current = DentedRail.of(rail, x0, x1)
    tables = ConstraintTables()
    ours_int: list[float] = []
    steps = rejected = rhs = 0
    peers: list[scipy_peer.PeerResult] = []
    agree: list[dict[str, Any]] = []
    for _ in range(peer_wheels):
        table = tables.table(wheel, current, x0, x1)
        w, _, out = _best_of(partial(simulate_passage, table, spec), repeats=3)
        ours_int.append(w)
        steps += out.steps
        rejected += out.rejected_steps
        rhs += out.rhs_evaluations
        ev = scipy_peer.solve_events(table, spec)
        _log(f"c: scipy with events {ev.wall:.2f} s for one wheel ({table.x.size} table nodes)")
        w_after, _, _ = _best_of(partial(simulate_passage, table, spec), repeats=3)
        ours_int[-1] = min(w, w_after)  # before and after the peer (see bench_passage)
        peers.append(ev)
        agree.append(agreement(out, ev, by="indentation"))
        current = rail_pass(wheel, current, spec, tables).rail
    psim = peer_wheels * spec.duration
    our_int = sum(ours_int)
    peer_wall = sum(p.wall for p in peers)
    res.update(
        {
            "peer_wheels": peer_wheels,
            "steps_per_sim_s": steps / psim,
            "rejected_per_sim_s": rejected / psim,
            "rhs_per_sim_s": rhs / psim,
            "wall_per_step_us": our_int / max(steps, 1) * 1e6,
            "integration_wall_per_wheel_s": our_int / peer_wheels,
            "scipy_events": {
                "wall_s": peer_wall,
                "wall_per_wheel_s": peer_wall / peer_wheels,
                "rtf": psim / peer_wall,
                "ratio": peer_wall / our_int,
                "ratio_vs_pipeline": (peer_wall / peer_wheels) / (best / wheels),
                "nfev_per_sim_s": sum(p.nfev for p in peers) / psim,
                "segments": sum(p.segments for p in peers),
                "rtol": spec.rtol,
            },
            "agreement": {
                "peak_of": "indentation",
                "peak_rel_diff": max(a["peak_rel_diff"] for a in agree),
                "transitions_ours": sum(a["transitions_ours"] for a in agree),
                "transitions_scipy": sum(a["transitions_scipy"] for a in agree),
                "same_sequence": all(a["same_sequence"] for a in agree),
                "max_dt": max(a["max_dt"] for a in agree),
                "per_wheel": agree,
            },
        }
    )
    return res


def brute_force_constraint(
    rail: RailProfile, radius: float, xq: NDArray[np.float64], *, full_chord: bool = False
) -> NDArray[np.float64]:
    """max over rail samples p within the bounded window of sqrt(R² - (p - x)²) + y_r(p) - R.

    The window: a sample farther than sqrt(2R·(max y - min y)) from x lies lower
    than any sample under the wheel, so only those inside can carry it.
    ``full_chord``: search the whole ±R instead (the naive brute force).
    """
    xs, ys = rail.x, rail.y
    h = float(ys.max() - ys.min())
    half = math.sqrt(2.0 * radius * h) + 2.0 * float(xs[1] - xs[0])
    if full_chord:
        half = radius
    dxs = float(xs[1] - xs[0])
    w = math.ceil(half / dxs)
    out = np.empty(xq.size)
    offs = np.arange(-w, w + 1)
    for i, x in enumerate(xq):
        c = round((x - xs[0]) / dxs)
        idx = np.clip(c + offs, 0, xs.size - 1)
        p = xs[idx] - x
        out[i] = np.max(np.sqrt(np.maximum(radius * radius - p * p, 0.0)) + ys[idx]) - radius
    return out


def bench_tabulation(
    length: float = TAB_LENGTH,
    dx: float = TAB_DX,
    repeats: int = 3,
    brute_points: int = BRUTE_POINTS,
) -> dict[str, Any]:
    """(d): tabulate_constraint of a round wheel on the random rail, vs a numpy brute force."""
    wheel, rail = tabulation_case(length, dx)
    R = wheel.nominal_radius
    lo, hi = 0.5, length - 0.5  # keep the wheel's whole window on measured rail
    tabulate_constraint(wheel, rail, lo, lo + 0.05)  # warm-up
    best, walls, table = _best_of(lambda: tabulate_constraint(wheel, rail, lo, hi), repeats)
    rng = np.random.default_rng(1)
    xq = np.sort(rng.uniform(lo, hi, brute_points))
    brute_force_constraint(rail, R, xq[:5])  # warm-up
    t = time.perf_counter()
    yb = brute_force_constraint(rail, R, xq)
    t_brute = time.perf_counter() - t
    per_point = t_brute / brute_points
    nc = max(2, brute_points // 10)
    t = time.perf_counter()
    yc = brute_force_constraint(rail, R, xq[:nc], full_chord=True)
    per_point_chord = (time.perf_counter() - t) / nc
    n_points = math.floor((hi - lo) / dx) + 1
    yt = table.evaluate(xq)
    h = float(rail.y.max() - rail.y.min())
    return {
        "key": "d",
        "case": f"(d) round wheel, {length:g} m random rail, {dx * 1e3:g} mm sampling",
        "rail_samples": int(rail.x.size),
        "rail_rms_m": float(np.std(rail.y)),
        "rail_height_range_m": h,
        "window_half_m": math.sqrt(2.0 * R * h),
        "span_m": hi - lo,
        "nodes": int(table.x.size),
        "kinks": int(table.kinks.size),
        "wall_s": best,
        "walls_s": walls,
        "us_per_metre": best / (hi - lo) * 1e6,
        "brute_points": brute_points,
        "brute_s_per_point": per_point,
        "brute_points_extrapolated": n_points,
        "brute_extrapolated_s": per_point * n_points,
        "ratio": per_point * n_points / best,
        "chord_points": nc,
        "chord_s_per_point": per_point_chord,
        "chord_extrapolated_s": per_point_chord * n_points,
        "chord_ratio": per_point_chord * n_points / best,
        "chord_max_abs_diff_m": float(np.max(np.abs(yc - yb[:nc]))),
        "max_abs_diff_m": float(np.max(np.abs(yt - yb))),
    }


# --------------------------------------------------------------------------------------
# the whole run
# --------------------------------------------------------------------------------------
def run(quick: bool = False, repeats: int = REPEATS, peer: bool = True) -> dict[str, Any]:
    """Every case; ``quick`` shrinks them to a smoke-test size (seconds, not meaningful numbers)."""
    out: dict[str, Any] = {"rtol": RTOL, "repeats": repeats, "quick": quick, "cases": []}
    periods = 6 if quick else RESONANCE_PERIODS
    table, spec = resonance_case(periods)
    out["cases"].append(
        bench_passage(
            "a", f"(a) Fig. 4, 280 Hz, {periods} periods, Hertz", table, spec, repeats, peer
        )
    )
    turns = 0.5 if quick else FLAT_TURNS
    table, spec = flat_compliant_case(turns)
    out["cases"].append(
        bench_passage(
            "b",
            f"(b) 60 mm flat, 100 km/h, compliant M = 10m, {turns:g} turns",
            table,
            spec,
            repeats,
            peer,
        )
    )
    if not quick:
        # The same two cases at a looser tolerance that still meets the issue's accuracy
        # (peak force 1e-4, transition times 1e-7 s against SciPy: see the agreement rows).
        for key, (tab, sp) in (
            ("a", resonance_case(periods)),
            ("b", flat_compliant_case(turns)),
        ):
            rtol = LOOSE_RTOL[key]
            out["cases"].append(
                bench_passage(
                    f"{key}{-math.log10(rtol):.0f}",
                    f"({key}) at rtol {rtol:g}",
                    tab,
                    replace(sp, rtol=rtol),
                    repeats,
                    peer,
                )
            )
    if quick:
        out["cases"].append(
            bench_multipass(wheels=2, peer_wheels=1, duration=0.01, repeats=1, peer=peer)
        )
        out["tabulation"] = bench_tabulation(length=1.2, repeats=1, brute_points=10)
    else:
        out["cases"].append(bench_multipass(peer=peer))
        out["tabulation"] = bench_tabulation()
    return out


def _fmt_s(x: float) -> str:
    if x >= 1.0:
        return f"{x:.2f} s"
    if x >= 1e-3:
        return f"{x * 1e3:.2f} ms"
    return f"{x * 1e6:.0f} µs"


def markdown(res: dict[str, Any]) -> str:
    """The tables of a ``run()`` result, ready for docs/benchmarks.md."""
    lines = [
        f"Simulation core, rtol = {res['rtol']:g} unless the case says otherwise (SciPy: same "
        f"rtol and atol), best of "
        f"{res['repeats']} after a compiling warm-up; SciPy runs once.",
        "",
        "| case | simulated | railtwin wall | real-time factor | steps / rejected / RHS per sim. s "
        "| SciPy DOP853 + events | ratio | SciPy one call, no events | ratio |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in res["cases"]:
        ev = c.get("scipy_events")
        pl = c.get("scipy_plain")
        work = (
            f"{c['steps_per_sim_s']:.3g} / {c['rejected_per_sim_s']:.3g} / {c['rhs_per_sim_s']:.3g}"
            f" ({c['wall_per_step_us']:.1f} µs/step)"
            if "steps_per_sim_s" in c
            else "–"
        )
        if c["key"] == "c":
            wall = f"{_fmt_s(c['wall_s'])} ({_fmt_s(c['wall_per_wheel_s'])}/wheel)"
            if ev:
                evs = (
                    f"{_fmt_s(ev['wall_per_wheel_s'])}/wheel ({c['peer_wheels']} wheels; ours "
                    f"{_fmt_s(c['integration_wall_per_wheel_s'])}/wheel integration only)"
                )
                ratio = f"{ev['ratio']:.0f}× ({ev['ratio_vs_pipeline']:.0f}× vs whole pipeline)"
            else:
                evs = ratio = "–"
            sim = f"{c['simulated_s']:g} s ({c['wheels']} × {c['simulated_s'] / c['wheels']:g} s)"
        else:
            wall = _fmt_s(c["wall_s"])
            evs = _fmt_s(ev["wall_s"]) if ev else "–"
            ratio = f"{ev['ratio']:.0f}×" if ev else "–"
            sim = f"{c['simulated_s']:.4g} s"
        pls = _fmt_s(pl["wall_s"]) if pl else ("n/a" if c["key"] == "c" else "–")
        pratio = f"{pl['ratio']:.0f}×" if pl else "–"
        lines.append(
            f"| {c['case']} | {sim} | {wall} | {c['rtf']:.3g} | {work} | {evs} | {ratio} "
            f"| {pls} | {pratio} |"
        )
    lines += [
        "",
        "Agreement with SciPy DOP853 + events, and with railtwin at a tight tolerance "
        "(transitions paired in order):",
        "",
        "| case | peak rel. diff | transitions ours / SciPy | same sequence | largest |Δt| "
        "| no-events call: peak rel. diff |",
        "|---|---|---|---|---|---|",
    ]
    for c in res["cases"]:
        pl = c.get("scipy_plain")
        plain = f"{pl['peak_rel_diff']:.2g}" if pl else "n/a"
        rows = [(c["key"] + " (whole window)", c.get("agreement"), plain)]
        if c.get("agreement_short"):
            rows[0] = (c["key"] + " (whole window, chaotic)", c.get("agreement"), plain)
            rows.append(
                (f"{c['key']} ({c['agreement_short']['window']})", c["agreement_short"], "–")
            )
        if c.get("agreement_tight"):
            rows.append(
                (f"{c['key']} ({c['agreement_tight']['window']})", c["agreement_tight"], "–")
            )
        for label, ag, pcol in rows:
            if not ag:
                continue
            what = "force" if ag["peak_of"] == "force" else "indentation"
            lines.append(
                f"| {label} | {ag['peak_rel_diff']:.2g} ({what}) | {ag['transitions_ours']} / "
                f"{ag['transitions_scipy']} | {'yes' if ag['same_sequence'] else 'no'} "
                f"| {ag['max_dt']:.2g} s | {pcol} |"
            )
    tb = res.get("tabulation")
    if tb:
        lines += [
            "",
            "Constraint tabulation (exact, closed-form polyline path):",
            "",
            "| case | span | nodes (kinks) | railtwin wall | per metre | numpy brute force "
            "(bounded window), extrapolated | ratio | max |diff| | brute force over ±R, "
            "extrapolated | ratio |",
            "|---|---|---|---|---|---|---|---|---|---|",
            f"| {tb['case']}, rms {tb['rail_rms_m'] * 1e6:.1f} µm | {tb['span_m']:g} m "
            f"| {tb['nodes']} ({tb['kinks']}) | {_fmt_s(tb['wall_s'])} "
            f"| {_fmt_s(tb['us_per_metre'] * 1e-6)} "
            f"| {_fmt_s(tb['brute_extrapolated_s'])} ({tb['brute_points']} points × "
            f"{tb['brute_points_extrapolated']}, window ±{tb['window_half_m'] * 1e3:.1f} mm) "
            f"| {tb['ratio']:.1f}× | {tb['max_abs_diff_m']:.1e} m "
            f"| {_fmt_s(tb['chord_extrapolated_s'])} ({tb['chord_points']} points) "
            f"| {tb['chord_ratio']:.0f}× |",
        ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0] if __doc__ else None)
    p.add_argument("--quick", action="store_true")
    p.add_argument("--repeats", type=int, default=REPEATS)
    p.add_argument("--no-peer", action="store_true")
    p.add_argument("--json", action="store_true", help="print the raw results as JSON too")
    a = p.parse_args(argv)
    res = run(quick=a.quick, repeats=a.repeats, peer=not a.no_peer)
    print(markdown(res))
    if a.json:
        print(json.dumps(res, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
