"""Zenoh configuration shared by the example clients: explicit, as in zenoh-python's examples."""

import argparse
import json
import time

import zenoh

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"  # where `railtwin serve` listens by default


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--mode", "-m", choices=["peer", "client"], default="peer",
                        help="Zenoh mode: client when joining a router (railtwin router)")
    parser.add_argument("--connect", "-e", action="append", default=[], metavar="ENDPOINT",
                        help=f"endpoint to connect to (repeatable; default {DEFAULT_ENDPOINT})")
    parser.add_argument("--listen", "-l", action="append", default=[], metavar="ENDPOINT",
                        help="endpoint to listen on (repeatable)")
    parser.add_argument("--config", "-c", metavar="FILE",
                        help="Zenoh JSON5 config (TLS certificates, ...), applied first")


def get_config_from_args(args: argparse.Namespace) -> zenoh.Config:
    zenoh.init_log_from_env_or("error")
    conf = zenoh.Config.from_file(args.config) if args.config else zenoh.Config()
    conf.insert_json5("mode", json.dumps(args.mode))
    conf.insert_json5("connect/endpoints", json.dumps(args.connect or [DEFAULT_ENDPOINT]))
    if args.listen:
        conf.insert_json5("listen/endpoints", json.dumps(args.listen))
    conf.insert_json5("scouting/multicast/enabled", "false")  # explicit endpoints only
    return conf


def wait_for_subscriber(publisher: zenoh.Publisher, timeout: float = 5.0) -> bool:
    """Wait until someone subscribes to ``publisher``'s key (a put before is lost)."""
    deadline = time.monotonic() + timeout
    while not publisher.matching_status.matching and time.monotonic() < deadline:  # type: ignore[attr-defined]  # stub says bool
        time.sleep(0.05)
    return bool(publisher.matching_status.matching)  # type: ignore[attr-defined]
