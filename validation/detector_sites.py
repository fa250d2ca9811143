"""Validation of the diagnosis from crib channels on the detector sites (``make validate``).

``validation/track-sites/``: the 32 test passages (8 per site: round wheels, fresh and worn
flats) of the handed-over ``track-sites`` set (an independent solver's records; README
there), each site's railtwin site file with the NOMINAL track, and the line-speed truth.
Each passage goes through the path of ``railtwin diagnose``: its ``WheelPassage`` and its
channel CSV read by ``read_measured``, ``Diagnoser.diagnose`` on one core.

    .venv/bin/python -m validation.detector_sites [--calibrate | --calibrated DIR]
        [--out validation/detector_sites_results.json] [--md validation/detector_sites_results.md]

``--calibrate`` (what ``make validate`` runs): first calibrate each site with ``railtwin
calibrate`` from its 12 round calibration wheels (P01-P12, copied beside the test passages),
then also diagnose with those calibrated site files, to show what the calibration buys;
``--calibrated DIR`` takes calibrated site files ``DIR/Sxx.site.toml`` made elsewhere. Prints
the table of the issue's targets per site file set (also to ``--md``), and writes every case
to ``--out``.
"""

from __future__ import annotations

import argparse
import gzip
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from schemas.messages import WheelPassage
from service.clients.measured_io import read_measured
from service.physics.diagnosis import Diagnoser
from service.wire.site import load_site

DATA = Path(__file__).parent / "track-sites"
SITES = ("S01", "S02", "S03", "S04")
REMOVE_LENGTH = 0.06
REMOVE_FORCE = 400e3


def wheel_passage(doc: dict[str, Any]) -> WheelPassage:
    """What the site knows of a passage (speed V, load P, mass m, radius R)."""
    return WheelPassage(
        passage_id=doc["id"],
        train_id=doc["site"],
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=doc["V"],
        load=doc["P"],
        mass=doc["m"],
        radius=doc["R"],
    )


def run_site(site_file: Path, site_id: str, scratch: Path) -> list[dict[str, Any]]:
    """Diagnose the site's 8 test passages; one row each (truth, answer, times)."""
    site = load_site(site_file)
    diagnoser = Diagnoser(site)
    diagnoser.warm_up()  # the track's reductions, as a served twin does before its first wheel
    line_truth = json.loads((DATA / "line_speed_truth.json").read_text())["passages"]
    rows = []
    for k in range(13, 21):
        pid = f"{site_id}_P{k:02d}"
        doc = json.loads((DATA / f"{pid}.json").read_text())
        csv = scratch / f"{pid}.csv"
        csv.write_bytes(gzip.decompress((DATA / f"{pid}.csv.gz").read_bytes()))
        passage = wheel_passage(doc)
        measured = read_measured(csv, pid, sample_rate=site.diagnosis.sample_rate)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        diag, _ = diagnoser.diagnose(passage, measured)
        cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
        truth = doc["truth"]
        line = line_truth.get(pid)
        f = diag.flat
        rows.append(
            {
                "case": pid,
                "kind": truth["kind"] or "round",
                "true_length": truth["flat_length_m"] or 0.0,
                "true_peak": truth["true_F_max_in_record"],
                "speed_kmh": doc["V_kmh"],
                "found_kind": f.kind if f else None,
                "found_length": f.length if f else 0.0,
                "length_low": f.length_low if f else None,
                "length_high": f.length_high if f else None,
                "verdict": diag.verdict,
                "explained": diag.explained,
                "residual_ratio": diag.fit_residual_ratio,
                "peak_fit": diag.peak_force_fit,
                "line_contact_truth": line["peak_contact"] if line else None,
                "line_channel_truth": line["peak_measured"] if line else None,
                "line_contact": diag.peak_force_at_line_speed,
                "line_contact_low": diag.peak_force_at_line_speed_low,
                "line_contact_high": diag.peak_force_at_line_speed_high,
                "line_channel": diag.peak_channel_at_line_speed,
                "line_channel_low": diag.peak_channel_at_line_speed_low,
                "line_channel_high": diag.peak_channel_at_line_speed_high,
                "calibration": diag.calibration.label if diag.calibration else None,
                "cpu_time": cpu,
                "wall_time": wall,
            }
        )
        print(
            f"  {pid} {rows[-1]['kind']:12s} {rows[-1]['true_length'] * 1e3:5.1f} mm -> "
            f"{f.kind if f else 'round':12s} {rows[-1]['found_length'] * 1e3:5.1f} mm "
            f"{diag.verdict:7s} cpu {cpu:.2f} s",
            file=sys.stderr,
            flush=True,
        )
    return rows


def within(r: dict[str, Any]) -> bool:
    tl = float(r["true_length"])
    return abs(float(r["found_length"]) - tl) <= max(0.005, 0.1 * tl)


def covered(r: dict[str, Any]) -> bool:
    lo, hi = r["length_low"], r["length_high"]
    return lo is not None and float(lo) <= float(r["true_length"]) <= float(hi)


