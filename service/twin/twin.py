"""The streaming twin of one site: passages in over Zenoh, forces and indentations out.

Pipeline, per message on ``railtwin/<site>/passage``:

1. the Zenoh callback only timestamps the payload and queues it (``Intake``: it never
   blocks Zenoh; a full queue gets an ``overloaded`` ServiceError);
2. one worker thread, in arrival order: validate (a bad input becomes a
   ``ServiceError`` naming the field, on ``railtwin/<site>/error``) →
   simulate (through the physics port, ``service.physics.port.PhysicsPort``) → publish
   ``force/<p>``, ``indentation/<p>`` and ``result/<p>`` (``Simulation``);
3. the recorder logs every received and published message to MCAP and draws the passage
   in Rerun (``Output``).

With ``pace="realtime"`` the series are published in chunks when the wheel
would reach their end (``Pacer``), and the result when it leaves the site.
Queryables answer ``railtwin/<site>/rail`` (``RailState``), ``railtwin/<site>/health``
and ``railtwin/health`` (``Health``), and ``railtwin/<site>/diagnoses?since=<unix s>``
(catch-up: one ``Diagnosis`` per reply, ``service.twin.diagnoses``). Every queryable
replies on its own concrete key, never on the query's (a wildcard query such as
``railtwin/*/health`` gets one reply per twin).

Diagnosis (when the port diagnoses: the site's own physics): measured passages come in on
``railtwin/<site>/measured`` (``MeasuredPassage``) through the same queue and worker and are
paired with their passage (``Pairing``; the last 10 000 valid passages are kept, at most
1 000 measurements wait); the ``Diagnosis`` goes out on
``railtwin/<site>/diagnosis/<passage>``.
"""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Any

import zenoh

from schemas.diagnosis import Diagnosis
from schemas.messages import Health, RailState, WheelPassage
from schemas.site import SiteConfig
from service.physics.port import PhysicsPort
from service.recording.input_journal import InputJournal
from service.recording.recorder import RecorderFront
from service.twin.diagnoses import MAX_REPLIES, DiagnosisStore, SinceError, parse_since
from service.twin.inbound import Inbound
from service.twin.intake import Intake, Stop
from service.twin.kept_passages import KeptPassages
from service.twin.output import Output
from service.twin.pacer import Pacer
from service.twin.pairing import Pairing
from service.twin.simulation import Pace, Simulation
from service.wire.keyspace import HEALTH_KEY, SiteKeys

__all__ = ["Inbound", "Pace", "Twin"]


