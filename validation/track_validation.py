"""The discrete and slab track against an independent reference and against ROSE (``make validate-track``).

Two sources, both in ``validation/data/track/`` (README there: what they are, whose):

- the independent reference's six forward cases (``track_cases.json.gz``): each case's
  peak contact force (target: within 2 %), each crib channel through the reference's
  4 kHz causal Butterworth at 200 kHz and compared at its 20 kHz samples (target: within
  2 % of P plus the reference's own step and mesh uncertainty), and the number of contact
  losses (the same);
- ROSE (PlatypusBytes/ROSE, two bugs fixed; ``summary_timoshenko.json``): the smooth rail,
  a 50 mm worn flat and a rail dip at 20 and 40 m/s on its ballasted track: impact peaks
  within 5 %, the smooth rail's dominant line at V/L_s and the P2 resonance within 2 %.

Every case runs through the contract's own path when it is a railtwin scenario (the
reference's), as ``railtwin simulate`` runs it.

Run: ``python -m validation.track_validation [--cases T01 T02 …] [--no-rose] [--out FILE.md]``.
"""

from __future__ import annotations

import argparse
import gzip
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

DATA = Path(__file__).parent / "data" / "track"
P_TOL_REF = 0.02
CHANNEL_TOL = 0.02
P_TOL_ROSE = 0.05
FREQ_TOL = 0.02


def reference_cases() -> list[dict[str, Any]]:
    """The independent reference's cases (scenario and answer each)."""
    with gzip.open(DATA / "track_cases.json.gz", "rt") as f:
        cases: list[dict[str, Any]] = json.load(f)["cases"]
    return cases


def lowpass(
    y: NDArray[np.float64], fs: float, corner: float = 4000.0, order: int = 4
) -> NDArray[np.float64]:
    """The reference's causal Butterworth, started in the steady state of the first sample."""
    from scipy.signal import butter, sosfilt, sosfilt_zi

    sos = butter(order, corner, fs=fs, output="sos")
    out, _ = sosfilt(sos, y, zi=sosfilt_zi(sos) * y[0])
    return np.asarray(out)


@dataclass(frozen=True)
class CaseRow:
    """One reference case's comparison."""

    case: str
    peak_ref: float
    peak: float
    channel_err: float
    channel_err_away: float
    channel_allowed: float
    losses_ref: int
    losses: int
    seconds: float

    @property
    def peak_rel(self) -> float:
        return self.peak / self.peak_ref - 1.0

    @property
    def ok(self) -> bool:
        return (
            abs(self.peak_rel) <= P_TOL_REF
            and self.channel_err_away <= self.channel_allowed
            and self.losses == self.losses_ref
        )


def run_reference_case(case: dict[str, Any]) -> CaseRow:
    """``case`` through the scenario runner, compared as the reference's README says."""
    from schemas.scenario import Scenario
    from service.physics.scenario_runner import run_scenario

    scenario = Scenario.model_validate(case["scenario"])
    t0 = time.perf_counter()
    result = run_scenario(scenario)
    seconds = time.perf_counter() - t0
    ref = case["reference"]
    p = scenario.wheel.load
    channels = result.series.channels or {}
    worst = 0.0
    worst_away = 0.0
    x = np.asarray(result.series.x)
    step = round(scenario.sample_rate / ref["sample_rate"])
    detector = scenario.detector
    gauges = [g for c in (detector.cribs if detector else []) for g in (c.x_a, c.x_b)]
    # a sample exactly on a gauge is a tie (the step's either side, by the last bits of x);
    # the filtered channel carries it for ~0.3 ms: those samples are also reported apart
    tie = np.zeros(x.size, dtype=bool)
    for g in gauges:
        hit = np.flatnonzero(np.abs(x - g) <= 1e-9 * (1 + abs(g)))
        for i in hit:
            tie[i : i + int(3e-4 * scenario.sample_rate)] = True
    for cid, expected in ref["channels_lp"].items():
        y = lowpass(np.asarray(channels[cid], dtype=np.float64), scenario.sample_rate)
        ours = y[::step]
        n = min(ours.size, len(expected))
        err = np.abs(ours[:n] - np.asarray(expected[:n])) / p
        worst = max(worst, float(np.max(err)))
        away = ~tie[::step][:n]
        worst_away = max(worst_away, float(np.max(err[away])) if away.any() else 0.0)
    dt_half = ref["self_convergence_dt_half"]["channels_lp4k_max_over_P"]
    h_half = ref["self_convergence_h_half"]["channels_lp4k_max_over_P"]
    return CaseRow(
        case=case["id"],
        peak_ref=ref["peak_force"],
        peak=result.summary.peak_force,
        channel_err=worst,
        channel_err_away=worst_away,
        channel_allowed=CHANNEL_TOL + dt_half + h_half,
        losses_ref=ref["contact_losses"],
        losses=result.summary.contact_losses,
        seconds=seconds,
    )


