"""Foxglove's well-known ``foxglove.Log`` on a channel of its own, so that the twin's errors
and verdicts show in Foxglove's Log panel.

For every ``ServiceError`` and ``Diagnosis`` it logs, the recorder also writes a
``foxglove.Log`` on ``railtwin/<site>/log`` (JSON, schema named ``foxglove.Log``): the
error's kind and message (level WARNING; ERROR for ``simulation_failed``), or the wheel's
verdict with the flat found (INFO for ``ok`` and ``watch``, WARNING for ``inspect``, ERROR
for ``remove``). The messages themselves stay on their own channels.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, ValidationError

from schemas.diagnosis import Diagnosis
from schemas.messages import ServiceError

SCHEMA_NAME = "foxglove.Log"

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
            return Log(timestamp=stamp, level=level, message=f"{e.kind}{about}: {e.message}",
                       name="railtwin.twin")
        if model_name == Diagnosis.__name__:
            d = Diagnosis.model_validate_json(data)
            flat = ("no flat" if d.flat is None else
                    f"{d.flat.kind} {d.flat.length * 1e3:.1f} mm")
            reasons = f" ({'; '.join(d.reasons)})" if d.reasons else ""
            return Log(timestamp=stamp, level=VERDICT_LEVELS[d.verdict],
                       message=f"passage {d.passage_id}: {d.verdict}, {flat}{reasons}",
                       name="railtwin.diagnosis")
    except ValidationError:
        return None
    return None
