"""What comes in: the Zenoh callbacks (they never block) and the queue to the worker.

A callback timestamps the payload, journals it (on disk before it is queued: it survives
``kill -9``) and queues it; a payload over its size limit, or one that finds the queue
full, is answered at once with a ``ServiceError``.
"""

from __future__ import annotations

import queue
import time
from typing import Final

import zenoh

from schemas.messages import ErrorKind, FieldProblem
from service.recording.input_journal import InputJournal
from service.twin.inbound import Inbound
from service.twin.output import Output
from service.wire import limits

LOGGED_PREFIX_BYTES = 4096
"""Bytes kept in the MCAP log of a payload refused for its size."""


class Stop:
    """Tells the worker to end, after what was queued before it."""


STOP: Final = Stop()


class Intake:
    """The Zenoh callbacks of the passage and measured subscribers, and their queue."""

    def __init__(self, output: Output, journal: InputJournal | None, capacity: int) -> None:
        self.output = output
        self.journal = journal
        self.capacity = capacity
        self.queue: queue.Queue[Inbound | Stop] = queue.Queue(maxsize=capacity)
        self.passages_received = 0
        self.measured_received = 0

    def on_passage(self, sample: zenoh.Sample) -> None:
        self.passages_received += 1
        self._take(sample, measured=False)

    def on_measured(self, sample: zenoh.Sample) -> None:
        self.measured_received += 1
        self._take(sample, measured=True)

    def next(self, timeout: float | None) -> Inbound | Stop | None:
        """The next input (``STOP`` to end); None when ``timeout`` s passed without one."""
        try:
            return self.queue.get(timeout=timeout)
        except queue.Empty:
            return None

    def stop(self) -> None:
        self.queue.put(STOP)

    def _take(self, sample: zenoh.Sample, measured: bool) -> None:
        """Queue an input; refuse it at once when it is too large or the queue is full."""
        received_ns, received_mono = time.time_ns(), time.monotonic()
        key = str(sample.key_expr)
        too_large = limits.payload_problem(len(sample.payload), measured)
        ticket = None
        if self.journal is not None:  # on disk before it is queued (survives kill -9)
            raw = sample.payload.to_bytes()
            ticket = self.journal.append(
                key, received_ns, raw if too_large is None else raw[:LOGGED_PREFIX_BYTES]
            )
        what = "measurement" if measured else "passage"
        if too_large is not None:  # refused unread: only its first bytes are logged
            head = sample.payload.to_bytes()[:LOGGED_PREFIX_BYTES]
            item = Inbound(key, head, received_ns, received_mono, ticket)
            self.output.log_input(item, None, payload_bytes=len(sample.payload))
            self.output.error(
                item,
                "invalid_measurement" if measured else "invalid_passage",
                f"{what} rejected: {too_large}",
                problems=[FieldProblem(field="", message=too_large, type="payload_too_large")],
                passage_id=limits.peek_passage_id(head),
            )
            return
        item = Inbound(
            key, sample.payload.to_bytes(), received_ns, received_mono, ticket, sender_of(sample)
        )
        try:
            self.queue.put_nowait(item)
        except queue.Full:
            self.output.log_input(item, None)
            self.output.error(
                item,
                "overloaded",
                f"{what} dropped: {self.capacity} inputs already waiting",
                passage_id=limits.peek_passage_id(item.payload),
            )


def sender_of(sample: zenoh.Sample) -> str | None:
    """The Zenoh id of the session that published ``sample``, if its publisher gave it."""
    info = sample.source_info
    return None if info is None else str(info.source_id.zid)


def refused_unread(output: Output, item: Inbound, measured: bool) -> bool:
    """Refuse JSON nested deeper than ``limits.MAX_NESTING`` before it is parsed."""
    problem = limits.structure_problem(item.payload)
    if problem is None:
        return False
    output.log_input(item, None)
    what = "measurement" if measured else "passage"
    error_type, message = problem
    kind: ErrorKind = (
        "invalid_json"
        if error_type == "json_too_deep"
        else ("invalid_measurement" if measured else "invalid_passage")
    )
    output.error(
        item,
        kind,
        f"{what} rejected before it was read: {message}",
        problems=[FieldProblem(field="", message=message, type=error_type)],
        passage_id=limits.peek_passage_id(item.payload),
    )
    return True
