"""``railtwin diagnose``: a measured passage in, the twin's verdict on its wheel out.

    railtwin diagnose --site SITE.toml --passage PASSAGE.json --measured MEASURED.csv
                      [--out DIAGNOSIS.json] [--format table|json]

The passage is a ``WheelPassage`` JSON file (speed, load, mass, radius; its outline is
ignored: finding the flat is the point); the measurement a CSV (``t_s,force_N``, or
``t_s`` then one column per crib id of the site's detector) or a railtwin MCAP log holding
the passage's ``MeasuredPassage``. Prints a short table (or the Diagnosis JSON with
``--format json``) and writes the Diagnosis JSON to ``--out``. A contact force is fitted at a
rigid or compliant site; crib channels, checked against the site's cribs, at a site whose
rail lies on discrete supports or slab (the twin simulates the cribs through the site's
chain). The Diagnosis names the calibration of the track it used.
Exit status: 0 done (whatever the verdict), 1 the fit failed, 2 invalid input.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from schemas.diagnosis import Diagnosis
from service.cli.common import (
    EXIT_CODES_HELP,
    EXIT_FAILURE,
    EXIT_OK,
    EXIT_USAGE,
    CommandError,
    SubParsers,
)


def register(subparsers: SubParsers) -> None:
    p = subparsers.add_parser(
        "diagnose",
        help="diagnose a wheel flat from a measured passage",
        description=__doc__.split("\n\n")[0] + "\n\n" + __doc__.split("\n\n")[2],
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--site", required=True, type=Path, help="site file (TOML)")
    p.add_argument("--passage", required=True, type=Path, help="WheelPassage JSON file")
    p.add_argument(
        "--measured",
        required=True,
        type=Path,
        help="measured force: CSV (t_s,force_N, or t_s,<crib id>,... channels) or railtwin .mcap",
    )
    p.add_argument("--out", type=Path, default=None, help="write the Diagnosis JSON here")
    p.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="stdout: a table for people (default) or the JSON",
    )
    p.set_defaults(func=cmd_diagnose)


def table(d: Diagnosis) -> str:
    kn = 1e-3
    rows: list[tuple[str, str]] = [("verdict", d.verdict)]
    if d.flat is None:
        rows.append(("flat", "none found"))
    else:
        f = d.flat
        rows += [
            (
                "flat",
                f"{f.kind}, {f.length * 1e3:.1f} mm "
                f"[{f.length_low * 1e3:.1f}, {f.length_high * 1e3:.1f}] mm",
            ),
            (
                "depth",
                f"{f.depth * 1e3:.3f} mm"
                + (
                    ""
                    if f.depth_factor is None or f.kind == "flat"
                    else f" ({f.depth_factor:.2f} x l²/16R)"
                ),
            ),
            ("phase", f"{f.phase:.3f} rad"),
        ]
    rows += [
        (
            "peak channel measured" if d.measured == "channels" else "peak force measured",
            f"{d.peak_force_measured * kn:.1f} kN",
        ),
        ("peak force of the fit", f"{d.peak_force_fit * kn:.1f} kN"),
        ("fit rms", f"{d.fit_rms * kn:.1f} kN"),
        (
            "peak at line speed",
            "—"
            if d.peak_force_at_line_speed is None
            else f"{d.peak_force_at_line_speed * kn:.1f} kN"
            + (
                ""
                if d.peak_force_at_line_speed_low is None or d.peak_force_at_line_speed_high is None
                else f" [{d.peak_force_at_line_speed_low * kn:.0f}, "
                f"{d.peak_force_at_line_speed_high * kn:.0f}] kN"
            ),
        ),
        *(
            [
                (
                    "detector peak at line speed",
                    f"{d.peak_channel_at_line_speed * kn:.1f} kN"
                    + (
                        ""
                        if d.peak_channel_at_line_speed_low is None
                        or d.peak_channel_at_line_speed_high is None
                        else f" [{d.peak_channel_at_line_speed_low * kn:.0f}, "
                        f"{d.peak_channel_at_line_speed_high * kn:.0f}] kN"
                    ),
                )
            ]
            if d.peak_channel_at_line_speed is not None
            else []
        ),
        (
            "explained",
            "—"
            if d.explained is None
            else f"{'yes' if d.explained else 'NO'} (residual {d.fit_residual_ratio or 0:.1f} x the "
            f"record's noise {(d.noise_level or 0) * kn:.2f} kN)",
        ),
        (
            "calibration",
            "—" if d.calibration is None else f"{d.calibration.source} {d.calibration.id}",
        ),
        ("wall time", f"{d.wall_time:.2f} s"),
    ]
    w = max(len(k) for k, _ in rows)
    lines = [f"{k:<{w}}  {v}" for k, v in rows]
    lines += [f"{'reason':<{w}}  {r}" for r in d.reasons]
    return "\n".join(lines) + "\n"


def _cores() -> int:
    """The cores this process may use, at most 2 (the fit's two kinds)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(2, cores))


def cmd_diagnose(args: argparse.Namespace) -> int:
    from schemas.messages import WheelPassage
    from service.cli.common import write_atomic
    from service.cli.inputs import load_json_file, load_site_file
    from service.clients.measured_io import MeasuredFileError, read_measured
    from service.physics.diagnosis import Diagnoser, IntegrationError, MeasurementError
    from service.wire.measured_channels import CHANNELS_FIELD, channels_problem

    site = load_site_file(args.site)
    passage = load_json_file(args.passage, "passage", WheelPassage)
    try:
        measured = read_measured(
            args.measured, passage.passage_id, sample_rate=site.diagnosis.sample_rate
        )
    except MeasuredFileError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    problem = channels_problem(measured, site)
    if problem is not None:  # refused before any physics is built
        raise CommandError(
            f"invalid measurement {args.measured}: {CHANNELS_FIELD}: {problem}", EXIT_USAGE
        )
    print(
        f"railtwin diagnose: fitting {measured.samples} samples of {passage.passage_id} ...",
        file=sys.stderr,
        flush=True,
    )
    try:
        diagnosis, _ = Diagnoser(site, cores=_cores()).diagnose(passage, measured)
    except MeasurementError as exc:
        raise CommandError(f"invalid measurement {args.measured}: {exc}", EXIT_USAGE) from None
    except (ValueError, ArithmeticError, IntegrationError) as exc:
        raise CommandError(f"the fit failed: {exc}", EXIT_FAILURE) from None
    text = diagnosis.model_dump_json(indent=2)
    if args.out is not None:
        write_atomic(args.out, text + "\n")
    sys.stdout.write(text + "\n" if args.format == "json" else table(diagnosis))
    return EXIT_OK
