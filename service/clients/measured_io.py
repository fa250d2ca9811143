"""Measured passages from files: a CSV (contact force or crib channels) or a railtwin MCAP log.

CSV (CONTRACT.md): a header line ``t_s,force_N`` (a contact-force sensor) or ``t_s`` then one
column per crib id (a detector: ``t_s,ch1,…,ch8``; the ids must be the site's
``detector.cribs``, checked by the caller with ``service.wire.measured_channels``), then one
sample per line (s, N). Every row has every column; every value is a finite number; ``t_s``
increases uniformly: at the site's measuring rate (``[diagnosis] sample_rate``) when it
states one, else at the rate of the file's median spacing, each step within 1 %. MCAP: a log
written by ``railtwin serve``; the ``MeasuredPassage`` messages on a
``railtwin/<site>/measured`` channel, the one with the passage's id.

Errors are ``MeasuredFileError`` with one line naming the file, and the line and column
where there is one.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from schemas._base import KEY_CHUNK
from schemas.diagnosis import MAX_MEASURED_SAMPLES, MIN_MEASURED_SAMPLES, MeasuredPassage

TIME_COLUMN = "t_s"
FORCE_COLUMN = "force_N"
CSV_HEADER = f"{TIME_COLUMN},{FORCE_COLUMN}"
SPACING_TOLERANCE = 0.01


class MeasuredFileError(ValueError):
    """A measured-data file that cannot be read; the message is one line."""


def _columns(path: Path, first: str) -> list[str]:
    """The value columns named by the header (``force_N`` or crib ids), checked."""
    names = [n.strip() for n in first.split(",")]
    if len(names) < 2 or names[0] != TIME_COLUMN:
        raise MeasuredFileError(
            f"{path}: line 1: header must be {CSV_HEADER!r} or '{TIME_COLUMN},' then one column "
            f"per crib id (t_s,ch1,…,ch8), got {first.strip()[:60]!r}"
        )
    columns = names[1:]
    if FORCE_COLUMN in columns and columns != [FORCE_COLUMN]:
        raise MeasuredFileError(
            f"{path}: line 1, column {len(names) - len(columns) + columns.index(FORCE_COLUMN) + 1}"
            f": {FORCE_COLUMN!r} is the contact force's only column, not a crib id"
        )
    seen: set[str] = set()
    for no, name in enumerate(columns, start=2):
        if not re.match(KEY_CHUNK, name):
            raise MeasuredFileError(
                f"{path}: line 1, column {no}: {name[:60]!r} is not a crib id "
                "([A-Za-z0-9_.-], 1 to 96 characters)"
            )
        if name in seen:
            raise MeasuredFileError(f"{path}: line 1, column {no}: crib id {name!r} repeated")
        seen.add(name)
    if len(columns) * MIN_MEASURED_SAMPLES > MAX_MEASURED_SAMPLES:
        raise MeasuredFileError(f"{path}: line 1: {len(columns)} columns, too many")
    return columns


def _rows(path: Path, lines: list[str], names: list[str]) -> tuple[list[int], list[list[float]]]:
    """The line numbers and the values (time first) of every data row, checked."""
    width = len(names)
    most = MAX_MEASURED_SAMPLES // (width - 1)
    numbers: list[int] = []
    rows: list[list[float]] = []
    for no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) != width:
            raise MeasuredFileError(
                f"{path}: line {no}: expected {width} values ({','.join(names)[:60]}), "
                f"got {len(parts)}"
            )
        row: list[float] = []
        for col, (name, text) in enumerate(zip(names, parts, strict=True), start=1):
            try:
                v = float(text)
            except ValueError:
                raise MeasuredFileError(
                    f"{path}: line {no}, column {col} ({name}): not a number: {text.strip()[:40]!r}"
                ) from None
            if not math.isfinite(v):
                raise MeasuredFileError(
                    f"{path}: line {no}, column {col} ({name}): must be finite, got "
                    f"{text.strip()!r}"
                )
            row.append(v)
        numbers.append(no)
        rows.append(row)
        if len(rows) > most:
            raise MeasuredFileError(
                f"{path}: line {no}: more than {most} samples"
                + (f" of {width - 1} channels" if width > 2 else "")
                + f" ({MAX_MEASURED_SAMPLES} values in all)"
            )
    if len(rows) < MIN_MEASURED_SAMPLES:
        raise MeasuredFileError(
            f"{path}: {len(rows)} samples, at least {MIN_MEASURED_SAMPLES} are needed"
        )
    return numbers, rows


def _time_step(path: Path, numbers: list[int], t: np.ndarray, sample_rate: float | None) -> float:
    """The spacing of ``t_s``: increasing, uniform, at ``sample_rate`` if given."""
    dt = np.diff(t)
    back = np.flatnonzero(dt <= 0.0)
    if back.size:
        k = int(back[0]) + 1
        raise MeasuredFileError(
            f"{path}: line {numbers[k]}, column 1 ({TIME_COLUMN}): time must increase, "
            f"{t[k]:g} s follows {t[k - 1]:g} s"
        )
    step = 1.0 / sample_rate if sample_rate is not None else float(np.median(dt))
    off = np.flatnonzero(np.abs(dt - step) > SPACING_TOLERANCE * step)
    if off.size:
        k = int(off[0]) + 1
        rate = (
            f"the site's sample rate {sample_rate:g} Hz"
            if sample_rate is not None
            else f"the file's median {1.0 / step:g} Hz"
        )
        raise MeasuredFileError(
            f"{path}: line {numbers[k]}, column 1 ({TIME_COLUMN}): {t[k]:g} s is {dt[k - 1]:g} s "
            f"after the sample before; {rate} needs {step:g} s (within "
            f"{SPACING_TOLERANCE:.0%})"
        )
    return step


def read_measured_csv(
    path: Path, passage_id: str, speed: float | None = None, sample_rate: float | None = None
) -> MeasuredPassage:
    """A ``MeasuredPassage`` from a CSV file (see the module docstring): ``force`` from a
    ``t_s,force_N`` file, ``channels`` from a ``t_s,<crib id>,…`` one. ``sample_rate``: the
    site's measuring rate, Hz, which ``t_s`` must keep (None: any uniform rate)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MeasuredFileError(f"cannot read {path}: {exc}") from None
    lines = text.splitlines()
    if not lines:
        raise MeasuredFileError(
            f"{path}: line 1: header must be {CSV_HEADER!r}, got the empty file"
        )
    columns = _columns(path, lines[0])
    numbers, rows = _rows(path, lines, [TIME_COLUMN, *columns])
    values = np.asarray(rows, dtype=np.float64)
    step = _time_step(path, numbers, values[:, 0], sample_rate)
    rate = sample_rate if sample_rate is not None else 1.0 / step
    force: list[float] | None = None
    channels: dict[str, list[float]] | None = None
    if columns == [FORCE_COLUMN]:
        force = values[:, 1].tolist()
    else:
        channels = {name: values[:, i].tolist() for i, name in enumerate(columns, start=1)}
    try:
        return MeasuredPassage(
            passage_id=passage_id,
            sample_rate=rate,
            t_start=float(values[0, 0]),
            force=force,
            channels=channels,
            speed=speed,
        )
    except ValidationError as exc:
        e = exc.errors()[0]
        raise MeasuredFileError(f"{path}: {'.'.join(map(str, e['loc']))}: {e['msg']}") from None