# --- ROSE ------------------------------------------------------------------------------------

ROSE_SPEEDS = (20.0, 40.0)
ROSE_TRAVEL = 6.0
ROSE_SAMPLE_RATE = 50_000.0


def rose_scenario(case: str, speed: float) -> dict[str, Any]:
    """ROSE's case (peers/rose README) as a railtwin scenario: x_C = 0 is ROSE's x = 12 m."""
    rail: dict[str, Any] = {"kind": "flat"}
    outline: dict[str, Any] = {"kind": "round"}
    phase = 0.0
    if case == "flat":
        outline = {"kind": "rounded_flat", "length": 0.05, "depth": 0.30e-3}
        phase = 2.0 * math.pi - 2.1 / 0.46
    elif case == "dip":
        xs = np.linspace(2.0, 2.2, 401)
        ys = -0.5 * 0.30e-3 * (1.0 - np.cos(2.0 * np.pi * (xs - 2.0) / 0.2))
        rail = {"kind": "sampled", "x": xs.tolist(), "y": ys.tolist()}
    e, nu = 2.1e11, 0.3
    return {
        "wheel": {
            "mass": 800.0,
            "load": 80000.0,
            "radius": 0.46,
            "outline": outline,
            "phase": phase,
        },
        "rail": rail,
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
        "contact": "hertz",
        "foundation": {
            "kind": "discrete",
            "rail": {
                "youngs_modulus": e,
                "second_moment": 3.055e-5,
                "mass_per_length": 7850.0 * 7.67e-3,
                "shear_modulus": e / (2.0 * (1.0 + nu)),
                "area": 7.67e-3,
                "shear_coefficient": 0.4,
            },
            "sleeper_spacing": 0.6,
            "first_sleeper": 0.0,
            "pad": {"stiffness": 2.0e8, "damping": 3.0e4},
            "sleeper_mass": 150.0,
            "ballast": {"stiffness": 1.2e8, "damping": 8.0e4},
        },
        "speed": speed,
        "duration": ROSE_TRAVEL / speed,
        "sample_rate": ROSE_SAMPLE_RATE,
    }


@dataclass(frozen=True)
class RoseRow:
    what: str
    rose: float
    ours: float
    tol: float

    @property
    def rel(self) -> float:
        return self.ours / self.rose - 1.0

    @property
    def ok(self) -> bool:
        return abs(self.rel) <= self.tol


def dominant_frequency(
    t: NDArray[np.float64], f: NDArray[np.float64], lo: float, hi: float
) -> float:
    """The largest spectral line of f between lo and hi (Hann window, zero-padded 4x)."""
    f = f - np.mean(f)
    nfft = 1 << (math.ceil(math.log2(f.size)) + 2)
    spec = np.abs(np.fft.rfft(f * np.hanning(f.size), nfft))
    fr = np.fft.rfftfreq(nfft, t[1] - t[0])
    sel = (fr >= lo) & (fr <= hi)
    return float(fr[sel][np.argmax(spec[sel])])


