"""``railtwin reanalyse``: a site's archive re-diagnosed with the current model, on a Dask
cluster.

    railtwin reanalyse LOG.mcap|DIR [...] --site SITE.toml [--workers N | --scheduler ADDR]
                       [--db FLEET_DB | --out DIR] [--batch N] [--format table|json]

Reads every passage and measured passage of the logs (files, or directories: every .mcap
below; rotated parts and recovered logs), pairs them as the twin does, and diagnoses each
pair again with this railtwin and the site file given, on an embedded cluster of N worker
processes (default: one per core) or on the cluster at --scheduler. Each diagnosis carries
its model version (railtwin's version, the track model, the site file's fingerprint) and is
stored once per (site, passage, model version) in the fleet database (--db: a SQLite file or
a postgresql:// URL, as 'fleet serve' takes) or under a directory (--out). A run stopped at
any point (even killed) and started again goes on where it was and stores nothing twice.
Progress goes to stderr (a bar on a terminal, a line every 10 s otherwise). The report says,
per verdict, how many passages changed from the verdict stored before (another model's, or
the twin's logged one) and which wheels rose to remove.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import cast

from service.cli.common import (
    EXIT_CODES_HELP,
    EXIT_OK,
    EXIT_USAGE,
    CommandError,
    SubParsers,
)


def positive_int(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"{text} must be at least 1")
    return n


def add_cluster_arguments(p: argparse.ArgumentParser) -> None:
    """--workers / --scheduler / --scheduler-timeout (reanalyse and study)."""
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=positive_int,
        metavar="N",
        help="worker processes of the embedded Dask cluster (default: one per core)",
    )
    where.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="run on the Dask cluster of this scheduler instead (docs/deployment.md)",
    )
    p.add_argument(
        "--scheduler-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds to wait for the scheduler (default 10)",
    )


def register(subparsers: SubParsers) -> None:
    doc = __doc__ or ""
    p = subparsers.add_parser(
        "reanalyse",
        help="re-diagnose a site's MCAP archive with the current model, on a Dask cluster",
        description=doc.split("\n\n")[0] + "\n\n" + doc.split("\n\n")[2],
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("logs", nargs="+", type=Path, metavar="LOG.mcap|DIR")
    p.add_argument("--site", type=Path, required=True, metavar="SITE.toml", help="site file")
    add_cluster_arguments(p)
    out = p.add_mutually_exclusive_group(required=True)
    out.add_argument(
        "--db", metavar="FLEET_DB", help="fleet database: SQLite file or postgresql:// URL"
    )
    out.add_argument("--out", type=Path, metavar="DIR", help="store under this directory")
    p.add_argument(
        "--batch",
        type=positive_int,
        metavar="N",
        help="passages per task (default: about 8 tasks per worker, at most 32)",
    )
    p.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="the report on stdout: a table for people (default) or JSON",
    )
    p.set_defaults(func=cmd_reanalyse)


def load_site(path: Path) -> object:
    from service.wire.site import SiteFileError
    from service.wire.site import load_site as load

    try:
        return load(path)
    except SiteFileError as exc:
        text = "; ".join(s.strip() for s in str(exc).splitlines() if s.strip())
        raise CommandError(text, EXIT_USAGE) from None


def cmd_reanalyse(args: argparse.Namespace) -> int:
    from schemas.site import SiteConfig
    from service.distributed.archive import ArchiveError, read_archive
    from service.distributed.cluster import ClusterError, open_client
    from service.distributed.reanalysis import DirSink, Sink, StoreSink, reanalyse
    from service.distributed.tasks import WarmUp
    from service.fleet.store import StoreError, open_store
    from service.physics.model_version import model_version

    site = load_site(args.site)
    assert isinstance(site, SiteConfig)
    if site.foundation.kind not in ("rigid", "compliant") and site.detector is None:
        raise CommandError(
            f"{args.site}: the site's foundation is {site.foundation.kind!r} with no "
            "detector: the diagnosis fits a contact force on a rigid or compliant (one-mass) "
            "foundation, or a detector's crib channels on a rail on supports (e.g. "
            "examples/site.toml)",
            EXIT_USAGE,
        )
    try:
        archive = read_archive(args.logs, site.site_id, site.diagnosis.pairing_timeout)
    except ArchiveError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    version = model_version(site)
    sink: Sink
    if args.db is not None:
        try:
            sink = StoreSink(open_store(args.db), site.site_id, version.key)
        except StoreError as exc:
            raise CommandError(str(exc), EXIT_USAGE) from None
    else:
        try:
            sink = DirSink(args.out, site.site_id, version.key)
        except OSError as exc:
            raise CommandError(f"cannot write {args.out}: {exc.strerror or exc}") from None
    try:
        try:
            with open_client(
                workers=args.workers,
                scheduler=args.scheduler,
                timeout=args.scheduler_timeout,
                warm=WarmUp(site.model_dump_json()),
            ) as (client, info):
                print(
                    f"railtwin reanalyse: {len(archive.pairs)} measured passages of site "
                    f"{site.site_id} in {len(archive.files)} log(s); {info.workers} worker(s) "
                    f"at {info.address}; model {version.key}",
                    file=sys.stderr,
                )
                report = reanalyse(client, info, archive, site, version, sink, batch=args.batch)
        except ClusterError as exc:
            raise CommandError(str(exc), EXIT_USAGE) from None
    finally:
        sink.close()
    if args.format == "json":
        print(json.dumps(report.json(), indent=2))
    else:
        print(report.table())
    return EXIT_OK


def standalone(argv: list[str] | None = None) -> int:
    """``python -m service.cli.reanalyse ARGS``: the subcommand alone (as ``main`` runs it)."""
    from service.cli.main import _Parser, _report

    parser = _Parser(prog="railtwin")
    sub = cast(SubParsers, parser.add_subparsers(dest="command"))
    register(sub)
    args = parser.parse_args(["reanalyse", *(sys.argv[1:] if argv is None else argv)])
    try:
        code: int = args.func(args)
    except CommandError as exc:
        _report(exc, args)
        return exc.code
    except KeyboardInterrupt:
        return 130
    return code


if __name__ == "__main__":
    sys.exit(standalone())
