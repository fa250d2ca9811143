"""The paper's Figs. 3–9 drawn from ``sim_core.paper`` (``railtwin figures --out DIR``).

``make_figures(out_dir)`` writes fig3.png … fig9.png and facts.json (every
figure's measured facts, SI units) and returns the paths written. Plotting
only: all numbers come from ``sim_core.paper``. matplotlib is imported here,
with the Agg backend, so the module needs no display.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from sim_core import paper

DPI = 110


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def _phase(ax: Axes, run: paper.Run, title: str) -> None:
    y = (run.y_c - run.y_c[0]) * 1e3
    ax.plot(run.v_c, y, lw=0.4, color="tab:blue")
    ax.plot(run.v_c[:1], y[:1], "o", ms=4, color="tab:red", label="start (static equilibrium)")
    ax.set_xlabel("wheel velocity dy_C/dt (m/s)")
    ax.set_ylabel("wheel centre y_C - y_C(0) (mm)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)


def fig3(path: Path) -> Path:
    r = paper.fig3()
    fig, axs = plt.subplots(2, 2, figsize=(11, 7.5))
    ax = axs[0, 0]
    ax.plot(r.cosine_x * 1e3, r.cosine_rail * 1e3, "--", color="gray", label="rail a·cos(2πx/λ)")
    ax.plot(r.cosine_x * 1e3, r.cosine_constraint * 1e3, color="tab:blue", label="constraint y_C^k")
    ax.set_xlabel("wheel position x_C (mm)")
    ax.set_ylabel("height (mm)")
    ax.set_title("Cosine rail a = 0.1 mm, λ = 5 cm: rigid constraint", fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    ax = axs[0, 1]
    k = np.arange(1, r.cosine_amplitudes.size)
    ax.bar(k, r.cosine_amplitudes[1:] / paper.AMPLITUDE, color="tab:blue")
    for i in (1, 2):
        ax.annotate(
            f"{r.cosine_amplitudes[i] / paper.AMPLITUDE:.3f}a",
            (i, r.cosine_amplitudes[i] / paper.AMPLITUDE),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    ax.set_xlabel("harmonic of λ (k)")
    ax.set_ylabel("amplitude / a (-)")
    ax.set_title("Cosine rail: amplitude spectrum of y_C^k", fontsize=9)
    ax.grid(alpha=0.3)
    ax = axs[1, 0]
    ax.plot(r.flat_x * 1e3, r.flat_constraint * 1e3, color="tab:green")
    ax.set_xlim(-100, 100)
    ax.set_xlabel("wheel position x_C from the flat's centre (mm)")
    ax.set_ylabel("constraint y_C^k (mm)")
    ax.set_title("Ideal flat l = 61.6 mm (d ≈ 1 mm), even rail: rigid constraint", fontsize=9)
    ax.grid(alpha=0.3)
    ax = axs[1, 1]
    k = np.arange(1, r.flat_amplitudes.size)
    ax.bar(k, r.flat_amplitudes[1:] * 1e6, color="tab:green")
    ax.set_xlabel("harmonic of the wheel rotation (k)")
    ax.set_ylabel("amplitude (µm)")
    ax.set_title(
        f"Ideal flat: spectrum (10th / 1st = {r.facts['flat_10th_over_1st']:.2f})", fontsize=9
    )
    ax.grid(alpha=0.3)
    fig.suptitle("Fig. 3 — rigid constraint y_C^k and its amplitude spectrum")
    fig.tight_layout()
    return _save(fig, path)


def fig4(path: Path, quick: bool) -> Path:
    r = paper.fig4(quick)
    fig, axs = plt.subplots(2, 3, figsize=(14, 7.5))
    for i, run in enumerate(r.runs):
        f = run.facts
        _phase(
            axs[0, i],
            run,
            f"{_frequency_label(run.frequency)}: {f['losses']} losses, "
            f"{100 * f['fraction_out_of_contact']:.1f} % out of contact",
        )
        ax = axs[1, i]
        n = int(min(20, f["periods"]) * paper.SAMPLES_PER_PERIOD)
        ax.plot(run.t[:n] * run.frequency, run.force[:n] / paper.LOAD, lw=0.7)
        ax.set_xlabel("time (excitation periods)")
        ax.set_ylabel("contact force F / P (-)")
        ax.set_title(
            f"first 20 periods: F_max = {f['early_peak_force_over_load']:.3g} P", fontsize=9
        )
        ax.grid(alpha=0.3)
    periods = r.runs[0].facts["periods"]
    fig.suptitle(
        f"Fig. 4 — Hertz contact on the cosine rail at 56 Hz, f0 = {paper.F0:g} Hz and "
        f"2f0 = {2 * paper.F0:g} Hz (the paper's ≈ 280 and 560 Hz), {periods} excitation "
        "periods: phase portraits (top) and contact force (bottom)",
        fontsize=10,
    )
    fig.tight_layout()
    return _save(fig, path)


def _frequency_label(f: float) -> str:
    """'f = 56 Hz', 'f = f0 = 270.6 Hz', 'f = 2f0 = 541.2 Hz'."""
    if f == paper.F0:
        return f"f = f0 = {f:g} Hz"
    if f == 2.0 * paper.F0:
        return f"f = 2f0 = {f:g} Hz"
    return f"f = {f:g} Hz"


def _static(path: Path, r: paper.StaticCurves, title: str, loading_label: str) -> Path:
    fig, ax = plt.subplots(figsize=(7.5, 5.5))
    ax.plot(r.delta_over_dy, r.hertz, ":", color="gray", label="Hertz C·δ^(3/2)")
    ax.plot(r.delta_over_dy, r.loading, color="tab:blue", label=loading_label)
    mask = r.unloading > 0
    ax.plot(r.delta_over_dy[mask], r.unloading[mask], color="tab:red", label="unloading from 2δ_Y")
    ax.axhline(1.0, color="k", lw=0.5)
    ax.axvline(1.0, color="k", lw=0.5)
    ax.set_xlim(0, 2)
    ax.set_ylim(0, 1.1 * max(float(r.loading.max()), float(r.hertz.max())))
    ax.set_xlabel("indentation δ / δ_Y (-)")
    ax.set_ylabel("contact force F / F_Y (-)")
    ax.set_title(title, fontsize=10)
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def fig5(path: Path) -> Path:
    r = paper.fig5()
    f = r.facts
    title = (
        "Fig. 5 — Johnson's cavity model, static: "
        f"F(2δ_Y) = {f['johnson_force_at_2dy_over_fy']:.2f} F_Y, "
        f"δ_f = {f['final_over_dy']:.3f} δ_Y"
    )
    return _static(path, r, title, "Johnson loading (Hertz below δ_Y)")


def fig7(path: Path) -> Path:
    r = paper.fig7()
    f = r.facts
    title = (
        "Fig. 7 — Hertzian–perfectly plastic, static: plateau F_Y, "
        f"recovery δ_r = {f['recovery_over_dy']:.2f} δ_Y"
    )
    return _static(path, r, title, "HPP loading (plateau F_Y above δ_Y)")


def fig6(path: Path, quick: bool) -> Path:
    r = paper.fig6(quick)
    fig, axs = plt.subplots(2, 2, figsize=(11, 8))
    for ax, run in zip(axs.ravel(), r.runs, strict=True):
        f = run.facts
        _phase(
            ax,
            run,
            f"{run.label}: {100 * f['fraction_out_of_contact']:.2f} % out of contact, "
            f"max gap {f['max_gap_m'] * 1e3:.2f} mm",
        )
    fig.suptitle(
        f"Fig. 6 — Johnson vs Hertz at 2f0 = {2 * paper.F0:g} Hz (the paper's ≈ 560 Hz) "
        f"on the cosine rail: phase portraits ({r.runs[0].facts['periods']} periods)",
        fontsize=10,
    )
    fig.tight_layout()
    return _save(fig, path)


def fig8(path: Path) -> Path:
    r = paper.fig8()
    fig, axs = plt.subplots(3, 1, figsize=(10, 9))
    for c in r.cases:
        lab = f"Y = {c.yield_stress / 1e6:.0f} MPa"
        axs[0].plot(c.t * 1e3, c.y_c * 1e3, lw=0.8, label=lab)
        axs[1].plot(c.t * 1e3, c.force / paper.LOAD, lw=0.8, label=lab)
        depths = c.facts["dent_depths_m"]
        mean = float(np.mean(depths)) if depths else 0.0
        axs[2].plot(
            c.dent_x, -c.dent_depth * 1e3, lw=0.8, label=f"{lab}: dents {mean * 1e3:.3f} mm"
        )
    axs[0].set_xlabel("time (ms)")
    axs[0].set_ylabel("wheel centre y_C (mm)")
    axs[1].set_xlabel("time (ms)")
    axs[1].set_ylabel("contact force F / P (-)")
    axs[2].set_xlabel("position along the rail x (m)")
    axs[2].set_ylabel("rail after passage y_f (mm)")
    for ax in axs:
        ax.legend(fontsize=8, loc="lower right")
        ax.grid(alpha=0.3)
    fig.suptitle(
        "Fig. 8 — HPP contact, even rail, V = 100 km/h, start dy_C/dt = -0.3 m/s: "
        "self-sustained bouncing and periodic dents"
    )
    fig.tight_layout()
    return _save(fig, path)


def fig9(path: Path, quick: bool) -> Path:
    r = paper.fig9(quick)
    shown = [run for run in r.runs if "profile" not in run.label or "0.25" in run.label]
    fig, axs = plt.subplots(len(shown), 1, figsize=(10, 2.2 * len(shown)), sharex=True)
    n = int(min(40, shown[0].facts["periods"]) * paper.SAMPLES_PER_PERIOD)
    for ax, run in zip(axs, shown, strict=True):
        f = run.facts
        ax.plot(run.t[:n] * run.frequency, run.delta[:n] * 1e3, lw=0.7)
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel("δ (mm)")
        ax.set_title(
            f"{run.label}: {f['losses']} losses, "
            f"{100 * f['fraction_out_of_contact']:.1f} % out of contact, "
            f"min δ = {f['min_delta_m'] * 1e3:.4f} mm",
            fontsize=9,
        )
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel("time (excitation periods at 280 Hz)")
    k = r.facts["foundation_stiffness_n_per_m"]
    fig.suptitle(
        f"Fig. 9 — compliant foundation k = {k:.3g} N/m, 280 Hz: indentation δ "
        "(first 40 periods; counts over the whole window)"
    )
    fig.tight_layout()
    return _save(fig, path)


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def make_figures(out_dir: Path, quick: bool = False) -> list[Path]:
    """Draw fig3.png … fig9.png and facts.json into ``out_dir``; return the paths.

    ``quick`` shortens the long simulated windows (300 → 40 excitation periods).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [
        fig3(out / "fig3.png"),
        fig4(out / "fig4.png", quick),
        fig5(out / "fig5.png"),
        fig6(out / "fig6.png", quick),
        fig7(out / "fig7.png"),
        fig8(out / "fig8.png"),
        fig9(out / "fig9.png", quick),
    ]
    facts = out / "facts.json"
    facts.write_text(json.dumps(_jsonable(paper.all_facts(quick)), indent=2) + "\n")
    paths.append(facts)
    return paths
