"""The service's log: Python ``logging`` on stderr, time, level and component on every line.

    2026-11-24T17:09:10.123Z INFO railtwin.serve: ready
    {"time": "2026-11-24T17:09:10.123Z", "level": "INFO", "component": "railtwin.serve",
     "message": "ready", "pid": 4100}                                   (--log-json)

Components are the loggers under ``railtwin``: ``railtwin.serve`` (start, stop, files),
``railtwin.twin`` (errors answered to inputs), ``railtwin.physics`` (worker restarts).
Times are UTC with milliseconds.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from datetime import UTC, datetime
from typing import IO, Literal

LogLevel = Literal["debug", "info", "warning", "error"]
LEVELS: tuple[LogLevel, ...] = ("debug", "info", "warning", "error")
ROOT_LOGGER = "railtwin"


def _utc(created: float) -> str:
    return (
        datetime.fromtimestamp(created, tz=UTC)
        .isoformat(timespec="milliseconds")
        .replace("+00:00", "Z")
    )


class TextFormatter(logging.Formatter):
    """``<UTC time> <LEVEL> <component>: <message>``."""

    def format(self, record: logging.LogRecord) -> str:
        line = f"{_utc(record.created)} {record.levelname} {record.name}: {record.getMessage()}"
        if record.exc_info:
            line += "\n" + self.formatException(record.exc_info)
        return line


class JsonFormatter(logging.Formatter):
    """One JSON object a line, for log shippers."""

    def format(self, record: logging.LogRecord) -> str:
        doc: dict[str, object] = {
            "time": _utc(record.created),
            "level": record.levelname,
            "component": record.name,
            "message": record.getMessage(),
            "pid": record.process,
        }
        if record.exc_info:
            doc["exception"] = self.formatException(record.exc_info)
        return json.dumps(doc, ensure_ascii=False)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--log-level",
        choices=LEVELS,
        default="info",
        help="least severe log lines written to stderr (default info)",
    )
    p.add_argument(
        "--log-json",
        action="store_true",
        help="log one JSON object a line (time, level, component, message, pid)",
    )


def configure(
    level: LogLevel = "info", json_lines: bool = False, stream: IO[str] | None = None
) -> logging.Logger:
    """Send the ``railtwin`` loggers to ``stream`` (stderr) at ``level``; returns the root."""
    handler = logging.StreamHandler(stream if stream is not None else sys.stderr)
    handler.setFormatter(JsonFormatter() if json_lines else TextFormatter())
    root = logging.getLogger(ROOT_LOGGER)
    for old in list(root.handlers):
        root.removeHandler(old)
    root.addHandler(handler)
    root.setLevel(level.upper())
    root.propagate = False
    return root
