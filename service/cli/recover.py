"""``railtwin recover``: a readable MCAP log from logs cut short by a crash.

    railtwin recover LOG.mcap [LOG.mcap ...] [RUN-inputs.journal] --out FIXED.mcap

Keeps every complete message (everything up to the last flushed chunk: the twin flushes
at least every 0.5 s), in log-time order, with its channel and JSON Schema, and
writes a finished file that ``make_reader``, Foxglove and ``railtwin replay`` read.
Give the run's ``-inputs.journal`` too: every input the twin received is in it (written
before the input was queued), so the inputs the recorder never wrote are added back.
Prints one line per damaged input saying where it was cut. Exit status: 0 written,
1 nothing could be salvaged or the output could not be written, 2 bad arguments or an
input that is not a log (nor a journal).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

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
        "recover",
        help="repair MCAP logs cut short by a crash",
        description=__doc__.split("\n\n")[0] + "\n\n" + __doc__.split("\n\n")[2],
        epilog=EXIT_CODES_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("logs", nargs="+", type=Path, metavar="LOG.mcap|RUN-inputs.journal")
    p.add_argument("--out", type=Path, required=True, help="the repaired log to write")
    p.set_defaults(func=cmd_recover)


def cmd_recover(args: argparse.Namespace) -> int:
    from service.cli.inputs import check_logs
    from service.recording.mcap_recover import recover

    check_logs(args.logs, journals=True)
    for p in args.logs:
        if p.resolve() == args.out.resolve():
            raise CommandError(f"--out {args.out} would overwrite its own input", EXIT_USAGE)
    try:
        report = recover(list(args.logs), args.out)
    except OSError as exc:
        raise CommandError(f"cannot write {args.out}: {exc}", EXIT_FAILURE) from None
    for d in report.damaged:
        print(f"railtwin recover: {d}", file=sys.stderr)
    extra = f" ({report.from_journal} only in the journal)" if report.from_journal else ""
    print(
        f"railtwin recover: {report.messages} messages from {report.files} file(s){extra} "
        f"-> {args.out}"
    )
    return EXIT_OK if report.messages else EXIT_FAILURE