def _near(r: dict[str, Any], what: str) -> bool | None:
    truth, got = r[f"line_{what}_truth"], r[f"line_{what}"]
    if truth is None or got is None:
        return None
    return abs(got / truth - 1.0) <= 0.2


def _band(r: dict[str, Any], what: str) -> bool | None:
    truth, lo, hi = r[f"line_{what}_truth"], r[f"line_{what}_low"], r[f"line_{what}_high"]
    if truth is None or lo is None or hi is None:
        return None
    return bool(lo <= truth <= hi)


def _frac(xs: list[bool | None]) -> str:
    v = [x for x in xs if x is not None]
    return f"{sum(v)}/{len(v)}" if v else "-"


def summary(rows: list[dict[str, Any]]) -> dict[str, str]:
    """The issue's measures over ``rows``, each as text for the table."""
    flats = [r for r in rows if r["kind"] != "round"]
    rounds = [r for r in rows if r["kind"] == "round"]
    due = [
        r
        for r in flats
        if r["true_length"] >= REMOVE_LENGTH
        or r["true_peak"] >= REMOVE_FORCE
        or (r["line_contact_truth"] or 0.0) >= REMOVE_FORCE
    ]
    missed = [r["case"] for r in due if r["verdict"] != "remove"]
    cpu_f = np.array([r["cpu_time"] for r in flats] or [0.0])
    cpu_r = np.array([r["cpu_time"] for r in rounds] or [0.0])
    return {
        "length within max(5 mm, 10 %)": _frac([within(r) for r in flats]),
        "kind right": _frac([r["found_kind"] == r["kind"] for r in flats]),
        "interval covers": _frac([covered(r) for r in flats]),
        "flat reported on a round wheel": f"{sum(r['found_kind'] is not None for r in rounds)}"
        f"/{len(rounds)}",
        "`remove` missed (of due)": f"{len(missed)}/{len(due)}"
        + (f" ({', '.join(missed)})" if missed else ""),
        "forecast ±20 %: contact peak": _frac([_near(r, "contact") for r in flats]),
        "band covers: contact peak": _frac([_band(r, "contact") for r in flats]),
        "forecast ±20 %: detector peak": _frac([_near(r, "channel") for r in flats]),
        "band covers: detector peak": _frac([_band(r, "channel") for r in flats]),
        "explained (flats / round)": f"{sum(bool(r['explained']) for r in flats)}/{len(flats)}"
        f" / {sum(bool(r['explained']) for r in rounds)}/{len(rounds)}",
        "CPU per flat wheel, median / worst": f"{np.median(cpu_f):.2f} / {cpu_f.max():.2f} s",
        "CPU per round wheel, median / worst": f"{np.median(cpu_r) * 1e3:.0f} / "
        f"{cpu_r.max() * 1e3:.0f} ms",
    }


TARGETS = {
    "length within max(5 mm, 10 %)": ">= 90 %",
    "kind right": ">= 90 %",
    "interval covers": ">= 90 %",
    "flat reported on a round wheel": "0",
    "`remove` missed (of due)": "0",
    "forecast ±20 %: contact peak": ">= 80 %",
    "band covers: contact peak": ">= 90 %",
    "forecast ±20 %: detector peak": ">= 80 %",
    "band covers: detector peak": ">= 90 %",
    "explained (flats / round)": "",
    "CPU per flat wheel, median / worst": "<= 2 s",
    "CPU per round wheel, median / worst": "<= 50 ms",
}


def table(sets: dict[str, list[dict[str, Any]]]) -> str:
    """Markdown: one column per site-file set (nominal, calibrated), the target last."""
    sums = {name: summary(rows) for name, rows in sets.items()}
    head = "| measure | " + " | ".join(sets) + " | target |"
    out = [head, "|---" * (len(sets) + 2) + "|"]
    for key, target in TARGETS.items():
        out.append(f"| {key} | " + " | ".join(s[key] for s in sums.values()) + f" | {target} |")
    for name, rows in sets.items():
        misses = [r["case"] for r in rows if r["kind"] != "round" and not within(r)]
        out.append("")
        out.append(f"- {name}: length misses {', '.join(misses) or 'none'}")
    return "\n".join(out)


CALIBRATION_WHEELS = tuple(f"P{i:02d}" for i in range(1, 13))


