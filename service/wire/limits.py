"""What one message may cost the twin: every limit in one place (docs/service.md, "Limits").

A wayside twin runs unattended; a single small message must not make it use
more than a bounded amount of memory, output or time. The checks here run
before (``payload_problem``, ``nesting_too_deep``) and after (``passage_problem``)
the payload is parsed. Each refusal names the field that broke the limit.

    >>> passage_samples(6.0, 10_000.0, 44.44)
    1351
    >>> lowest_speed(6.0, 10_000.0)
    0.4
    >>> round(lowest_speed(6.0, 10_000.0, cribs=8), 4)  # the output bytes cap binds
    0.5066
    >>> nesting_too_deep(b'{"a": [[[[[[[[1]]]]]]]]}', 8)
    True
    >>> nesting_too_deep(b'{"a": "[[[[[[[[[[[[[[[[[["}', 8)
    False
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING

from schemas.diagnosis import MAX_MEASURED_SAMPLES
from schemas.messages import (
    MAX_ID_LENGTH,
    MAX_PASSAGE_OUTPUT_BYTES,
    MAX_PASSAGE_SAMPLES,
    OUTPUT_BYTES_PER_SAMPLE,
    Identifier,
    WheelPassage,
)
from schemas.scenario import MAX_OUTLINE_POINTS
from schemas.site import MAX_RAIL_POINTS

if TYPE_CHECKING:
    from schemas.site import SiteConfig

__all__ = [
    "CHANNEL_BYTES_PER_SAMPLE",
    "DEFAULT_PASSAGE_BUDGET",
    "MAX_ID_LENGTH",
    "MAX_MEASURED_PAYLOAD_BYTES",
    "MAX_MEASURED_SAMPLES",
    "MAX_NESTING",
    "MAX_OUTLINE_POINTS",
    "MAX_PASSAGE_OUTPUT_BYTES",
    "MAX_PASSAGE_PAYLOAD_BYTES",
    "MAX_PASSAGE_SAMPLES",
    "MAX_RAIL_POINTS",
    "OUTPUT_BYTES_PER_SAMPLE",
    "Identifier",
]

MAX_PASSAGE_PAYLOAD_BYTES = 1 << 20
"""A ``WheelPassage`` payload of more than 1 MiB is refused unread (a sampled outline at its
cap of points is about 200 kB)."""

MAX_MEASURED_PAYLOAD_BYTES = 64 << 20
"""A ``MeasuredPassage`` payload of more than 64 MiB is refused unread (its cap of
2 000 000 samples is at most ~50 MB of JSON)."""

MAX_NESTING = 8
"""JSON nested deeper than this (objects and arrays) is refused as ``invalid_json`` before it
is parsed; the deepest valid input (a passage's sampled outline) is 3 deep."""

DEFAULT_PASSAGE_BUDGET = 30.0
"""s of wall time one passage (or one diagnosis) may take in the physics worker."""

ERROR_TEXT_LIMIT = 400
"""Characters of a field path or message kept in a ServiceError (inputs are never echoed)."""

MAX_PROBLEMS = 20
"""Field problems listed in one ServiceError."""

_ID = re.compile(rf"[A-Za-z0-9_.\-]{{1,{MAX_ID_LENGTH}}}")
_STRING = re.compile(rb'"(?:[^"\\]|\\.)*"', re.DOTALL)
_BRACKET_MAP = bytes.maketrans(b"[{]}", b"(())")
_NOT_BRACKETS = bytes(sorted(set(range(256)) - set(b"[]{}")))
_PASSAGE_ID = re.compile(
    rb'"passage_id"\s*:\s*"([A-Za-z0-9_.\-]{1,' + str(MAX_ID_LENGTH).encode() + rb'})"'
)


def valid_id(value: object) -> str | None:
    """``value`` if it is a valid passage/train id (a Zenoh key chunk), else None."""
    return value if isinstance(value, str) and _ID.fullmatch(value) else None


def clip(text: str, limit: int = ERROR_TEXT_LIMIT) -> str:
    """``text`` cut to ``limit`` characters (with a note of how much was cut)."""
    if len(text) <= limit:
        return text
    return f"{text[:limit]}… ({len(text) - limit} more characters)"


def peek_passage_id(payload: bytes, window: int = 4096) -> str | None:
    """The passage id of an unparsed payload, when a valid one is in its first ``window`` bytes."""
    m = _PASSAGE_ID.search(payload[:window])
    return m.group(1).decode("ascii") if m else None


def payload_problem(size: int, measured: bool) -> str | None:
    """Why a payload of ``size`` bytes is refused unread, or None."""
    cap = MAX_MEASURED_PAYLOAD_BYTES if measured else MAX_PASSAGE_PAYLOAD_BYTES
    if size <= cap:
        return None
    what = "MeasuredPassage" if measured else "WheelPassage"
    return f"payload of {size} bytes is larger than the {cap} bytes a {what} may have; not read"


def nesting_too_deep(payload: bytes, limit: int = MAX_NESTING) -> bool:
    """Whether the JSON text nests objects/arrays deeper than ``limit`` (strings skipped).

    In C speed, whatever the payload: strings are cut out, the brackets kept, and each of
    ``limit`` passes removes the innermost pairs; a pair still left is deeper. Brackets that
    do not pair up (a truncated text) are left to the parser to report.
    """
    if payload.count(b"[") + payload.count(b"{") <= limit:
        return False
    brackets = _STRING.sub(b"", payload).translate(_BRACKET_MAP, _NOT_BRACKETS)
    for _ in range(limit):
        shorter = brackets.replace(b"()", b"")
        if len(shorter) == len(brackets):
            break
        brackets = shorter
    else:
        return b"()" in brackets
    return brackets.count(b"(") > limit  # what is left is ")))(((": unclosed levels


def structure_problem(payload: bytes, limit: int = MAX_NESTING) -> tuple[str, str] | None:
    """(type, message) when a payload is refused for its structure before it is parsed.

    ``json_too_deep``: nested deeper than ``limit``. ``too_many_brackets``: a payload larger
    than a passage may be (so a measurement) with more than ``limit`` brackets; a valid
    ``MeasuredPassage`` has one object and one array, and scanning such a payload for its
    depth would hold the interpreter for seconds.
    """
    count = payload.count(b"[") + payload.count(b"{")
    if count <= limit:
        return None
    if len(payload) > MAX_PASSAGE_PAYLOAD_BYTES:
        return "too_many_brackets", (
            f"{count} brackets in a payload of {len(payload)} bytes: a MeasuredPassage has one "
            "object and one array"
        )
    if nesting_too_deep(payload, limit):
        return "json_too_deep", f"JSON nested deeper than {limit} levels"
    return None


SAMPLES_BEYOND_ANY_LIMIT = 2**62
"""What ``passage_samples`` answers for a passage too slow to count (a speed of 1e-308 m/s
makes the count overflow a float): far above every limit, so it is refused as too long."""


def passage_samples(length: float, sample_rate: float, speed: float) -> int:
    """Samples of one passage: x from 0 to ``length`` at ``speed``, ``sample_rate`` Hz.

    >>> passage_samples(3.0, 2000.0, 30.0), passage_samples(3.0, 2000.0, 2.2e-308) > 10**18
    (201, True)
    """
    n = length / speed * sample_rate * (1.0 + 1e-12)
    if not n < SAMPLES_BEYOND_ANY_LIMIT:  # inf (or NaN) included
        return SAMPLES_BEYOND_ANY_LIMIT
    return math.floor(n) + 1


CHANNEL_BYTES_PER_SAMPLE = 25
"""Bytes a crib channel adds to each sample a passage publishes: one more float in the
result's JSON (``PassageResult.channels``), as ``OUTPUT_BYTES_PER_SAMPLE`` counts the others."""


def bytes_per_sample(cribs: int = 0) -> int:
    """Bytes a passage publishes per sample at a site with ``cribs`` crib channels."""
    return OUTPUT_BYTES_PER_SAMPLE + CHANNEL_BYTES_PER_SAMPLE * cribs


def site_cribs(site: SiteConfig) -> int:
    """How many crib channels each of the site's passages publishes."""
    return len(site.detector.cribs) if site.detector is not None else 0


def max_samples(cribs: int = 0) -> int:
    """The binding cap: the sample cap, or fewer if the output bytes cap is tighter (a site
    with many crib channels)."""
    return min(MAX_PASSAGE_SAMPLES, MAX_PASSAGE_OUTPUT_BYTES // bytes_per_sample(cribs))


def lowest_speed(length: float, sample_rate: float, cribs: int = 0) -> float:
    """The speed a passage must exceed at a site, m/s: length·sample_rate / max_samples().

    Above it a passage has at most ``max_samples(cribs)`` samples; at it, one more.
    """
    return length * sample_rate / max_samples(cribs)


def passage_problem(site: SiteConfig, passage: WheelPassage) -> tuple[str, str] | None:
    """(field, message) when a valid passage is still too much for this site, else None."""
    n = passage_samples(site.length, site.output_sample_rate, passage.speed)
    cribs = site_cribs(site)
    floor = lowest_speed(site.length, site.output_sample_rate, cribs)
    if n > MAX_PASSAGE_SAMPLES:
        return "speed", (
            f"speed {passage.speed:g} m/s would take {n} samples over the site "
            f"({site.length:g} m at {site.output_sample_rate:g} Hz), more than the "
            f"{MAX_PASSAGE_SAMPLES} a passage may have; the speed must be above {floor:.6g} m/s here"
        )
    out = n * bytes_per_sample(cribs)
    if out > MAX_PASSAGE_OUTPUT_BYTES:
        channels = f" with its {cribs} crib channels" if cribs else ""
        return "speed", (
            f"speed {passage.speed:g} m/s would publish about {out} bytes ({n} samples"
            f"{channels}), more than the {MAX_PASSAGE_OUTPUT_BYTES} bytes a passage may; the "
            f"speed must be above {floor:.6g} m/s here"
        )
    return None


def site_problem(site: SiteConfig) -> str | None:
    """Why a (resolved) site cannot be served, or None: its rail's points (a file rail too)."""
    x = getattr(site.rail, "x", None)
    if x is not None and len(x) > MAX_RAIL_POINTS:
        return (
            f"rail: {len(x)} points, more than the {MAX_RAIL_POINTS} a site's rail may have "
            "(resample the profile)"
        )
    return None