def rose_rows() -> list[RoseRow]:
    """Every ROSE figure of its README against railtwin's."""
    from schemas.scenario import Scenario
    from service.physics.scenario_runner import run_scenario

    rose = json.loads((DATA / "summary_timoshenko.json").read_text())
    by = {(r["case"], r["speed"]): r for r in rose["results"]}
    rows: list[RoseRow] = []
    for speed in ROSE_SPEEDS:
        for case in ("smooth", "flat", "dip"):
            res = run_scenario(Scenario.model_validate(rose_scenario(case, speed)))
            t = np.asarray(res.series.t)
            x = np.asarray(res.series.x)
            f = np.asarray(res.series.force)
            r = by[(case, speed)]
            settle = x >= 1.0
            tag = f"{case} {speed:g} m/s"
            if case == "smooth":
                rows.append(
                    RoseRow(
                        f"{tag}: max force",
                        r["max_force_after_1m_N"],
                        float(f[settle].max()),
                        P_TOL_ROSE,
                    )
                )
                rows.append(
                    RoseRow(
                        f"{tag}: min force",
                        r["min_force_after_1m_N"],
                        float(f[settle].min()),
                        P_TOL_ROSE,
                    )
                )
                # the sleeper-passing line V/L_s or its harmonic, whichever ROSE found dominant
                line = dominant_frequency(t[settle], f[settle], 5.0, 3000.0)
                rose_line = r["dominant_freqs_Hz_relamp"][0][0]
                k = round(rose_line / (speed / 0.6))
                rows.append(RoseRow(f"{tag}: dominant line ({k}·V/L_s)", rose_line, line, FREQ_TOL))
            elif case == "flat":
                for k, ev in enumerate(r["events"][:2]):
                    xc = ev["x_centre_m"] - 12.0
                    w = (x > xc - 0.1) & (x < xc + 0.6)
                    rows.append(
                        RoseRow(
                            f"{tag}: impact {k + 1}", ev["F_max_N"], float(f[w].max()), P_TOL_ROSE
                        )
                    )
                xc = r["events"][0]["x_centre_m"] - 12.0
                i0 = int(np.argmin(np.abs(x - (xc - 0.05))))
                w = slice(i0, i0 + int(0.06 * ROSE_SAMPLE_RATE))
                p2 = dominant_frequency(t[w], f[w], 30.0, 200.0)
                rose_p2 = next(
                    fr
                    for fr, _ in r["dominant_freqs_after_first_event_Hz_relamp"]
                    if 30 <= fr <= 200
                )
                rows.append(RoseRow(f"{tag}: P2 line after the impact", rose_p2, p2, FREQ_TOL))
            else:
                ev = r["events"][0]
                rows.append(
                    RoseRow(f"{tag}: dip peak", ev["F_max_N"], float(f[settle].max()), P_TOL_ROSE)
                )
                rows.append(
                    RoseRow(f"{tag}: dip least", ev["F_min_N"], float(f[settle].min()), P_TOL_ROSE)
                )
    return rows


def markdown(cases: list[CaseRow], rose: list[RoseRow]) -> str:
    out = [
        "| case | peak, reference (kN) | peak, railtwin (kN) | Δ | worst channel Δ (of P) | away from gauge ties | allowed | losses ref / ours | s | ok |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in cases:
        out.append(
            f"| {c.case} | {c.peak_ref / 1e3:.1f} | {c.peak / 1e3:.1f} | {100 * c.peak_rel:+.2f} % | "
            f"{100 * c.channel_err:.2f} % | {100 * c.channel_err_away:.2f} % | {100 * c.channel_allowed:.2f} % | {c.losses_ref} / {c.losses} | "
            f"{c.seconds:.1f} | {'yes' if c.ok else 'NO'} |"
        )
    if rose:
        out += [
            "",
            "| ROSE figure | ROSE | railtwin | Δ | allowed | ok |",
            "|---|---|---|---|---|---|",
        ]
        for r in rose:
            unit, scale = ("Hz", 1.0) if "line" in r.what else ("kN", 1e-3)
            out.append(
                f"| {r.what} | {r.rose * scale:.1f} {unit} | {r.ours * scale:.1f} {unit} | {100 * r.rel:+.2f} % | "
                f"{100 * r.tol:.0f} % | {'yes' if r.ok else 'NO'} |"
            )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m validation.track_validation", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--cases", nargs="*", help="reference case ids (default: all)")
    ap.add_argument("--no-rose", action="store_true", help="skip the ROSE cases")
    ap.add_argument("--out", type=Path, help="also write the tables to this markdown file")
    a = ap.parse_args(argv)
    rows = []
    for case in reference_cases():
        if a.cases and case["id"] not in a.cases:
            continue
        row = run_reference_case(case)
        print(
            f"{row.case}: peak {100 * row.peak_rel:+.2f} %, channels {100 * row.channel_err:.2f} % of P",
            file=sys.stderr,
        )
        rows.append(row)
    rose = [] if a.no_rose else rose_rows()
    text = markdown(rows, rose)
    print(text)
    if a.out:
        a.out.write_text(text + "\n")
    return 0 if all(r.ok for r in rows) and all(r.ok for r in rose) else 1


if __name__ == "__main__":
    raise SystemExit(main())
