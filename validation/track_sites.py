"""The detector sites (``track-sites``, an independent solver's records) through ``railtwin calibrate``.

The handed-over set (its README: free to copy) holds per site a railtwin site file with the
NOMINAL track (``railtwin/Sxx.site.toml``), and per passage a JSON of passage facts (not a
WheelPassage) with the truth inline, and the channels' CSV. ``wheel_passage`` makes the
WheelPassage a site knows of a passage (speed V, load P, mass m, radius R; a round outline);
``convert`` writes a directory of NAME.json/NAME.csv pairs as ``railtwin calibrate`` reads.

Run (the data directory is an argument: nothing in the repository reads it otherwise):

    python -m validation.track_sites DATA_DIR [--sites S01 S02] [--out FILE.md]

calibrates each site from its 12 calibration wheels and reports per site each estimate over
the truth with its interval, the identifiability, each wheel's residual rms over its true
noise σ on the nominal and on the calibrated track, and the wall time.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path
from typing import Any

from schemas.messages import WheelPassage

TRUE_KEYS = {
    "pad.stiffness": "k_p",
    "pad.damping": "c_p",
    "sleeper_mass": "m_s",
    "ballast.stiffness": "k_b",
    "ballast.damping": "c_b",
}
"""The site file's names of the track values → the data set's."""


def wheel_passage(doc: dict[str, Any]) -> WheelPassage:
    """What the site knows of a passage of the data set, as a ``WheelPassage``."""
    number = int(str(doc["id"]).rsplit("P", 1)[-1])
    return WheelPassage.model_validate(
        {
            "passage_id": doc["id"],
            "train_id": doc["site"],
            "axle_index": number,
            "side": "right",
            "timestamp": 0.0,
            "speed": doc["V"],
            "load": doc["P"],
            "mass": doc["m"],
            "radius": doc["R"],
            "outline": {"kind": "round"},
        }
    )


def convert(
    data: Path, site_id: str, out: Path, role: str = "calibration", only: list[str] | None = None
) -> list[str]:
    """Write NAME.json (WheelPassage) and NAME.csv (the channels) of the site's passages of
    ``role`` (or the ids ``only``) into ``out``; their names."""
    out.mkdir(parents=True, exist_ok=True)
    names = []
    for path in sorted(data.glob(f"{site_id}_P*.json")):
        doc = json.loads(path.read_text(encoding="utf-8"))
        if (only is not None and doc["id"] not in only) or (only is None and doc["role"] != role):
            continue
        (out / f"{doc['id']}.json").write_text(
            wheel_passage(doc).model_dump_json(indent=2) + "\n", encoding="utf-8"
        )
        shutil.copyfile(data / f"{doc['id']}.csv", out / f"{doc['id']}.csv")
        names.append(doc["id"])
    return names


def run_site(data: Path, site_id: str, work: Path) -> dict[str, Any]:
    """Calibrate ``site_id`` from its calibration wheels; the numbers against the truth."""
    from service.cli.calibrate import read_wheels
    from service.physics.calibration import estimate
    from service.wire.site import load_site

    site = load_site(data / "railtwin" / f"{site_id}.site.toml")
    names = convert(data, site_id, work / site_id)
    wheels = read_wheels(site, work / site_id)
    start = time.perf_counter()
    est = estimate(site, wheels)
    wall = time.perf_counter() - start
    truth = [json.loads((data / f"{n}.json").read_text(encoding="utf-8")) for n in names]
    true_track = truth[0]["truth"]["track_true"]
    rows = []
    for i, name in enumerate(est.names):
        tv = float(true_track[TRUE_KEYS[name]])
        lo, hi = est.interval(i)
        rows.append(
            {
                "name": name,
                "nominal_over_true": est.nominal[i] / tv,
                "estimate_over_true": est.estimate[i] / tv,
                "low_over_true": lo / tv,
                "high_over_true": hi / tv,
                "covers": lo <= tv <= hi,
                "identifiable": est.identifiability.identifiable[i],
            }
        )
    wheels_rows = []
    for k, doc in enumerate(truth):
        s = float(doc["noise_sigma_N"])
        wheels_rows.append(
            {
                "name": doc["id"],
                "speed_kmh": doc["V_kmh"],
                "sigma_estimated_over_true": est.sigma[k] / s,
                "nominal": est.rms_nominal[k] * est.sigma[k] / s,
                "calibrated": est.rms_calibrated[k] * est.sigma[k] / s,
            }
        )
    return {
        "site": site_id,
        "kind": site.foundation.kind,
        "wall_time": wall,
        "steps": est.steps,
        "parameters": rows,
        "cannot_tell_apart": [c.label(est.names) for c in est.identifiability.weak],
        "wheels": wheels_rows,
    }


def markdown(results: list[dict[str, Any]]) -> str:
    """The results as the tables of docs/calibration.md."""
    out = [
        "| site | parameter | nominal/true | estimate/true | 95 % interval/true | covers | identifiable |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in results:
        for p in r["parameters"]:
            out.append(
                f"| {r['site']} | {p['name']} | {p['nominal_over_true']:.3f} | "
                f"{p['estimate_over_true']:.3f} | [{p['low_over_true']:.3f}, "
                f"{p['high_over_true']:.3f}] | {'yes' if p['covers'] else 'no'} | "
                f"{p['identifiable']} |"
            )
    out += [
        "",
        "| site | kind | wall s | cannot tell apart | residual/σ nominal (max) | calibrated (max) |",
        "|---|---|---|---|---|---|",
    ]
    for r in results:
        nom = max(w["nominal"] for w in r["wheels"])
        cal = max(w["calibrated"] for w in r["wheels"])
        weak = ", ".join(r["cannot_tell_apart"]) or "—"
        out.append(
            f"| {r['site']} | {r['kind']} | {r['wall_time']:.1f} | {weak} | {nom:.3f} | {cal:.3f} |"
        )
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.track_sites", description=__doc__)
    p.add_argument("data", type=Path, help="the track-sites directory")
    p.add_argument("--sites", nargs="+", default=["S01", "S02", "S03", "S04"])
    p.add_argument("--work", type=Path, default=Path("validation/out/track_sites"))
    p.add_argument("--out", type=Path, default=None, help="write the markdown tables here")
    p.add_argument("--json", type=Path, default=None, help="write the full results here")
    args = p.parse_args(argv)
    results = []
    for s in args.sites:
        r = run_site(args.data, s, args.work)
        print(json.dumps(r), flush=True)
        results.append(r)
    text = markdown(results)
    sys.stdout.write(text)
    if args.out is not None:
        args.out.write_text(text, encoding="utf-8")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