def calibrate_site(site_id: str, scratch: Path) -> tuple[Path, dict[str, Any]]:
    """``railtwin calibrate`` on the site's 12 round wheels, as a user runs it: the pairs
    NAME.json (WheelPassage) and NAME.csv written to a directory, the command in a child
    process. Returns the calibrated site file and the command's JSON report (with its wall
    and CPU seconds)."""
    wheels = scratch / "wheels" / site_id
    wheels.mkdir(parents=True, exist_ok=True)
    for p in CALIBRATION_WHEELS:
        doc = json.loads((DATA / f"{site_id}_{p}.json").read_text())
        (wheels / f"{site_id}_{p}.json").write_text(wheel_passage(doc).model_dump_json())
        with gzip.open(DATA / f"{site_id}_{p}.csv.gz", "rb") as f:
            (wheels / f"{site_id}_{p}.csv").write_bytes(f.read())
    out = scratch / "calibrated" / f"{site_id}.site.toml"
    out.parent.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, "-m", "service.cli", "calibrate", "--site"]
    cmd += [str(DATA / f"{site_id}.site.toml"), str(wheels), "--out", str(out), "--json", "-q"]
    t0 = time.perf_counter()
    before = _children_cpu()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        raise SystemExit(f"railtwin calibrate failed on {site_id}: {done.stderr.strip()}")
    report: dict[str, Any] = json.loads(done.stdout)
    report["validation_wall_s"] = time.perf_counter() - t0
    report["validation_cpu_s"] = _children_cpu() - before
    return out, report


TRUTH_KEYS = {
    "pad.stiffness": "k_p",
    "pad.damping": "c_p",
    "sleeper_mass": "m_s",
    "ballast.stiffness": "k_b",
    "ballast.damping": "c_b",
}
"""The calibrated parameters' names in the data set's ``truth.track_true``."""


def calibration_table(reports: dict[str, dict[str, Any]]) -> str:
    """Markdown: each site's estimates against the data set's true track, with the command's
    time and how well the calibrated channels explain the wheels."""
    out = [
        "### `railtwin calibrate` from each site's 12 round wheels, against the true track",
        "",
        "| site | parameter | nominal / truth | estimate / truth | 95 % interval / truth "
        "| covers | identifiable |",
        "|---|---|---|---|---|---|---|",
    ]
    covers = 0
    counted = 0
    for site_id, rep in reports.items():
        true = json.loads((DATA / f"{site_id}_P13.json").read_text())["truth"]["track_true"]
        for prm in rep["parameters"]:
            t = float(true[TRUTH_KEYS[prm["name"]]])
            inside = prm["low"] <= t <= prm["high"]
            if prm["identifiable"] != "no":
                counted += 1
                covers += inside
            out.append(
                f"| {site_id} | {prm['name']} | {prm['nominal'] / t:.3f} | "
                f"{prm['estimate'] / t:.3f} | [{prm['low'] / t:.3f}, {prm['high'] / t:.3f}] | "
                f"{'yes' if inside else 'no'} | {prm['identifiable']} |"
            )
    out.append("")
    out.append(
        f"Intervals covering the truth, parameters the wheels determine (`yes`/`partly`): "
        f"{covers}/{counted}. Parameters marked `no` are held at the nominal with the prior's "
        "interval."
    )
    out.append("")
    out.append(
        "| site | CPU (s) | wall (s) | residual rms / noise, worst wheel: nominal → calibrated |"
    )
    out.append("|---|---|---|---|")
    for site_id, rep in reports.items():
        nom = max(p["rms_over_sigma_nominal"] for p in rep["passages"])
        cal = max(p["rms_over_sigma_calibrated"] for p in rep["passages"])
        out.append(
            f"| {site_id} | {rep['validation_cpu_s']:.1f} | {rep['validation_wall_s']:.1f} | "
            f"{nom:.2f} → {cal:.2f} |"
        )
    return "\n".join(out)


def _children_cpu() -> float:
    t = os.times()
    return float(t.children_user + t.children_system)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--calibrate",
        action="store_true",
        help="calibrate each site from its 12 round wheels first, and diagnose with those files too",
    )
    ap.add_argument("--calibrated", type=Path, default=None, help="calibrated site files")
    ap.add_argument("--sites", nargs="+", default=list(SITES))
    ap.add_argument("--out", type=Path, default=Path("validation/detector_sites_results.json"))
    ap.add_argument("--md", type=Path, default=Path("validation/detector_sites_results.md"))
    args = ap.parse_args(argv)
    sets: dict[str, list[dict[str, Any]]] = {}
    calibrations: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        scratch = Path(tmp)
        calibrated = args.calibrated
        if args.calibrate:
            for s in args.sites:
                print(f"railtwin calibrate {s} (12 round wheels) ...", file=sys.stderr, flush=True)
                site_file, calibrations[s] = calibrate_site(s, scratch)
            calibrated = site_file.parent
        for name, folder in (("nominal", DATA), ("calibrated", calibrated)):
            if folder is None:
                continue
            print(f"{name} site files ({folder}):", file=sys.stderr)
            rows: list[dict[str, Any]] = []
            for s in args.sites:
                rows += run_site(folder / f"{s}.site.toml", s, scratch)
            sets[name] = rows
    args.out.write_text(json.dumps(sets | {"calibrations": calibrations}, indent=1) + "\n")
    text = "## Detector sites (track-sites): the diagnosis from crib channels\n\n" + table(sets)
    if calibrations:
        text += "\n\n" + calibration_table(calibrations)
    args.md.write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
