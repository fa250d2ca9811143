"""``railtwin replay LOG.mcap...``: republish a log's inputs onto Zenoh in their original timing.

    railtwin replay recordings/railtwin-demo-*.mcap [--site ID] [--include-rejected]
                    [--rate X] [--connect E]... [--zenoh-config FILE] [--dry-run]

Publishes only to ``railtwin/<site>/passage`` and ``railtwin/<site>/measured`` of the
site given by ``--site`` (or of the log's site, when the log holds exactly one), and
only payloads that are valid against their model unless ``--include-rejected``; see
``service.clients.replay``. Reads cut logs (a killed twin's) too.

Also runnable as ``python -m service.cli.replay ...``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from service.cli.common import EXIT_USAGE, CommandError, SubParsers
from service.cli.inputs import check_logs, zenoh_config
from service.clients.replay import ReplayError, ReplayPlan, plan_replay, read_logs, replay
from service.recording.mcap_recover import RecoveryReport
from service.wire.zenoh_session import DEFAULT_ENDPOINT, open_session


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "logs",
        type=Path,
        nargs="+",
        metavar="LOG.mcap",
        help="MCAP log(s) of one run (rotated parts together; cut logs are read "
        "up to their last complete chunk)",
    )
    p.add_argument(
        "--site",
        default=None,
        metavar="ID",
        help="publish to this site's input keys; required when the log holds the "
        "inputs of several sites (then only that site's are replayed), "
        "otherwise the log's site",
    )
    p.add_argument(
        "--include-rejected",
        action="store_true",
        help="also send the inputs that are not valid against their model (the "
        "log's rejected inputs), so that the twin answers them with the same "
        "errors; default: only valid passages and measurements",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=1.0,
        help="time scale: 2 replays twice as fast; 0 sends without waiting (default 1)",
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"Zenoh endpoint of the twin (repeatable; default {DEFAULT_ENDPOINT})",
    )
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT")
    p.add_argument(
        "--zenoh-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="Zenoh JSON5 config (e.g. deploy/zenoh/site-publisher.json5 for TLS)",
    )
    p.add_argument(
        "--wait",
        type=float,
        default=10.0,
        help="s to wait for a subscriber before replaying (default 10)",
    )
    p.add_argument(
        "--dry-run", action="store_true", help="say what would be sent, and send nothing"
    )


def register(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Add ``replay`` to the ``railtwin`` CLI's subparsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "replay",
        help="republish the inputs of an MCAP log onto Zenoh",
        description="Republish the passages and measurements a twin received (from its MCAP "
        "log) in their original timing to one site's input keys, so that a fresh "
        "twin reproduces the logged outputs.",
    )
    add_arguments(p)
    p.set_defaults(func=run)
    return p


def describe(plan: ReplayPlan, include_rejected: bool) -> list[str]:
    """What the replay sends and leaves out, a line each."""
    logged = ", ".join(plan.logged_sites) or "none"
    lines = [
        f"site {plan.site_id} (inputs of site {logged} in the log): "
        f"{len(plan.inputs)} inputs to send: {plan.count('passage')} passages, "
        f"{plan.count('measured')} measurements"
        + (
            f", {plan.count('passage', False) + plan.count('measured', False)} rejected"
            if include_rejected
            else ""
        )
    ]
    if plan.rejected_skipped:
        lines.append(
            f"{plan.rejected_skipped} rejected inputs not sent "
            "(use --include-rejected to send them)"
        )
    if plan.truncated:
        lines.append(f"{plan.truncated} rejected inputs not sent: logged cut (too large)")
    if plan.damaged:
        lines.append(f"{plan.damaged} unreadable records of a rejected-input channel skipped")
    if plan.other_sites:
        lines.append(f"{plan.other_sites} inputs of other sites skipped")
    skipped = sum(plan.skipped_channels.values())
    if skipped:
        lines.append(
            f"{skipped} messages on {len(plan.skipped_channels)} other channels "
            "skipped (outputs are never replayed)"
        )
    unknown = plan.unknown_channels()
    if unknown:
        shown = ", ".join(f"{t!r} ({plan.skipped_channels[t]})" for t in unknown[:10])
        more = f" and {len(unknown) - 10} more" if len(unknown) > 10 else ""
        lines.append(f"warning: channels that are not the twin's skipped: {shown}{more}")
    return lines


def run(args: argparse.Namespace) -> int:
    check_logs(args.logs, journals=False)
    connect = args.connect or ([] if (args.zenoh_config or args.listen) else [DEFAULT_ENDPOINT])
    cfg = zenoh_config(listen=args.listen, connect=connect, config_file=args.zenoh_config)
    report = RecoveryReport()
    messages = read_logs(args.logs, report)
    for cut in report.damaged:
        print(f"railtwin replay: warning: {cut}; replaying what came before", file=sys.stderr)
    try:
        plan = plan_replay(messages, site_id=args.site, include_rejected=args.include_rejected)
    except ReplayError as exc:
        raise CommandError(str(exc), EXIT_USAGE) from None
    for line in describe(plan, args.include_rejected):
        print(f"railtwin replay: {line}", flush=True)
    if args.dry_run:
        return 0
    with open_session(cfg) as session:
        n = replay(session, plan, rate=args.rate, match_timeout=args.wait)
    print(
        f"railtwin replay: published {n} inputs from {len(args.logs)} file(s) to "
        f"railtwin/{plan.site_id}/passage and .../measured",
        flush=True,
    )
    return 0


def main(argv: list[str] | None = None) -> int:
    """``railtwin replay ARGV``, with its error reporting."""
    from service.cli.main import main as cli_main

    return cli_main(["replay", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
