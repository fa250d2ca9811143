"""Republish the inputs of an MCAP log onto Zenoh, in their original timing.

A log is data, not instructions: whatever its channels are called, a replay
publishes only to the two input keys of one site, ``railtwin/<site>/passage`` and
``railtwin/<site>/measured``, and only payloads that are valid against their model.

- **Which messages.** Only the twin's input channels are read:
  ``railtwin/<s>/passage`` (schema ``railtwin.WheelPassage/1.0``),
  ``railtwin/<s>/measured`` (``railtwin.MeasuredPassage/1.0``) and their
  ``.../rejected`` channels (``railtwin.RejectedInput/1.0``, the payload kept verbatim
  in base64). Every other channel (the twin's outputs, or a topic a crafted log
  names) is skipped and counted, and so is an input channel with the wrong schema.
- **Which site.** ``site_id`` (``--site``) when given; otherwise the log's site, when
  exactly one site's inputs are in it. A log with the inputs of several sites needs
  ``--site`` naming one of them, and only that site's inputs are replayed. A log of one
  site replayed with ``--site`` another id goes to that site's keys.
- **Which payloads.** Each payload is checked as the twin checks it before
  simulating: its size cap, its JSON nesting, then its model (``WheelPassage`` or
  ``MeasuredPassage``), wherever it was logged. A valid one is sent. An invalid one
  (the log's rejected inputs, or a crafted "valid" one) is sent only with
  ``include_rejected``. A rejected input that was logged cut (too large, only its
  head kept) is never sent.
- **Cut logs.** Logs are read with ``service.recording.mcap_recover.salvage``, so a log whose
  writer was killed (no footer) replays up to its last complete chunk.

    >>> plan = plan_replay([], site_id="km12")
    >>> plan.site_id, plan.inputs
    ('km12', [])
"""

from __future__ import annotations

import base64
import binascii
import re
import time
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import zenoh
from pydantic import BaseModel, ValidationError

from schemas.diagnosis import MeasuredPassage
from schemas.messages import RejectedInput, WheelPassage, encoding_schema, is_encoding_of
from service.clients.feeder import wait_matching
from service.recording.mcap_log import LoggedMessage
from service.recording.mcap_recover import RecoveryReport, salvage
from service.wire import limits
from service.wire.keyspace import SiteKeys

InputKind = Literal["passage", "measured"]

INPUT_TOPIC = re.compile(r"railtwin/([A-Za-z0-9_.\-]{1,96})/(passage|measured)(/rejected)?")
"""An input channel of the twin's log: site, kind, and whether it holds rejected inputs."""

MODELS: dict[InputKind, type[BaseModel]] = {"passage": WheelPassage, "measured": MeasuredPassage}


class ReplayError(ValueError):
    """The log cannot be replayed as asked (e.g. which site is ambiguous)."""


@dataclass(frozen=True)
class LoggedInput:
    """One input to send: when it was received (log time, ns), its kind and its bytes."""

    log_time_ns: int
    kind: InputKind
    payload: bytes
    valid: bool = True
    problem: str | None = None
    """Why it is invalid (the first problem), for an input sent with ``include_rejected``."""


@dataclass
class ReplayPlan:
    """What a replay sends (``inputs``, in log-time order) and what it leaves out."""

    site_id: str
    """The site whose input keys are published to."""
    logged_sites: list[str] = field(default_factory=list)
    """The sites whose inputs are in the log."""
    inputs: list[LoggedInput] = field(default_factory=list)
    rejected_skipped: int = 0
    """Invalid inputs left out (sent only with ``include_rejected``)."""
    truncated: int = 0
    """Rejected inputs logged cut (only their head kept): never sent."""
    damaged: int = 0
    """Records of a rejected-input channel that are not a readable ``RejectedInput``."""
    other_sites: int = 0
    """Inputs of the log's other sites, left out."""
    skipped_channels: Counter[str] = field(default_factory=Counter)
    """Messages left out by channel topic: the twin's outputs, and any topic that is not an
    input channel with its schema."""

    def count(self, kind: InputKind, valid: bool = True) -> int:
        return sum(1 for i in self.inputs if i.kind == kind and i.valid == valid)

    def unknown_channels(self) -> list[str]:
        """Skipped topics that are not the twin's own outputs: a log from elsewhere, or a
        crafted one."""
        out = []
        for topic in self.skipped_channels:
            parts = topic.split("/")
            own_output = (
                len(parts) == 3
                and parts[0] == "railtwin"
                and parts[2] in ("force", "indentation", "result", "diagnosis", "error")
            )
            if not own_output:
                out.append(topic)
        return sorted(out)


def check_payload(kind: InputKind, payload: bytes) -> str | None:
    """Why the twin would refuse ``payload`` on its ``kind`` key, or None when it is valid."""
    problem = limits.payload_problem(len(payload), kind == "measured")
    if problem is not None:
        return problem
    if limits.nesting_too_deep(payload):
        return f"JSON nested deeper than {limits.MAX_NESTING} levels"
    try:
        MODELS[kind].model_validate_json(payload)
    except ValidationError as exc:
        e = exc.errors()[0]
        where = ".".join(str(p) for p in e["loc"])
        return limits.clip(f"{where}: {e['msg']}" if where else e["msg"])
    return None


