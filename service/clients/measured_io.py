"""Measured passages from files: a CSV of ``t_s,force_N`` or a railtwin MCAP log.

CSV: a header line exactly ``t_s,force_N``, then one sample per line (s, N), uniformly
spaced (the sample rate is taken from the times; a spacing that varies by more than
1 % is refused). MCAP: a log written by ``railtwin serve``; the ``MeasuredPassage``
messages on a ``railtwin/<site>/measured`` channel, the one with the passage's id.

Errors are ``MeasuredFileError`` with one line naming the file, line or field.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pydantic import ValidationError

from schemas.diagnosis import MAX_MEASURED_SAMPLES, MIN_MEASURED_SAMPLES, MeasuredPassage

CSV_HEADER = "t_s,force_N"
SPACING_TOLERANCE = 0.01


class MeasuredFileError(ValueError):
    """A measured-data file that cannot be read; the message is one line."""


def read_measured_csv(path: Path, passage_id: str, speed: float | None = None) -> MeasuredPassage:
    """A ``MeasuredPassage`` from a CSV file (see the module docstring)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MeasuredFileError(f"cannot read {path}: {exc}") from None
    lines = text.splitlines()
    if not lines or lines[0].strip().replace(" ", "") != CSV_HEADER:
        got = lines[0].strip()[:60] if lines else "(empty file)"
        raise MeasuredFileError(f"{path}: line 1: header must be {CSV_HEADER!r}, got {got!r}")
    t: list[float] = []
    f: list[float] = []
    for no, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) != 2:
            raise MeasuredFileError(f"{path}: line {no}: expected 2 values, got {len(parts)}")
        try:
            tv, fv = float(parts[0]), float(parts[1])
        except ValueError:
            raise MeasuredFileError(
                f"{path}: line {no}: not numbers: {line.strip()[:60]!r}"
            ) from None
        if not (math.isfinite(tv) and math.isfinite(fv)):
            raise MeasuredFileError(
                f"{path}: line {no}: values must be finite, got {line.strip()!r}"
            )
        t.append(tv)
        f.append(fv)
        if len(t) > MAX_MEASURED_SAMPLES:
            raise MeasuredFileError(f"{path}: more than {MAX_MEASURED_SAMPLES} samples")
    if len(t) < MIN_MEASURED_SAMPLES:
        raise MeasuredFileError(
            f"{path}: force: {len(t)} samples, at least {MIN_MEASURED_SAMPLES} are needed"
        )
    ta = np.asarray(t)
    dt = np.diff(ta)
    step = float(np.median(dt))
    if not step > 0 or np.max(np.abs(dt - step)) > SPACING_TOLERANCE * step:
        raise MeasuredFileError(
            f"{path}: t_s must be increasing and uniformly spaced "
            f"(sample rate): spacing varies from {dt.min():g} to {dt.max():g} s"
        )
    try:
        return MeasuredPassage(
            passage_id=passage_id,
            sample_rate=1.0 / step,
            t_start=float(ta[0]),
            force=f,
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


def read_measured(path: Path, passage_id: str, speed: float | None = None) -> MeasuredPassage:
    """CSV or MCAP by the file's suffix."""
    if path.suffix.lower() == ".mcap":
        return read_measured_mcap(path, passage_id)
    return read_measured_csv(path, passage_id, speed)
