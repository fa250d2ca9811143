"""``railtwin feed``, ``railtwin feed-measured`` and ``railtwin synthesize``: the clients
(``service.clients``) as subcommands. Each client module has ``add_arguments(parser)`` and
``run(args) -> exit code`` (and a ``main`` for ``python -m``); here each command reads and
checks its files and flags first (``service.cli.inputs``: one line and exit 2 for bad
input), then hands what they hold to the client."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

from schemas.diagnosis import MeasuredPassage
from schemas.messages import TrainFile, WheelPassage
from service.cli.common import EXIT_FAILURE, EXIT_USAGE, CommandError, SubParsers
from service.cli.inputs import load_json_file, load_site_file, zenoh_config
from service.clients import feeder, measured_feeder, synthesize
from service.clients.measured_io import MeasuredFileError
from service.physics.measurement_error import MeasurementError
from service.wire.zenoh_session import DEFAULT_ENDPOINT


def _register(
    subparsers: SubParsers,
    name: str,
    summary: str,
    module: ModuleType,
    handler: Callable[[argparse.Namespace], int],
) -> argparse.ArgumentParser:
    description = module.__doc__.split("\n")[0] if module.__doc__ else summary
    p: argparse.ArgumentParser = subparsers.add_parser(name, help=summary, description=description)
    module.add_arguments(p)
    p.set_defaults(func=handler)
    return p


def _need(ok: bool, flag: str, value: object, what: str) -> None:
    """CommandError (exit 2) naming ``flag`` unless ``ok``."""
    if not ok:
        raise CommandError(f"{flag} {value}: must be {what}", EXIT_USAGE)


def _not_written(exc: OSError, out: Path | None) -> None:
    """CommandError (exit 1) if ``exc`` is the failure to write ``out``."""
    if out is not None and exc.filename == str(out):
        raise CommandError(f"cannot write {out}: {exc.strerror or exc}", EXIT_FAILURE) from None


def cmd_feed(args: argparse.Namespace) -> int:
    _need(args.timeout > 0, "--timeout", args.timeout, "> 0 s")
    train = load_json_file(args.train, "train", TrainFile)
    cfg = zenoh_config(connect=feeder.endpoints(args), config_file=args.zenoh_config)
    return feeder.feed(args, train, cfg)


def cmd_feed_measured(args: argparse.Namespace) -> int:
    _need(args.timeout > 0, "--timeout", args.timeout, "> 0 s")
    site = load_site_file(args.site_file)
    train = load_json_file(args.train, "train", TrainFile)
    saved = None
    if args.load is not None and args.measured:
        raise CommandError("--load and --measured: give one or the other", EXIT_USAGE)
    if args.load is not None:
        saved = load_json_file(args.load, "measurements", list[MeasuredPassage])
    elif args.measured:
        try:
            saved = measured_feeder.read_measured_files(args.measured, site)
        except MeasuredFileError as exc:
            raise CommandError(str(exc), EXIT_USAGE) from None
    else:
        axles = {w.passage.axle_index for w in train.wheels}
        missing = " ".join(str(a) for a in args.axles if a not in axles)
        where = (
            f"axles of train {train.train_id} ({min(axles, default=0)}..{max(axles, default=0)})"
        )
        _need(not missing, "--axles", missing, where)
    if saved is not None:  # crib channels that are not the site's: refused before publishing
        problem = measured_feeder.measurements_problem(saved, site)
        if problem is not None:
            source = args.load if args.load is not None else "--measured"
            raise CommandError(f"invalid measurement in {source}: {problem}", EXIT_USAGE)
    cfg = zenoh_config(connect=args.connect or [DEFAULT_ENDPOINT])
    try:
        return measured_feeder.feed_measured(args, site, train, saved, cfg)
    except MeasurementError as exc:  # the site is not one the measurements can be made for
        raise CommandError(f"invalid site {args.site_file}: {exc}", EXIT_USAGE) from None
    except OSError as exc:
        _not_written(exc, args.save)
        raise


def cmd_synthesize(args: argparse.Namespace) -> int:
    site = load_site_file(args.site)
    passage = load_json_file(args.passage, "passage", WheelPassage)
    if args.flat is not None:
        diameter = 2.0 * passage.radius
        _need(0 < args.length < diameter, "--length", args.length, f"in (0, {diameter:g}) m")
    for flag, value in (("--noise", args.noise), ("--roughness", args.roughness)):
        _need(value >= 0, flag, value, ">= 0")
    _need(args.damping_ratio >= 0, "--damping-ratio", args.damping_ratio, ">= 0")
    _need(args.speed_error > -1, "--speed-error", args.speed_error, "> -1")
    try:
        return synthesize.write_measurement(args, site, passage)
    except MeasurementError as exc:
        raise CommandError(f"invalid site {args.site}: {exc}", EXIT_USAGE) from None
    except OSError as exc:
        _not_written(exc, args.out)
        raise


def register_feed(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "feed",
        "stream a train's wheel passages to a running twin, print the results",
        feeder,
        cmd_feed,
    )


def register_feed_measured(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "feed-measured",
        "publish measured forces of some wheels, print the diagnoses",
        measured_feeder,
        cmd_feed_measured,
    )


def register_synthesize(subparsers: SubParsers) -> argparse.ArgumentParser:
    return _register(
        subparsers,
        "synthesize",
        "write a synthetic measured force of one passage (CSV)",
        synthesize,
        cmd_synthesize,
    )