def _classify(m: LoggedMessage) -> tuple[str, InputKind, bool] | None:
    """(logged site, kind, rejected channel) of an input channel with its own schema."""
    match = INPUT_TOPIC.fullmatch(m.topic)
    if match is None:
        return None
    site, kind_text, rejected = match.group(1), match.group(2), match.group(3) is not None
    kind: InputKind = "passage" if kind_text == "passage" else "measured"
    if not is_encoding_of(m.schema_name, RejectedInput if rejected else MODELS[kind]):
        return None  # not its schema (any 1.x of it is: a log of an older twin replays)
    return site, kind, rejected


def plan_replay(
    messages: Iterable[LoggedMessage],
    *,
    site_id: str | None = None,
    include_rejected: bool = False,
) -> ReplayPlan:
    """Which inputs of ``messages`` (a log, in log-time order) a replay sends, and where.

    Raises ``ReplayError`` when ``site_id`` is not a valid site id, or when it is not
    given and the log holds the inputs of several sites or of none.
    """
    if site_id is not None and limits.valid_id(site_id) is None:
        raise ReplayError(
            f"--site {site_id!r} is not a site id ([A-Za-z0-9_.-], 1 to "
            f"{limits.MAX_ID_LENGTH} characters)"
        )
    found: list[tuple[LoggedMessage, str, InputKind, bool]] = []
    skipped: Counter[str] = Counter()
    for m in messages:
        c = _classify(m)
        if c is None:
            skipped[m.topic] += 1
        else:
            found.append((m, *c))
    sites = sorted({site for _, site, _, _ in found})
    if site_id is not None:
        source = site_id if len(sites) > 1 else (sites[0] if sites else site_id)
        if len(sites) > 1 and site_id not in sites:
            raise ReplayError(
                f"the log holds the inputs of sites {', '.join(sites)}: "
                "--site must name one of them"
            )
    elif len(sites) == 1:
        source = site_id = sites[0]
    elif sites:
        raise ReplayError(
            f"the log holds the inputs of several sites ({', '.join(sites)}): "
            "say which one with --site"
        )
    else:
        raise ReplayError("the log holds no site's inputs: give --site to replay it anyway")
    plan = ReplayPlan(site_id=site_id, logged_sites=sites, skipped_channels=skipped)
    for m, site, kind, rejected in found:
        if site != source:
            plan.other_sites += 1
            continue
        payload = m.data
        if rejected:
            try:
                r = RejectedInput.model_validate_json(m.data)
                payload = base64.b64decode(r.payload_base64, validate=True)
            except (ValidationError, binascii.Error):
                plan.damaged += 1
                continue
            if r.payload_bytes is not None and r.payload_bytes != len(payload):
                plan.truncated += 1
                continue
        problem = check_payload(kind, payload)
        if problem is not None and not include_rejected:
            plan.rejected_skipped += 1
            continue
        plan.inputs.append(LoggedInput(m.log_time_ns, kind, payload, problem is None, problem))
    plan.inputs.sort(key=lambda i: i.log_time_ns)
    return plan


def read_logs(paths: Sequence[Path], report: RecoveryReport | None = None) -> list[LoggedMessage]:
    """Every complete message of ``paths`` (finished or cut logs), in log-time order; where a
    file is cut is added to ``report.damaged``."""
    msgs: list[LoggedMessage] = []
    for p in sorted(paths):
        msgs.extend(salvage(p, report))
    msgs.sort(key=lambda m: m.log_time_ns)
    return msgs


def replay(
    session: zenoh.Session,
    plan: ReplayPlan,
    *,
    rate: float = 1.0,
    match_timeout: float = 10.0,
) -> int:
    """Publish ``plan.inputs`` to the input keys of ``plan.site_id``, with their original
    spacing divided by ``rate`` (<= 0: no waits).

    Waits up to ``match_timeout`` s for a subscriber on each key first.
    Returns the number of messages published.
    """
    keys = SiteKeys(plan.site_id)
    key_of: dict[InputKind, str] = {"passage": keys.passage, "measured": keys.measured}
    publishers: dict[InputKind, zenoh.Publisher] = {}
    for kind in sorted({i.kind for i in plan.inputs}):
        encoding = zenoh.Encoding.APPLICATION_JSON.with_schema(encoding_schema(MODELS[kind]))
        pub = session.declare_publisher(
            key_of[kind],
            encoding=encoding,
            congestion_control=zenoh.CongestionControl.BLOCK,
            express=True,
        )
        wait_matching(pub, match_timeout)
        publishers[kind] = pub
    if not plan.inputs:
        return 0
    start = time.monotonic()
    first = plan.inputs[0].log_time_ns
    for item in plan.inputs:
        if rate > 0:
            delay = start + (item.log_time_ns - first) / 1e9 / rate - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        publishers[item.kind].put(item.payload)
    for pub in publishers.values():
        pub.undeclare()
    return len(plan.inputs)
