"""The independent wide set (``validation/measured-wide``) through the same path as
``railtwin diagnose``: site file, ``WheelPassage`` from what the site knows, the CSV as a
``MeasuredPassage``, ``Diagnoser.diagnose``; then compared with ``truth`` and
``line_speed_truth.json``; and, for each flat, what the truth itself gives the twin
(``validation.truth_bounds``).

    .venv/bin/python -m validation.wide_set [--only W01,W05] [--out rows.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.physics.diagnosis import Diagnoser, FitCurves
from service.wire.site import load_site
from sim_core.diagnosis.forward import FlatKind
from validation.truth_bounds import true_depth_factor, truth_fields

WIDE_DIR = Path(__file__).resolve().parent / "measured-wide"


@dataclass(frozen=True)
class WideCase:
    """One passage of the wide set: what the site knows, the record, the truth."""

    case_id: str
    site: SiteConfig
    passage: WheelPassage
    measured: MeasuredPassage
    truth: dict[str, Any]
    zeta: float
    line_peak_measured: float | None


def true_flat(c: WideCase) -> tuple[FlatKind, float, float] | None:
    """(kind, length m, depth factor) of the case's true flat, None for a round wheel."""
    kind = c.truth["kind"]
    if not kind:
        return None
    length = float(c.truth["flat_length_m"])
    depth = float(c.truth.get("flat_depth_m") or 0.0)
    return kind, length, true_depth_factor(kind, c.passage.radius, length, depth)


def case_ids(directory: Path = WIDE_DIR) -> list[str]:
    return sorted(p.stem for p in directory.glob("W*.json"))


def load_case(case_id: str, directory: Path = WIDE_DIR) -> WideCase:
    meta = json.loads((directory / f"{case_id}.json").read_text(encoding="utf-8"))
    site = load_site(directory / f"{case_id}.site.toml")
    passage = WheelPassage(
        passage_id=case_id.lower(),
        train_id="wide",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=float(meta["V"]),
        load=float(meta["P"]),
        mass=float(meta["m"]),
        radius=float(meta["R"]),
    )
    data = np.loadtxt(directory / f"{case_id}.csv", delimiter=",", skiprows=1)
    t, f = data[:, 0], data[:, 1]
    rate = float(meta["sensor"]["fs_Hz"])
    measured = MeasuredPassage(
        passage_id=passage.passage_id, sample_rate=rate, t_start=float(t[0]), force=f.tolist()
    )
    line = json.loads((directory / "line_speed_truth.json").read_text(encoding="utf-8"))
    got = line["passages"].get(case_id)
    return WideCase(
        case_id,
        site,
        passage,
        measured,
        meta["truth"],
        float(meta["foundation"]["zeta"]),
        float(got["peak_measured"]) if got else None,
    )


def run_case(c: WideCase) -> dict[str, Any]:
    d = Diagnoser(c.site)
    cpu = time.process_time()
    diag, curves = d.diagnose(c.passage, c.measured)
    cpu = time.process_time() - cpu
    tr = c.truth
    kind = tr["kind"] or "round"
    bounds: dict[str, Any] = {}
    if tr["kind"]:
        bounds = truth_fields(
            d,
            c.passage,
            c.measured,
            tr["kind"],
            float(tr["flat_length_m"]),
            float(tr.get("flat_depth_m") or 0.0),
            float(tr["phi0"]),
            c.line_peak_measured,
        )
    return {
        "case": c.case_id,
        "source": "wide",
        "kind": kind,
        "true_length": float(tr["flat_length_m"] or 0.0),
        "true_depth": float(tr["flat_depth_m"]) if tr.get("flat_depth_m") else None,
        "speed_kmh": c.passage.speed * 3.6,
        "true_damping_ratio": c.zeta,
        "true_peak": float(tr["true_F_max_in_site"]),
        "line_truth": c.line_peak_measured,
        **fitted_fields(diag, curves, cpu),
        **bounds,
    }


def fitted_fields(diag: Diagnosis, curves: FitCurves, cpu: float) -> dict[str, Any]:
    """The columns of a validation row that come from the diagnosis (both sources)."""
    found = diag.flat
    est = curves.force_estimate
    return {
        "fitted_damping_ratio": est.damping_ratio,
        "found_kind": found.kind if found else None,
        "found_length": found.length if found else 0.0,
        "length_low": found.length_low if found else None,
        "length_high": found.length_high if found else None,
        "found_depth": found.depth if found else None,
        "best_kind": est.best_kind,
        "best_length": est.best_length,
        "verdict": diag.verdict,
        "reasons": diag.reasons,
        "peak_measured": diag.peak_force_measured,
        "explained": diag.explained,
        "noise_level": diag.noise_level,
        "fit_rms": diag.fit_rms,
        "line_point": diag.peak_force_at_line_speed,
        "line_low": diag.peak_force_at_line_speed_low,
        "line_high": diag.peak_force_at_line_speed_high,
        "wall_time": diag.wall_time,
        "fit_time": est.wall_time,
        "cpu_time": cpu,
        "significance": est.significance,
        "contrast": est.contrast,
    }


def summary_line(r: dict[str, Any]) -> str:
    ll = (
        ""
        if r["line_truth"] is None
        else (
            f" line {r['line_point'] / 1e3:6.0f} kN vs {r['line_truth'] / 1e3:6.0f}"
            + (
                ""
                if r["line_low"] is None
                else f" [{r['line_low'] / 1e3:.0f}, {r['line_high'] / 1e3:.0f}]"
            )
        )
    )
    iv = (
        ""
        if r["length_low"] is None
        else f" [{r['length_low'] * 1e3:5.1f},{r['length_high'] * 1e3:5.1f}]"
    )
    return (
        f"{r['case']} {r['kind']:12s} {r['true_length'] * 1e3:6.1f} mm @ {r['speed_kmh']:5.0f} "
        f"km/h z {r['true_damping_ratio']:.2f}->{r['fitted_damping_ratio']:.2f} -> "
        f"{r['found_kind']!s:12s} {r['found_length'] * 1e3:6.1f}{iv} {r['verdict']:7s} "
        f"expl {r['explained']} rms {r['fit_rms'] / 1e3:.1f} kN{ll} {r['wall_time']:.2f} s"
    )


def run_all(ids: list[str]) -> list[dict[str, Any]]:
    rows = []
    for cid in ids:
        r = run_case(load_case(cid))
        rows.append(r)
        print(summary_line(r), file=sys.stderr, flush=True)
    return rows


def cases_parser(module: str, doc: str | None) -> argparse.ArgumentParser:
    """The command line of a script over the wide set: ``--only`` case ids (see
    ``chosen_ids``); ``doc``'s first line is its description."""
    p = argparse.ArgumentParser(prog=f"python -m {module}", description=(doc or "").split("\n")[0])
    p.add_argument("--only", default=None, help="comma-separated case ids (default: all)")
    return p


def chosen_ids(args: argparse.Namespace) -> list[str]:
    """The case ids ``--only`` names, else every case of the set."""
    return str(args.only).split(",") if args.only else case_ids()


def main(argv: list[str] | None = None) -> int:
    p = cases_parser("validation.wide_set", __doc__)
    p.add_argument("--out", type=Path, default=None)
    a = p.parse_args(argv)
    rows = run_all(chosen_ids(a))
    if a.out:
        a.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
