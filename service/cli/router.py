"""``railtwin router``: a Zenoh router for a network of sites, until SIGINT/SIGTERM.

    railtwin router --listen tcp/0.0.0.0:7447 [--connect tcp/<other router>:7447]...
                    [--zenoh-config router.json5]

Zenoh's own routing (a session in ``router`` mode): twins (``railtwin serve --connect``),
the fleet service (``railtwin fleet serve --connect``) and clients join it, and it routes
their publications, subscriptions and queries; ``--connect`` links it to the routers of
other regions. TLS and access control come from ``--zenoh-config`` (docs/deployment.md,
deploy/zenoh/). Multicast scouting is off: peers and routers are given explicitly.

Also runnable as ``python -m service.cli.router ...``.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import zenoh

from service.cli.inputs import zenoh_config
from service.wire.zenoh_session import DEFAULT_ENDPOINT, open_session


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"endpoint to listen on (repeatable; default {DEFAULT_ENDPOINT} unless "
        "--zenoh-config is given), e.g. tcp/0.0.0.0:7447 or tls/host:7447",
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="another router to link to (repeatable): routers of other regions",
    )
    p.add_argument(
        "--zenoh-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="Zenoh JSON5 config (TLS, access control); --listen/--connect apply on top of it",
    )


def register(subparsers: Any) -> None:
    p = subparsers.add_parser(
        "router",
        help="run a Zenoh router that sites, the fleet and clients join",
        description=__doc__.split("\n\n")[0] if __doc__ else None,
    )
    add_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    listen = args.listen or ([] if args.zenoh_config else [DEFAULT_ENDPOINT])
    cfg = zenoh_config(
        listen=listen, connect=args.connect, config_file=args.zenoh_config, mode="router"
    )
    stop = threading.Event()

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            session = open_session(cfg)
        except zenoh.ZError as exc:
            print(
                f"railtwin router: cannot start: {' '.join(str(exc).split())}",
                file=sys.stderr,
                flush=True,
            )
            return 1
        with session:
            where = ", ".join(listen) if listen else "(from config)"
            links = f", linked to {', '.join(args.connect)}" if args.connect else ""
            print(f"railtwin router: routing on {where}{links} (zid {session.zid()})", flush=True)
            print("railtwin router: ready", flush=True)
            while not stop.wait(0.2):
                pass
        print("railtwin router: stopped", flush=True)
        return 0
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def main(argv: Sequence[str] | None = None) -> int:
    """``railtwin router ARGV``, with its error reporting."""
    from service.cli.main import main as cli_main

    return cli_main(["router", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    raise SystemExit(main())
