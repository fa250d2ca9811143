"""Foxglove's conventions: ``foxglove.Log`` for errors and verdicts, one message per sample
for the series, so that Foxglove shows them as its users expect.

**Samples.** Foxglove's Plot panel plots a message path against the messages' timestamps
(log time by default, or a timestamp field of the message); a whole-passage message
(``.../result``, ``.../force``) can only be drawn as x against value of the latest one.
(Foxglove's own schemas have no scalar sample, so the schema is railtwin's.)
So for every ``PassageResult`` it logs, the recorder also writes one ``PassageSample`` per
sample on ``railtwin/<site>/samples``: log time and publish time = the sample's own time
(the passage's ``timestamp`` + x/speed), and the same time in a ``timestamp`` field
(Foxglove's ``{sec, nsec}``), with the passage id, x (m), force (N) and indentation (m).
``/railtwin/<site>/samples.force`` then plots every wheel's force against time, across
passages and files. Values have 7 significant digits. It costs the recorder ~10 ms a passage
and the MCAP ~40 bytes a sample (zstd; ~55 kB a wheel of ``make demo``, 1 351 samples),
so it is skipped, like a Rerun drawing, while the recorder is behind
(``RecordingPlan.samples_backlog_bytes``, 16 MB): the result holds the same series.

**Crib channels.** At a site with a detector each sample also carries ``channels``: crib
id → that crib's channel Q(x_a) − Q(x_b) at the sample, N (``PassageResult.channels``), so
``/railtwin/<site>/samples.channels.ch1`` plots crib ``ch1``'s channel against time beside
``.force``. A site without a detector writes no ``channels`` key: its samples are as before.

**Log.**
For every ``ServiceError`` and ``Diagnosis`` it logs, the recorder also writes a
``foxglove.Log`` on ``railtwin/<site>/log`` (JSON, schema named ``foxglove.Log``): the
error's kind and message (level WARNING; ERROR for ``simulation_failed``), or the wheel's
verdict with the flat found (INFO for ``ok`` and ``watch``, WARNING for ``inspect``, ERROR
for ``remove``). The messages themselves stay on their own channels.
"""

from __future__ import annotations

import json
from collections.abc import Iterator

from pydantic import BaseModel, ConfigDict, ValidationError

from schemas.diagnosis import Diagnosis
from schemas.messages import ServiceError

SCHEMA_NAME = "foxglove.Log"
SAMPLE_SCHEMA_NAME = "railtwin.PassageSample"

DEBUG, INFO, WARNING, ERROR, FATAL = 1, 2, 3, 4, 5
"""``foxglove.Log``'s levels."""

VERDICT_LEVELS = {"ok": INFO, "watch": INFO, "inspect": WARNING, "remove": ERROR}


class Time(BaseModel):
    """Foxglove's time: seconds and nanoseconds since the UNIX epoch."""

    model_config = ConfigDict(frozen=True)
    sec: int
    nsec: int


class Log(BaseModel):
    """``foxglove.Log`` (the class is named after the schema: ``model_for_schema``)."""

    model_config = ConfigDict(frozen=True)
    timestamp: Time
    level: int
    message: str
    name: str
    file: str = ""
    line: int = 0


def log_topic(topic: str) -> str:
    """``railtwin/<site>/log`` for a message of ``railtwin/<site>/<kind>``."""
    return topic.rsplit("/", 1)[0] + "/log"


