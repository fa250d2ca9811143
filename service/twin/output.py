"""Everything the twin says goes out here: published on Zenoh, journaled, logged.

The Zenoh callbacks, the worker, the publisher and the pacer threads all publish through
one ``Output``; it counts the errors (for ``Health``).
"""

from __future__ import annotations

import base64
import logging
import threading
import time

import zenoh
from pydantic import BaseModel

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import (
    ErrorKind,
    FieldProblem,
    Health,
    PassageResult,
    PassageSeries,
    RailState,
    RejectedInput,
    ServiceError,
    WheelPassage,
)
from service.recording.input_journal import InputJournal
from service.recording.recorder import RecorderFront
from service.twin.errors import service_error
from service.twin.inbound import Inbound
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys

log = logging.getLogger("railtwin.twin")

JOURNALED_OUTPUTS: tuple[type[BaseModel], ...] = (PassageResult, Diagnosis, ServiceError)
"""Outputs also appended to the journal when published (the series are in the result)."""


class Output:
    """Publishes the twin's messages on one Zenoh session, journals and records them."""

    def __init__(
        self,
        keys: SiteKeys,
        session: zenoh.Session,
        *,
        recorder: RecorderFront | None,
        journal: InputJournal | None,
    ) -> None:
        self.keys = keys
        self.session = session
        self.recorder = recorder
        self.journal = journal
        self.encodings: dict[type[BaseModel], zenoh.Encoding] = {
            m: json_encoding(m)
            for m in (PassageSeries, PassageResult, ServiceError, RailState, Health, Diagnosis)
        }
        self.errors = 0
        self.last_error: ServiceError | None = None
        self._counts = threading.Lock()

    def put(
        self,
        key: str,
        topic: str,
        model: type[BaseModel],
        data: bytes,
        publish_time_ns: int | None = None,
    ) -> None:
        """Publish; log (MCAP with ``publish_time_ns``: the passage's own time, if given)."""
        self.session.put(
            key,
            data,
            encoding=self.encodings[model],
            congestion_control=zenoh.CongestionControl.BLOCK,
            express=True,
        )
        now = time.time_ns()
        ticket = None
        if self.journal is not None and model in JOURNALED_OUTPUTS:
            # the record of what the twin said, on disk now: the recorder may lag behind
            ticket = self.journal.append(topic, now, data)
        if self.recorder is not None:
            self.recorder.message(topic, model, data, now, publish_time_ns, ticket)

    def publish_error(self, error: ServiceError) -> None:
        with self._counts:  # the callbacks, the worker and the publisher all report errors
            self.errors += 1
            self.last_error = error
        # the twin's own trouble is the operator's; a bad input is its sender's
        level = (
            logging.WARNING if error.kind in ("simulation_failed", "overloaded") else logging.DEBUG
        )
        log.log(level, "%s (passage %s): %s", error.kind, error.passage_id, error.message)
        self.put(self.keys.error, self.keys.error, ServiceError, error.model_dump_json().encode())

    def error(
        self,
        item: Inbound,
        kind: ErrorKind,
        message: str,
        *,
        field: str | None = None,
        passage_id: str | None = None,
        problems: list[FieldProblem] | None = None,
    ) -> None:
        """Publish a ``ServiceError`` about ``item``."""
        self.publish_error(
            service_error(
                self.keys.site_id,
                kind,
                message,
                received_at=item.received_at,
                field=field,
                passage_id=passage_id,
                problems=problems,
            )
        )

    def log_input(
        self, item: Inbound, message: BaseModel | None, payload_bytes: int | None = None
    ) -> None:
        """Log an input: as the model it is, or (``message`` None) as a rejected input."""
        if self.recorder is None:
            return
        measured = item.key == self.keys.measured
        key = self.keys.measured if measured else self.keys.passage
        if message is not None:
            model = MeasuredPassage if measured else WheelPassage
            at = (
                round(message.timestamp * 1e9) if isinstance(message, WheelPassage) else None
            )  # the passage's own time, as publish_time in the log
            self.recorder.message(
                key, model, item.payload, item.received_ns, at, item.journal_ticket
            )
            return
        rejected = RejectedInput(
            key=item.key,
            payload_base64=base64.b64encode(item.payload).decode("ascii"),
            payload_text=item.payload.decode("utf-8", errors="replace"),
            payload_bytes=payload_bytes,
        )
        self.recorder.message(
            f"{key}/rejected",
            RejectedInput,
            rejected.model_dump_json().encode(),
            item.received_ns,
            None,
            item.journal_ticket,
        )
