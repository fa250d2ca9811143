"""``railtwin calibrate``: a site's track values from the round wheels that passed it.

    railtwin calibrate --site SITE.toml DIR --out CALIBRATED.site.toml [--json] [-q]

DIR holds pairs NAME.json (a round wheel's WheelPassage: speed, load, mass, radius) and
NAME.csv (its crib channels: t_s then one column per crib id of the site's detector). The
command fits the track's pad stiffness and damping, sleeper mass, ballast stiffness and
damping (a slab: the pad's) to the channels, weighted by each record's noise, and says which
the wheels determine and which combinations they cannot tell apart. It prints a table
(parameter, nominal, estimate, 95 % interval, identifiable) or, with --json, the report as
JSON, and writes the site file with the estimates in its foundation and a [calibration]
table. Progress goes to stderr.
Exit status: 0 done, 1 the calibration failed, 2 invalid input (one line naming the file
and the field).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from service.cli.common import (
    EXIT_CODES_HELP,
    EXIT_FAILURE,
    EXIT_OK,
    EXIT_USAGE,
    CommandError,
    SubParsers,
)

if TYPE_CHECKING:
    from schemas.diagnosis import MeasuredPassage
    from schemas.messages import WheelPassage
    from schemas.site import SiteConfig


def register(subparsers: SubParsers) -> None:
    p = subparsers.add_parser(
        "calibrate",
        help="calibrate a site's track from round wheels' crib channels",
        description=__doc__.split("\n\n")[0] + "\n\n" + __doc__.split("\n\n")[2],
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--site", required=True, type=Path, help="site file (TOML), the nominal track")
    p.add_argument(
        "directory", type=Path, metavar="DIR", help="pairs NAME.json (WheelPassage), NAME.csv"
    )
    p.add_argument(
        "--out", required=True, type=Path, help="write the calibrated site file (TOML) here"
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON, not a table")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    p.set_defaults(func=cmd_calibrate)


def read_wheels(
    site: SiteConfig, directory: Path
) -> list[tuple[str, WheelPassage, MeasuredPassage]]:
    """The pairs in ``directory``, read and checked; ``CommandError`` (exit 2) naming the file."""
    from schemas.messages import WheelPassage
    from service.cli.inputs import load_json_file
    from service.clients.measured_io import MeasuredFileError, read_measured_csv
    from service.physics.calibration import check_wheel

    if not directory.is_dir():
        raise CommandError(f"{directory}: not a directory of NAME.json/NAME.csv pairs", EXIT_USAGE)
    try:
        files = sorted(directory.iterdir())
    except OSError as exc:
        raise CommandError(f"{directory}: cannot list: {exc}", EXIT_USAGE) from None
    jsons = [f for f in files if f.suffix == ".json"]
    csvs = {f.stem: f for f in files if f.suffix == ".csv"}
    for stem, lone in csvs.items():
        if not (directory / f"{stem}.json").exists():
            raise CommandError(f"{lone}: no {stem}.json (its WheelPassage) beside it", EXIT_USAGE)
    if not jsons:
        raise CommandError(f"{directory}: no NAME.json/NAME.csv pairs", EXIT_USAGE)
    wheels = []
    for j in jsons:
        csv = csvs.get(j.stem)
        if csv is None:
            raise CommandError(f"{j}: no {j.stem}.csv (its channels) beside it", EXIT_USAGE)
        passage = load_json_file(j, "passage", WheelPassage)
        try:
            measured = read_measured_csv(
                csv, passage.passage_id, sample_rate=site.diagnosis.sample_rate
            )
        except MeasuredFileError as exc:
            raise CommandError(str(exc), EXIT_USAGE) from None
        problem = check_wheel(site, passage, measured)
        if problem is not None:
            where = j if problem.startswith("outline") else csv
            raise CommandError(f"{where}: {problem}", EXIT_USAGE)
        wheels.append((j.stem, passage, measured))
    return wheels


def cmd_calibrate(args: argparse.Namespace) -> int:
    from service.cli.common import write_atomic
    from service.cli.inputs import load_site_file
    from service.physics.calibration import (
        CalibrationInputError,
        calibrated_site,
        check_site,
        estimate,
        report,
        table,
    )
    from service.wire.site_writer import dumps_site

    site = load_site_file(args.site)
    try:
        check_site(site)
    except CalibrationInputError as exc:
        raise CommandError(f"{args.site}: {exc}", EXIT_USAGE) from None
    if args.out.exists() and args.out.is_dir():
        raise CommandError(f"--out {args.out}: is a directory", EXIT_USAGE)
    wheels = read_wheels(site, args.directory)
    if not args.quiet:
        print(
            f"railtwin calibrate: {len(wheels)} wheels at {site.site_id}, fitting "
            f"{site.foundation.kind} track values ...",
            file=sys.stderr,
            flush=True,
        )
    start = time.perf_counter()
    quiet = args.quiet

    def progress(what: str, done: int, total: int) -> None:
        if not quiet and done == total:
            print(
                f"railtwin calibrate: {what}: {total} wheels simulated, "
                f"{time.perf_counter() - start:.0f} s",
                file=sys.stderr,
                flush=True,
            )

    try:
        est = estimate(site, wheels, progress)
    except CalibrationInputError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    except (ValueError, ArithmeticError, RuntimeError) as exc:
        raise CommandError(f"the calibration failed: {exc}", EXIT_FAILURE) from None
    wall = time.perf_counter() - start
    new = calibrated_site(site, est)
    header = (
        f"{new.site_id}: calibrated by railtwin calibrate from {len(wheels)} round wheels in "
        f"{args.directory}\n(nominal: {args.site}; see [calibration])"
    )
    try:
        write_atomic(args.out, dumps_site(new, header))
    except OSError as exc:
        raise CommandError(f"cannot write {args.out}: {exc}", EXIT_FAILURE) from None
    if args.json:
        sys.stdout.write(json.dumps(report(est, site, wall), indent=2) + "\n")
    else:
        sys.stdout.write(table(est, wall))
    return EXIT_OK
