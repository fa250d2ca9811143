"""The files a subcommand is given, read and checked before anything starts.

Each loader returns what the file holds, validated, or raises ``CommandError`` (exit 2) whose
message is one line naming the file and the field or the problem: JSON files are read by
``common.read_json`` and their fields reported by ``schemas.errors.ErrorReport`` (the
``--format json`` report too), site files by ``service.wire.site.load_site``.

    >>> from pathlib import Path
    >>> from schemas.messages import WheelPassage
    >>> import tempfile
    >>> bad = Path(tempfile.mkdtemp()) / "p.json"
    >>> _ = bad.write_text('{"passage_id": "a"}')
    >>> try:
    ...     load_json_file(bad, "passage", WheelPassage)
    ... except CommandError as exc:
    ...     print(exc.code, *str(exc).replace(str(bad), "p.json").split("; ")[:2], sep=" | ")
    2 | invalid passage p.json: 8 invalid fields | train_id: required field is missing
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from service.cli.common import EXIT_USAGE, CommandError, one_line, read_json

if TYPE_CHECKING:  # zenoh and the site's model are imported when used: --help stays quick
    import zenoh

    from schemas.site import SiteConfig

T = TypeVar("T")


def load_json_file(path: Path | str, what: str, schema: type[T]) -> T:
    """The JSON file ``path`` validated as ``schema`` (a model, or e.g. ``list[Model]``)."""
    from pydantic import TypeAdapter, ValidationError

    from schemas.errors import ErrorReport

    source = str(path)
    data = read_json(source, source)
    try:
        return TypeAdapter(schema).validate_python(data)
    except ValidationError as exc:
        report = ErrorReport.from_validation_error(exc, data, source)
        raise CommandError(
            f"invalid {what} {one_line(report.to_text())}", EXIT_USAGE, report
        ) from None


def load_site_file(path: Path, *, served: bool = False) -> SiteConfig:
    """The site file ``path``, validated and resolved; if ``served``, one a twin can serve."""
    from service.wire.limits import site_problem
    from service.wire.site import SiteFileError, load_site

    try:
        site = load_site(path)
    except SiteFileError as exc:
        raise CommandError(one_line(str(exc)), EXIT_USAGE) from None
    problem = site_problem(site) if served else None
    if problem is not None:
        raise CommandError(f"{path}: invalid site: {problem}", EXIT_USAGE)
    return site


def zenoh_config(
    *,
    listen: Sequence[str] = (),
    connect: Sequence[str] = (),
    config_file: Path | None = None,
    mode: str = "peer",
    multicast_scouting: bool = False,
) -> zenoh.Config:
    """``build_config``, its errors named: the config file (with the line) or an endpoint."""
    import zenoh

    from service.wire.zenoh_session import build_config

    if config_file is not None:
        try:
            zenoh.Config.from_file(str(config_file))
        except zenoh.ZError as exc:
            raise CommandError(
                f"invalid Zenoh config {config_file}: {zenoh_message(exc)}", EXIT_USAGE
            ) from None
    try:
        return build_config(
            listen=listen,
            connect=connect,
            config_file=config_file,
            mode=mode,
            multicast_scouting=multicast_scouting,
        )
    except zenoh.ZError as exc:
        endpoints = " ".join([*listen, *connect])
        raise CommandError(
            f"invalid endpoint ({endpoints}): {zenoh_message(exc, located=False)}", EXIT_USAGE
        ) from None


_RUST_SOURCE = re.compile(r"\s+at /\S+?\.rs:\d+\.?")
_SERDE = re.compile(
    r'msg: "(?P<msg>.*)", location: Some\(Location \{ line: (?P<line>\d+), '
    r"column: (?P<col>\d+) \}\)",
    re.S,
)
_PEST = re.compile(r"-->\s*(?P<line>\d+):(?P<col>\d+).*?\n\s*=\s*(?P<msg>[^\n]*)", re.S)


def zenoh_message(exc: BaseException, *, located: bool = True) -> str:
    """A Zenoh error in one line, without the Rust source locations it carries: the parser's
    message, after the line and column in the file when ``located``.

    >>> zenoh_message(ValueError(' --> 1:1\\n  |\\n1 | {bad\\n  | ^---\\n  |\\n  = expected '
    ...     'value at /x/lib.rs:1486.'))
    'line 1 column 1: expected value'
    """
    text = _RUST_SOURCE.sub("", str(exc))
    m = _SERDE.search(text) or _PEST.search(text)
    if m is None:
        return " ".join(text.split())[:300]
    where = f"line {m['line']} column {m['col']}: " if located else ""
    return where + " ".join(m["msg"].split())


def check_logs(paths: Sequence[Path], *, journals: bool) -> None:
    """Every path is a file, an MCAP log (cut short or not) or, if ``journals``, an input
    journal; CommandError (exit 2) naming the first that is not."""
    from service.recording.mcap_recover import log_problem

    for p in paths:
        if not p.is_file():
            raise CommandError(f"no such file: {p}", EXIT_USAGE)
        problem = log_problem(p, journals=journals)
        if problem is not None:
            raise CommandError(f"{p}: {problem}", EXIT_USAGE)


SQLITE_MAGIC = b"SQLite format 3\x00"


def check_sqlite(db: str) -> None:
    """A SQLite ``--db`` that exists holds a database (a new or empty file is made one)."""
    if db.startswith(("postgresql://", "postgres://")):
        return
    path = Path(db)
    if path.is_dir():
        raise CommandError(f"--db {db}: a directory, not a SQLite database file", EXIT_USAGE)
    try:
        with path.open("rb") as f:
            head = f.read(len(SQLITE_MAGIC))
    except FileNotFoundError:
        return
    except OSError as exc:
        raise CommandError(f"--db {db}: cannot read: {exc.strerror or exc}", EXIT_USAGE) from None
    if head and head != SQLITE_MAGIC:
        raise CommandError(
            f"--db {db}: not a SQLite database (it starts with {head[:8]!r})", EXIT_USAGE
        )
