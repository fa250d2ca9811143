"""One explicit Zenoh configuration for every railtwin process (service, feeder, replay).

Peer mode, explicit ``listen``/``connect`` endpoints and multicast scouting
off unless asked for (``../shared/ECOSYSTEM.md``: scouting is slow and may
lose the first message); a JSON5 config file, when given, is the starting
point and the command-line endpoints are applied on top of it.

    >>> cfg = build_config(listen=["tcp/127.0.0.1:7447"])
    >>> isinstance(cfg, zenoh.Config)
    True
"""

from __future__ import annotations

import json
import socket
from collections.abc import Sequence
from pathlib import Path

import zenoh

DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"
"""Where ``railtwin serve`` listens and the feeder/replay connect by default (loopback)."""


def build_config(
    *,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: Path | None = None,
    mode: str = "peer",
    multicast_scouting: bool = False,
) -> zenoh.Config:
    """A Zenoh config: ``config_file`` (if any), then mode, endpoints and scouting."""
    cfg = zenoh.Config.from_file(str(config_file)) if config_file else zenoh.Config()
    if config_file is None or mode != "peer":
        cfg.insert_json5("mode", json.dumps(mode))
    if listen:
        cfg.insert_json5("listen/endpoints", json.dumps(list(listen)))
    if connect:
        cfg.insert_json5("connect/endpoints", json.dumps(list(connect)))
    if config_file is None or multicast_scouting:
        cfg.insert_json5("scouting/multicast/enabled", json.dumps(multicast_scouting))
    return cfg


def free_tcp_endpoint(host: str = "127.0.0.1") -> str:
    """A ``tcp/host:port`` endpoint on a port that is free now (for tests and benchmarks)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        port = s.getsockname()[1]
    return f"tcp/{host}:{port}"


def open_session(cfg: zenoh.Config) -> zenoh.Session:
    """Open a session; the caller must ``close()`` it (or use ``with``): see ECOSYSTEM.md."""
    return zenoh.open(cfg)
