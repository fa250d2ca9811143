"""``railtwin replay LOG.mcap...``: republish a log's inputs onto Zenoh in their original timing.

    railtwin replay recordings/railtwin-demo-*.mcap [--rate X] [--connect E]... [--site ID]

Also runnable as ``python -m service.replay_cli ...``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from service.replay import logged_inputs, replay
from service.zenoh_session import DEFAULT_ENDPOINT, build_config, open_session


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("logs", type=Path, nargs="+", metavar="LOG.mcap",
                   help="MCAP log(s) of one run (rotated parts together)")
    p.add_argument("--rate", type=float, default=1.0,
                   help="time scale: 2 replays twice as fast; 0 sends without waiting (default 1)")
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help=f"Zenoh endpoint of the twin (repeatable; default {DEFAULT_ENDPOINT})")
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT")
    p.add_argument("--zenoh-config", type=Path, default=None, metavar="FILE")
    p.add_argument("--site", default=None, help="publish to this site id instead of the logged one")
    p.add_argument("--wait", type=float, default=10.0,
                   help="s to wait for a subscriber before replaying (default 10)")


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``replay`` to the ``railtwin`` CLI's subparsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "replay", help="republish the inputs of an MCAP log onto Zenoh",
        description="Republish the passages a twin received (from its MCAP log) in their "
                    "original timing, so that a fresh twin reproduces the logged outputs.",
    )
    add_arguments(p)
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    missing = [p for p in args.logs if not p.is_file()]
    if missing:
        print(f"railtwin replay: no such file: {missing[0]}", file=sys.stderr)
        return 2
    inputs = logged_inputs(args.logs)
    connect = args.connect or ([] if (args.zenoh_config or args.listen) else [DEFAULT_ENDPOINT])
    cfg = build_config(listen=args.listen, connect=connect, config_file=args.zenoh_config)
    with open_session(cfg) as session:
        n = replay(session, inputs, rate=args.rate, site_id=args.site, match_timeout=args.wait)
    print(f"railtwin replay: published {n} inputs from {len(args.logs)} file(s)", flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin replay", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
