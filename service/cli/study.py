"""``railtwin study``: a parameter study on a Dask cluster, one Parquet row per case.

    railtwin study SPEC.toml [--workers N | --scheduler ADDR] --out TABLE.parquet [--plot]

The spec names a base scenario and the fields to vary by dotted path (a grid, random draws
with a seed, or both; examples/study.toml). Each case is simulated on an embedded cluster of
N worker processes (default: one per core) or on the cluster at --scheduler; its row holds
its parameters and the summary of its last pass (peak force, losses, max dent, ...), or its
error: a failed case does not stop the study. --plot draws the peak force against the first
numeric parameter beside the table (TABLE.png).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from service.cli.common import EXIT_CODES_HELP, EXIT_OK, EXIT_USAGE, CommandError, SubParsers
from service.cli.reanalyse import add_cluster_arguments, positive_int


def register(subparsers: SubParsers) -> None:
    doc = __doc__ or ""
    p = subparsers.add_parser(
        "study",
        help="a parameter study on a Dask cluster, one Parquet row per case",
        description=doc.split("\n\n")[0] + "\n\n" + doc.split("\n\n")[2],
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("spec", type=Path, metavar="SPEC.toml")
    add_cluster_arguments(p)
    p.add_argument("--out", type=Path, required=True, metavar="TABLE.parquet")
    p.add_argument("--plot", action="store_true", help="draw the peak force curves (TABLE.png)")
    p.add_argument("--batch", type=positive_int, metavar="N", help="cases per task")
    p.add_argument(
        "--format",
        choices=("table", "json"),
        default="table",
        help="the summary on stdout: a table for people (default) or JSON",
    )
    p.set_defaults(func=cmd_study)


def cmd_study(args: argparse.Namespace) -> int:
    import pyarrow.parquet as pq

    from service.distributed.cluster import ClusterError, open_client
    from service.distributed.study import StudyError, load_spec, plot, run_study, table_of
    from service.distributed.tasks import WarmUp

    try:
        base, cases = load_spec(args.spec)
    except StudyError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    params = sorted({k for c in cases for k in c})
    try:
        with open_client(
            workers=args.workers,
            scheduler=args.scheduler,
            timeout=args.scheduler_timeout,
            warm=WarmUp(None),
        ) as (client, info):
            print(
                f"railtwin study: {len(cases)} cases on {info.workers} worker(s)", file=sys.stderr
            )
            rows, wall, tasks = run_study(client, info, base, cases, batch=args.batch)
    except ClusterError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    table = table_of(rows, params)
    try:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, args.out)
    except OSError as exc:
        raise CommandError(f"cannot write {args.out}: {exc}") from None
    png = plot(table, params, args.out) if args.plot else None
    failed = sum(1 for r in rows if r["error"] is not None)
    summary = {
        "cases": len(rows),
        "failed": failed,
        "tasks": tasks,
        "workers": info.workers,
        "wall_time": wall,
        "out": str(args.out),
        "plot": str(png) if png else None,
    }
    if args.format == "json":
        print(json.dumps(summary))
    else:
        for r in sorted(rows, key=lambda r: r["case"]):
            what = ", ".join(f"{p}={json.dumps(r.get(p))}" for p in params)
            res = (
                f"error: {r['error']}"
                if r["error"]
                else f"peak {r['peak_force'] / 1e3:.1f} kN, {r['contact_losses']} losses"
            )
            print(f"case {r['case']:>3}  {what}  ->  {res}")
        print(
            f"{len(rows)} cases ({failed} failed) in {wall:.1f} s on {info.workers} worker(s), "
            f"{tasks} tasks -> {args.out}" + (f", {png}" if png else "")
        )
    return EXIT_OK
