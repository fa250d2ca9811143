"""Log lines for operators: time, level and component on every line; --log-json."""

from __future__ import annotations

import io
import json
import logging
import re
from collections.abc import Iterator

import pytest

from service.cli import logs
from service.cli.serve import add_arguments

LINE = re.compile(
    r"^\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z (DEBUG|INFO|WARNING|ERROR) "
    r"(railtwin(\.\w+)*): (.*)$"
)


@pytest.fixture
def restore_logging() -> Iterator[None]:
    root = logging.getLogger(logs.ROOT_LOGGER)
    handlers, level, propagate = list(root.handlers), root.level, root.propagate
    yield
    root.handlers[:] = handlers
    root.setLevel(level)
    root.propagate = propagate


def test_text_lines_carry_time_level_and_component(restore_logging: None) -> None:
    out = io.StringIO()
    logs.configure("info", stream=out)
    logging.getLogger("railtwin.serve").info("ready")
    logging.getLogger("railtwin.twin").warning("overloaded (passage p1): dropped")
    logging.getLogger("railtwin.twin").debug("not shown at info")
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    found = [LINE.match(line) for line in lines]
    assert all(found), lines
    assert [(m.group(1), m.group(2), m.group(4)) for m in found if m] == [
        ("INFO", "railtwin.serve", "ready"),
        ("WARNING", "railtwin.twin", "overloaded (passage p1): dropped"),
    ]


def test_json_lines_for_log_shippers(restore_logging: None) -> None:
    out = io.StringIO()
    logs.configure("debug", json_lines=True, stream=out)
    logging.getLogger("railtwin.physics").debug("worker %d restarted", 2)
    doc = json.loads(out.getvalue())
    assert doc["level"] == "DEBUG" and doc["component"] == "railtwin.physics"
    assert doc["message"] == "worker 2 restarted" and isinstance(doc["pid"], int)
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z", doc["time"])


def test_serve_takes_the_log_options() -> None:
    import argparse

    p = argparse.ArgumentParser()
    add_arguments(p)
    args = p.parse_args(["--site", "s.toml", "--log-level", "warning", "--log-json"])
    assert args.log_level == "warning" and args.log_json
    with pytest.raises(SystemExit):
        p.parse_args(["--site", "s.toml", "--log-level", "loud"])
