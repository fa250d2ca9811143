"""What every ``railtwin`` subcommand shares: exit codes, the one-line error, JSON files."""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, TypeAlias

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

EXIT_CODES_HELP = """\
exit status:
  0    success
  1    runtime failure (the simulation failed, an output could not be written,
       an optional dependency is missing)
  2    invalid input (bad arguments, unreadable or invalid scenario file; the
       message names the offending field)
  130  interrupted (Ctrl-C)
"""


SubParsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"
"""What ``register(subparsers)`` of a subcommand module is given."""


class CommandError(Exception):
    """A failure to report as one message and an exit code, without a traceback."""

    def __init__(self, message: str, code: int = EXIT_FAILURE, report: Any = None) -> None:
        super().__init__(message)
        self.code = code
        self.report = report


def one_line(text: str) -> str:
    """A message of several lines (a report, a site file's fields) as one: its lines joined
    with ``; ``."""
    return "; ".join(part.strip() for part in text.splitlines() if part.strip())


def read_json(path: str, source: str) -> Any:
    """The JSON document in ``path`` (``-``: stdin); ``CommandError`` (exit 2) naming
    ``source`` when it cannot be read or is not JSON."""
    from schemas.errors import ErrorReport

    try:
        text = sys.stdin.read() if path == "-" else Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        message = f"cannot read {source}: {exc.strerror or exc}"
        raise CommandError(
            message, EXIT_USAGE, ErrorReport(error="io_error", message=message, source=source)
        ) from None
    except UnicodeDecodeError as exc:
        message = f"cannot read {source}: not UTF-8 text ({exc.reason})"
        raise CommandError(
            message, EXIT_USAGE, ErrorReport(error="invalid_input", message=message, source=source)
        ) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        message = f"{source} is not valid JSON: line {exc.lineno} column {exc.colno}: {exc.msg}"
        raise CommandError(
            message,
            EXIT_USAGE,
            ErrorReport(error="invalid_input", message=message, source=source),
        ) from None


def write_atomic(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` via a temporary file, so a reader never sees half a result."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(text)
                f.write("\n")
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    except OSError as exc:
        raise CommandError(f"cannot write {path}: {exc.strerror or exc}") from None
