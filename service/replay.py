"""Republish the inputs of an MCAP log onto Zenoh, in their original timing.

The inputs are the messages the twin received: valid passages (channel
``railtwin/<site>/passage``) and rejected ones (``.../passage/rejected``, kept
verbatim), in log-time order; each goes out with the exact bytes that came
in, so a fresh twin fed a replay computes the same outputs.
"""

from __future__ import annotations

import base64
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import zenoh

from schemas.messages import RejectedInput, WheelPassage, encoding_schema
from service.feeder import wait_matching
from service.mcap_log import read_log


@dataclass(frozen=True)
class LoggedInput:
    """One received payload: when (log time, ns), on which key, the bytes."""

    log_time_ns: int
    key: str
    payload: bytes


def logged_inputs(paths: Sequence[Path]) -> list[LoggedInput]:
    """The received payloads of a log (its rotated parts together), in log-time order."""
    out = []
    for m in read_log(list(paths)):
        if m.schema_name == encoding_schema(WheelPassage):
            out.append(LoggedInput(m.log_time_ns, m.topic, m.data))
        elif m.schema_name == encoding_schema(RejectedInput):
            r = RejectedInput.model_validate_json(m.data)
            out.append(LoggedInput(m.log_time_ns, r.key, base64.b64decode(r.payload_base64)))
    out.sort(key=lambda i: i.log_time_ns)
    return out


def retarget(key: str, site_id: str | None) -> str:
    """``railtwin/<old>/passage`` → ``railtwin/<site_id>/passage``."""
    if site_id is None:
        return key
    parts = key.split("/")
    if len(parts) >= 3 and parts[0] == "railtwin":
        parts[1] = site_id
    return "/".join(parts)


def replay(
    session: zenoh.Session,
    inputs: Sequence[LoggedInput],
    *,
    rate: float = 1.0,
    site_id: str | None = None,
    match_timeout: float = 10.0,
) -> int:
    """Publish ``inputs`` with their original spacing divided by ``rate`` (<= 0: no waits).

    Waits up to ``match_timeout`` s for a subscriber on each key first.
    Returns the number of messages published.
    """
    encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(encoding_schema(WheelPassage))
    publishers: dict[str, zenoh.Publisher] = {}
    for item in inputs:
        key = retarget(item.key, site_id)
        if key not in publishers:
            pub = session.declare_publisher(
                key, encoding=encoding, congestion_control=zenoh.CongestionControl.BLOCK,
                express=True,
            )
            wait_matching(pub, match_timeout)
            publishers[key] = pub
    if not inputs:
        return 0
    start = time.monotonic()
    first = inputs[0].log_time_ns
    for item in inputs:
        if rate > 0:
            delay = start + (item.log_time_ns - first) / 1e9 / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        publishers[retarget(item.key, site_id)].put(item.payload)
    for pub in publishers.values():
        pub.undeclare()
    return len(inputs)