class Twin:
    """The service of one site on an open Zenoh session (the caller owns the session)."""

    def __init__(
        self,
        site: SiteConfig,
        session: zenoh.Session,
        physics: PhysicsPort,
        *,
        recorder: RecorderFront | None = None,
        journal: InputJournal | None = None,
        pace: Pace = "fast",
        chunk_period: float = 0.02,
        queue_capacity: int = 10_000,
        diagnoses: DiagnosisStore | None = None,
    ) -> None:
        self.site = site
        self.keys = SiteKeys(site.site_id)
        self.session = session
        self.physics = physics
        self.recorder = recorder
        self.pace = pace
        self.output = Output(self.keys, session, recorder=recorder, journal=journal)
        self.intake = Intake(self.output, journal, queue_capacity)
        self.pacer = Pacer(self.output) if pace == "realtime" else None
        passages: KeptPassages[WheelPassage] = KeptPassages()
        self.simulation = Simulation(
            site,
            self.output,
            physics,
            passages,
            pace=pace,
            chunk_period=chunk_period,
            pacer=self.pacer,
        )
        self.pairing = Pairing(
            site,
            self.output,
            physics,
            passages,
            before_diagnosis=self.simulation.drain,
            diagnoses=diagnoses,
        )
        self.diagnoses = self.pairing.diagnoses
        self.started_at = time.time()
        self._started_mono = time.monotonic()
        self._worker = threading.Thread(target=self._work, name="railtwin-worker", daemon=True)
        self._declared: list[Any] = []
        self._stop_by: float | None = None

    @property
    def passages_done(self) -> int:
        return self.simulation.done

    @property
    def diagnoses_done(self) -> int:
        return self.pairing.done

    # --- life cycle --------------------------------------------------------------------

    def start(self) -> None:
        """Declare the subscriber and queryables, start the threads."""
        if self.recorder is not None:
            self.recorder.rail(self.physics.rail_state())
        self._worker.start()
        self.simulation.start()
        if self.pacer is not None:
            self.pacer.start()
        s = self.session
        self._declared = [
            s.declare_queryable(self.keys.rail, self._on_rail_query),
            s.declare_queryable(HEALTH_KEY, lambda q: self._on_health_query(q, HEALTH_KEY)),
            s.declare_queryable(
                self.keys.health, lambda q: self._on_health_query(q, self.keys.health)
            ),
            s.declare_queryable(self.keys.diagnoses, self._on_diagnoses_query),
            s.declare_subscriber(self.keys.passage, self.intake.on_passage),
            s.declare_subscriber(self.keys.measured, self.intake.on_measured),
            # clients see the twin come and go: a liveliness subscriber gets PUT/DELETE
            s.liveliness().declare_token(self.keys.alive),
        ]

    def stop(self, deadline: float | None = None) -> None:
        """Stop taking input, finish what is queued (paced output at once), close the log.

        ``deadline`` (monotonic s): inputs still queued then are not served; each gets an
        ``overloaded`` error (it is in the journal all the same)."""
        self._stop_by = deadline
        for d in reversed(self._declared):
            with contextlib.suppress(Exception):  # the session may already be closing
                d.undeclare()
        self._declared = []
        self.intake.stop()
        if self._worker.is_alive():
            self._worker.join()
        self.simulation.stop()
        if self.pacer is not None:
            self.pacer.stop()
        if self.recorder is not None:
            self.recorder.close()

    # --- the worker thread -------------------------------------------------------------

    def _work(self) -> None:
        while True:
            deadline = self.pairing.next_deadline()
            timeout = None if deadline is None else max(0.0, deadline - time.monotonic())
            item = self.intake.next(timeout)
            if isinstance(item, Stop):
                return
            if item is not None and self._too_late(item):
                continue
            if item is not None:
                try:
                    self.serve(item)
                except Exception as exc:  # never let one input kill the service
                    self.output.error(
                        item, "simulation_failed", f"internal error: {type(exc).__name__}: {exc}"
                    )
            self.pairing.expire()

    def _too_late(self, item: Inbound) -> bool:
        """Past the stop deadline: ``item`` is answered, not served."""
        if self._stop_by is None or time.monotonic() < self._stop_by:
            return False
        what = "measurement" if item.key == self.keys.measured else "passage"
        self.output.error(
            item, "overloaded", f"{what} dropped: the service stopped before its turn came"
        )
        return True

    def serve(self, item: Inbound) -> None:
        """One input off the queue: a measured passage, or a passage."""
        if item.key == self.keys.measured:
            self.pairing.serve(item)
            return
        passage = self.simulation.accept(item)
        if passage is None:
            return
        try:
            self.simulation.simulate(item, passage)
        finally:  # the result goes out first; then the measurement waiting for it
            self.pairing.passage_came(passage)

    # --- queryables --------------------------------------------------------------------

    def _on_rail_query(self, query: zenoh.Query) -> None:
        with query:
            try:
                data = self.physics.rail_state().model_dump_json().encode()
                query.reply(self.keys.rail, data, encoding=self.output.encodings[RailState])
            except Exception as exc:
                query.reply_err(f"rail state unavailable: {exc}")

    def _on_health_query(self, query: zenoh.Query, key: str) -> None:
        with query:  # on the queryable's own key: a wildcard query gets one reply per twin
            data = self.health().model_dump_json().encode()
            query.reply(key, data, encoding=self.output.encodings[Health])

    def _on_diagnoses_query(self, query: zenoh.Query) -> None:
        """Catch-up: every Diagnosis made (or of a passage) since ``?since=<unix s>``."""
        with query:
            try:
                since = parse_since(query.parameters.get("since"))
            except SinceError as exc:
                query.reply_err(f"{self.keys.diagnoses}: {exc}")
                return
            if query.accepts_replies() != zenoh.ReplyKeyExpr.ANY:
                query.reply_err(
                    f"{self.keys.diagnoses}: each diagnosis is answered on its own key "
                    f"{self.keys.diagnosis('<passage_id>')}: query with "
                    "accept_replies=zenoh.ReplyKeyExpr.ANY (or add the parameter _anyke: "
                    "?since=T;_anyke)"
                )
                return
            rows = self.diagnoses.since(since, limit=MAX_REPLIES)
            for pid, data in rows:
                query.reply(
                    self.keys.diagnosis(pid), data, encoding=self.output.encodings[Diagnosis]
                )
            if len(rows) >= MAX_REPLIES:  # the oldest first: the querier asks again from there
                query.reply_err(
                    f"{self.keys.diagnoses}: answer cut at {MAX_REPLIES} diagnoses "
                    "(the oldest made first): ask again with a later since"
                )

    def health(self) -> Health:
        mcap_path = self.recorder.mcap_path() if self.recorder is not None else None
        rrd_path = self.recorder.rrd_path() if self.recorder is not None else None
        return Health(
            site_id=self.site.site_id,
            started_at=self.started_at,
            uptime=time.monotonic() - self._started_mono,
            passages_received=self.intake.passages_received,
            passages_done=self.passages_done,
            passages_without_wheel=self.simulation.without_wheel,
            errors=self.output.errors,
            queue_depth=self.intake.queue.qsize(),
            queue_capacity=self.intake.capacity,
            last_error=self.output.last_error,
            mcap_path=mcap_path,
            rrd_path=rrd_path,
            calibration=self.pairing.calibration,
        )
