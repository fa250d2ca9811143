"""``railtwin fleet``: the fleet service and its clients.

    railtwin fleet serve --connect ENDPOINT --db DB [--http HOST:PORT] [--limits SITE.toml]
                         [--horizon-days 30] [--catch-up-margin 3600]
    railtwin fleet wheel V/2/left --connect ENDPOINT [--json]
    railtwin fleet alarms --connect ENDPOINT [--all] [--json]

Also runnable as ``python -m service.cli.fleet ...``.
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import sys
import threading
import time
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_UNKNOWN_WHEEL = 3

EXIT_HELP = """\
exit status:
  0  success
  1  runtime failure (no fleet answered, the database or Zenoh could not be opened)
  2  invalid arguments (e.g. a malformed wheel id, limits file, Zenoh config or
     --db that is not a SQLite database)
  3  (wheel) the fleet does not know this wheel
"""


def _zenoh_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to, e.g. a router's tcp/10.0.0.1:7447 (repeatable)",
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to listen on (repeatable)",
    )
    p.add_argument(
        "--zenoh-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="Zenoh JSON5 config file (TLS, access control); --connect/--listen apply on top of it",
    )
    p.add_argument(
        "--mode",
        choices=("peer", "client"),
        default="peer",
        help="Zenoh mode (default peer; client: through the router only)",
    )


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``fleet`` (with ``serve``, ``wheel``, ``alarms``) to the ``railtwin`` CLI."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "fleet",
        help="the fleet service: every wheel's history, trend and alarms",
        description="The fleet service and its clients (docs/fleet.md).",
        epilog=EXIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = p.add_subparsers(dest="fleet_command", required=True, metavar="COMMAND")
    s = sub.add_parser(
        "serve",
        help="store every site's diagnoses, raise alarms, answer queries",
        epilog=EXIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _zenoh_args(s)
    s.add_argument(
        "--db",
        default="fleet.sqlite",
        help="SQLite file (default fleet.sqlite) or postgresql://user@host/db",
    )
    s.add_argument(
        "--http",
        default=None,
        metavar="HOST:PORT",
        help="serve the dashboard here, e.g. 127.0.0.1:8080",
    )
    s.add_argument(
        "--limits",
        type=Path,
        default=None,
        metavar="SITE.toml",
        help="forecast against this site file's [diagnosis] limits (default: the "
        "defaults, 40/60 mm and 350/400 kN for inspect/remove)",
    )
    s.add_argument(
        "--horizon-days",
        type=float,
        default=30.0,
        help="raise a forecast alarm when a limit is predicted within this many "
        "days of the wheel's latest diagnosis (default 30)",
    )
    s.add_argument(
        "--catch-up-margin",
        type=float,
        default=3600.0,
        metavar="S",
        help="on start, ask the twins for diagnoses since the latest stored time "
        "minus this (default 3600 s)",
    )
    s.add_argument("--no-catch-up", action="store_true", help="do not ask the twins on start")
    s.set_defaults(func=cmd_serve)
    w = sub.add_parser(
        "wheel",
        help="print a wheel's history and trend",
        epilog=EXIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    w.add_argument("wheel_id", metavar="VEHICLE/WHEELSET/SIDE", help="e.g. V123/2/left")
    _zenoh_args(w)
    w.add_argument("--json", action="store_true", help="print the JSON document")
    w.add_argument("--timeout", type=float, default=5.0, help="s to wait for the fleet")
    w.set_defaults(func=cmd_wheel)
    a = sub.add_parser(
        "alarms",
        help="print the fleet's alarms",
        epilog=EXIT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _zenoh_args(a)
    a.add_argument("--all", action="store_true", help="cleared alarms too")
    a.add_argument("--json", action="store_true", help="print the JSON document")
    a.add_argument("--timeout", type=float, default=5.0, help="s to wait for the fleet")
    a.set_defaults(func=cmd_alarms)
    return p


def _config(args: argparse.Namespace) -> Any:
    """The Zenoh config of the flags; CommandError (exit 2) naming a bad file or endpoint."""
    from service.cli.inputs import zenoh_config

    return zenoh_config(
        listen=args.listen, connect=args.connect, config_file=args.zenoh_config, mode=args.mode
    )


def _err(message: str) -> None:
    print(f"railtwin fleet: {message}", file=sys.stderr, flush=True)


def parse_http(text: str) -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--http {text!r}: expected HOST:PORT, e.g. 127.0.0.1:8080")
    return host, int(port)


def cmd_serve(args: argparse.Namespace) -> int:
    import zenoh

    from service.cli.inputs import check_sqlite
    from service.fleet.limits import FleetLimits
    from service.fleet.service import FleetService
    from service.fleet.store import StoreError, open_store

    logging.basicConfig(
        level=logging.INFO, stream=sys.stderr, format="fleet %(asctime)s %(levelname)s %(message)s"
    )
    try:
        limits = FleetLimits.from_site_file(args.limits) if args.limits else FleetLimits.defaults()
        http = parse_http(args.http) if args.http else None
        if not args.horizon_days > 0 or not args.catch_up_margin >= 0:
            raise ValueError("--horizon-days must be > 0 and --catch-up-margin >= 0")
    except ValueError as exc:
        _err(str(exc))
        return EXIT_USAGE
    config = _config(args)
    check_sqlite(args.db)
    try:
        store = open_store(args.db)
    except StoreError as exc:
        _err(str(exc))
        return EXIT_FAILURE
    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    try:
        session = zenoh.open(config)
    except zenoh.ZError as exc:
        _err(f"cannot open the Zenoh session: {exc}")
        store.close()
        return EXIT_FAILURE
    dashboard = None
    try:
        svc = FleetService(
            session,
            store,
            limits=limits,
            horizon=args.horizon_days * 86400.0,
            catch_up_margin=args.catch_up_margin,
        )
        svc.start(catch_up=not args.no_catch_up)
        url = ""
        if http is not None:
            from service.fleet.dashboard import Dashboard

            try:
                dashboard = Dashboard(svc, *http)
            except OSError as exc:
                _err(f"cannot serve the dashboard on {args.http}: {exc}")
                return EXIT_FAILURE
            dashboard.start()
            url = f", dashboard {dashboard.url}"
        print(
            f"fleet: ready ({store.dialect} {store.where}, {store.count()} diagnoses stored{url})",
            flush=True,
        )
        while not stop.wait(0.5):
            pass
        return EXIT_OK
    finally:
        if dashboard is not None:
            dashboard.stop()
        svc.stop()
        session.close()
        store.close()


def _get_one(args: argparse.Namespace, selector: str) -> tuple[str, Any] | None:
    """("ok"|"err", parsed JSON) of the first reply, None if nobody answered."""
    import zenoh

    config = _config(args)
    with zenoh.open(config) as session:
        deadline = time.monotonic() + args.timeout
        while True:  # a fresh session may need a moment to reach the router
            for reply in session.get(selector, timeout=max(0.5, deadline - time.monotonic())):
                if reply.ok is not None:
                    return "ok", json.loads(reply.ok.payload.to_bytes())
                if reply.err is not None:
                    try:
                        return "err", json.loads(reply.err.payload.to_bytes())
                    except ValueError:
                        return "err", {"message": reply.err.payload.to_string()}
            if time.monotonic() >= deadline:
                return None
            time.sleep(0.2)


def cmd_wheel(args: argparse.Namespace) -> int:
    from service.fleet.keys import WheelIdError, parse_wheel_id, wheel_key

    try:
        parse_wheel_id(args.wheel_id)
    except WheelIdError as exc:
        _err(str(exc))
        return EXIT_USAGE
    got = _get_one(args, wheel_key(args.wheel_id))
    if got is None:
        _err(
            f"no fleet service answered within {args.timeout:g} s (is `railtwin fleet serve` "
            "running and reachable at --connect?)"
        )
        return EXIT_FAILURE
    status, doc = got
    if status == "err":
        if isinstance(doc, dict) and doc.get("error") == "unknown_wheel":
            _err(f"the fleet has no diagnosis of wheel {args.wheel_id}")
            return EXIT_UNKNOWN_WHEEL
        _err(f"the fleet answered with an error: {doc}")
        return EXIT_FAILURE
    if args.json:
        print(json.dumps(doc, indent=1))
    else:
        sys.stdout.write(wheel_table(doc))
    return EXIT_OK


def cmd_alarms(args: argparse.Namespace) -> int:
    from service.fleet.keys import ALARMS_KEY

    got = _get_one(args, ALARMS_KEY + ("?all=true" if args.all else ""))
    if got is None or got[0] == "err":
        _err("no fleet service answered" if got is None else f"the fleet answered: {got[1]}")
        return EXIT_FAILURE
    doc = got[1]
    if args.json:
        print(json.dumps(doc, indent=1))
        return EXIT_OK
    if not doc["alarms"]:
        print("no alarms" if args.all else "no open alarms")
    for a in doc["alarms"]:
        print(f"{_date(a['raised_at'])}  {a['severity']:<8} {a['wheel_id']:<20} {a['reason']}")
    return EXIT_OK


def _date(t: float | None, fmt: str = "%Y-%m-%d %H:%M") -> str:
    return "-" if t is None else time.strftime(fmt, time.gmtime(t))


def wheel_table(doc: dict[str, Any]) -> str:
    """The wheel document as a table for people."""
    hist = doc["history"]
    sites = sorted({h["site_id"] for h in hist})
    sw = max([4, *(len(h["site_id"]) for h in hist)])
    pw = max([7, *(len(h["passage_id"]) for h in hist)])
    lines = [
        f"wheel {doc['wheel_id']}: last verdict {doc['last_verdict']}, {len(hist)} "
        f"diagnoses at {len(sites)} site(s) ({', '.join(sites)})",
        "",
        f"{'date (UTC)':<17} {'site':<{sw}} {'passage':<{pw}} {'verdict':<8} "
        f"{'flat mm [95 %]':<20} {'F@line kN':>9} {'speed m/s':>9}",
    ]
    for h in hist:
        f = h["flat"]
        flat = (
            "-"
            if f is None
            else (
                f"{f['length'] * 1e3:.1f} [{f['length_low'] * 1e3:.1f}-"
                f"{f['length_high'] * 1e3:.1f}]"
            )
        )
        fl = h["peak_force_at_line_speed"]
        sp = h["speed"]
        lines.append(
            f"{_date(h['timestamp']):<17} {h['site_id']:<{sw}} {h['passage_id']:<{pw}} "
            f"{h['verdict']:<8} {flat:<20} {'-' if fl is None else f'{fl / 1e3:.0f}':>9} "
            f"{'-' if sp is None else f'{sp:.1f}':>9}"
        )
    tr = doc["trend"]
    lines.append("")
    for name, label, scale, unit in (
        ("flat_length", "flat length", 1e3, "mm"),
        ("peak_force_at_line_speed", "peak force at line speed", 1e-3, "kN"),
    ):
        t = tr[name]
        if t is None:
            lines.append(f"trend of {label}: not determined (too few diagnoses with a flat)")
            continue
        parts = []
        for c in t["crossings"]:
            lim = f"{c['level']} {c['limit'] * scale:g} {unit}"
            if c["status"] == "not_growing":
                parts.append(f"{lim}: not growing")
                continue
            when = (
                "reached" if c["status"] == "reached" else f"predicted {_date(c['at'], '%Y-%m-%d')}"
            )
            span = ""
            if c["earliest"] is not None:
                span = f" (95 % {_date(c['earliest'], '%Y-%m-%d')} .. " + (
                    f"{_date(c['latest'], '%Y-%m-%d')})" if c["latest"] is not None else "open)"
                )
            parts.append(f"{lim}: {when}{span}")
        lines.append(
            f"trend of {label} since {_date(tr['since'], '%Y-%m-%d')}: "
            f"{t['slope_per_day'] * scale:+.3g} ± {t['slope_se_per_day'] * scale:.2g} "
            f"{unit}/day over {t['points']} diagnoses; " + "; ".join(parts)
        )
    lines.append("distance run: not in the messages (no odometer reading): not tracked")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``railtwin fleet ARGV``, with its error reporting."""
    from service.cli.main import main as cli_main

    return cli_main(["fleet", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
