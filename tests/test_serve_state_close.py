"""``railtwin serve`` closes its rail-state store when it stops (issue 16's "what an operator
needs to run it for months": a store left open is only closed by the interpreter's teardown,
or not at all if the process leaves with ``os._exit``)."""

from __future__ import annotations

import sqlite3
import threading
from pathlib import Path

import pytest

import service.cli.serve as serve
from schemas.site import SiteConfig
from service.cli.main import build_parser
from service.physics.rail_store import RailStore

ROOT = Path(__file__).resolve().parent.parent


def test_a_stop_before_serving_closes_the_state_store(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    opened: list[RailStore] = []
    real_open = serve.open_state

    def recording_open(directory: Path, site: SiteConfig) -> RailStore:
        store = real_open(directory, site)
        opened.append(store)
        return store

    monkeypatch.setattr(serve, "open_state", recording_open)
    argv = [
        "serve",
        "--site",
        str(ROOT / "examples" / "site.toml"),
        "--physics",
        "stub",
        "--recordings",
        str(tmp_path),
        "--state",
        str(tmp_path / "state"),
        "--listen",
        "tcp/127.0.0.1:0",
    ]
    args = build_parser(argv).parse_args(argv)
    stop = threading.Event()
    stop.set()  # as if SIGTERM came during the warm-up: serve starts nothing more
    assert serve._run(args, stop, []) == 0
    assert len(opened) == 1
    with pytest.raises(sqlite3.ProgrammingError):
        opened[0].applied_count()  # closed