def read_measured_mcap(path: Path, passage_id: str) -> MeasuredPassage:
    """The ``MeasuredPassage`` of ``passage_id`` logged in a railtwin MCAP file."""
    from service.recording.mcap_log import read_log

    found: MeasuredPassage | None = None
    try:
        for msg in read_log([path]):
            if not msg.topic.endswith("/measured") or "MeasuredPassage" not in msg.schema_name:
                continue
            try:
                m = MeasuredPassage.model_validate_json(msg.data)
            except ValidationError:
                continue
            if m.passage_id == passage_id:
                found = m
    except Exception as exc:  # a cut or foreign file: say so in one line
        raise MeasuredFileError(f"cannot read MCAP {path}: {type(exc).__name__}: {exc}") from None
    if found is None:
        raise MeasuredFileError(f"{path}: no MeasuredPassage with passage_id {passage_id!r}")
    return found


def read_measured(
    path: Path, passage_id: str, speed: float | None = None, sample_rate: float | None = None
) -> MeasuredPassage:
    """CSV or MCAP by the file's suffix (``sample_rate``: see ``read_measured_csv``; an MCAP's
    message states its own, which the diagnosis checks)."""
    if path.suffix.lower() == ".mcap":
        return read_measured_mcap(path, passage_id)
    return read_measured_csv(path, passage_id, speed, sample_rate)