def log_entry(model_name: str, data: bytes, time_ns: int) -> Log | None:
    """The ``foxglove.Log`` of a logged ServiceError or Diagnosis; None for anything else
    (or a message that does not parse: the log is not where that is reported)."""
    stamp = Time(sec=time_ns // 1_000_000_000, nsec=time_ns % 1_000_000_000)
    try:
        if model_name == ServiceError.__name__:
            e = ServiceError.model_validate_json(data)
            level = ERROR if e.kind == "simulation_failed" else WARNING
            about = f" (passage {e.passage_id})" if e.passage_id else ""
            return Log(
                timestamp=stamp,
                level=level,
                message=f"{e.kind}{about}: {e.message}",
                name="railtwin.twin",
            )
        if model_name == Diagnosis.__name__:
            d = Diagnosis.model_validate_json(data)
            flat = "no flat" if d.flat is None else f"{d.flat.kind} {d.flat.length * 1e3:.1f} mm"
            reasons = f" ({'; '.join(d.reasons)})" if d.reasons else ""
            return Log(
                timestamp=stamp,
                level=VERDICT_LEVELS[d.verdict],
                message=f"passage {d.passage_id}: {d.verdict}, {flat}{reasons}",
                name="railtwin.diagnosis",
            )
    except ValidationError:
        return None
    return None


class PassageSample(BaseModel):
    """One sample of a passage, at its own time (the class is named after the schema)."""

    model_config = ConfigDict(frozen=True)
    timestamp: Time
    passage_id: str
    x: float
    """wheel centre position along the site, m"""
    force: float
    """contact force F, N"""
    indentation: float
    """indentation δ, m (negative: out of contact)"""
    channels: dict[str, float] | None = None
    """crib id -> the crib's channel Q(x_a) − Q(x_b), N; only at a site with a detector"""


def samples_topic(topic: str) -> str:
    """``railtwin/<site>/samples`` for a message of ``railtwin/<site>/<kind>``."""
    return topic.rsplit("/", 1)[0] + "/samples"


def samples(result_json: bytes) -> Iterator[tuple[int, bytes]]:
    """(time in UNIX ns, ``PassageSample`` JSON) of every sample of a ``PassageResult``'s
    JSON; nothing for JSON that is not one. Values have 7 significant digits (a plot's
    precision; the result has them exact): a quarter less MCAP than all 17. A result with
    ``channels`` (a site with a detector) gives each sample its channels' values too.

    >>> r = b'{"passage_id": "p1", "timestamp": 10.0, "speed": 40.0, "x": [0.0, 0.4],'
    >>> r += b' "force": [1.0, 2.5e5], "indentation": [0.0, 1e-4]'
    >>> [(t, PassageSample.model_validate_json(d).force) for t, d in samples(r + b'}')]
    [(10000000000, 1.0), (10010000000, 250000.0)]
    >>> r += b', "channels": {"ch1": [0.0, 2.4e5]}}'
    >>> [PassageSample.model_validate_json(d).channels for _, d in samples(r)]
    [{'ch1': 0.0}, {'ch1': 240000.0}]
    """
    try:
        r = json.loads(result_json)
        pid, t0, speed = json.dumps(str(r["passage_id"])), float(r["timestamp"]), float(r["speed"])
        xs, fs, ds = r["x"], r["force"], r["indentation"]
        channels: dict[str, list[float]] = r.get("channels") or {}
        names = [json.dumps(str(c)) for c in channels]
        columns = [[float(v) for v in c] for c in channels.values()]
    except (ValueError, KeyError, TypeError, AttributeError):
        return
    pairs = list(zip(names, columns, strict=True))
    if any(len(c) != len(xs) for c in columns):  # not a valid result: its series alone
        pairs = []
    for i, (x, f, d) in enumerate(zip(xs, fs, ds, strict=False)):
        ns = round((t0 + x / speed) * 1e9)
        sec, nsec = divmod(ns, 1_000_000_000)
        crib = (
            ',"channels":{' + ",".join(f"{n}:{c[i]:.7g}" for n, c in pairs) + "}" if pairs else ""
        )
        yield (
            ns,
            (
                f'{{"timestamp":{{"sec":{sec},"nsec":{nsec}}},"passage_id":{pid},'
                f'"x":{x:.7g},"force":{f:.7g},"indentation":{d:.7g}{crib}}}'
            ).encode(),
        )
