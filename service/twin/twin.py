"""The streaming twin of one site: passages in over Zenoh, forces and indentations out.

Pipeline, per message on ``railtwin/<site>/passage``:

1. the Zenoh callback only timestamps the payload and queues it (it never
   blocks Zenoh; a full queue gets an ``overloaded`` ServiceError);
2. one worker thread, in arrival order: validate (a bad input becomes a
   ``ServiceError`` naming the field, on ``railtwin/<site>/error``) →
   simulate (the injected ``PassageSimulator``) → publish ``force/<p>``,
   ``indentation/<p>`` and ``result/<p>``;
3. the ``Recorder`` thread logs every received and published message to MCAP
   and draws the passage in Rerun.

With ``pace="realtime"`` the series are published in chunks when the wheel
would reach their end (a pacer thread), and the result when it leaves the site.
Queryables answer ``railtwin/<site>/rail`` (``RailState``) and
``railtwin/health`` (``Health``).

Diagnosis (with the site's own physics, ``SitePhysics``): measured passages come in on
``railtwin/<site>/measured`` (``MeasuredPassage``) through the same queue and worker.
The worker pairs each with the ``WheelPassage`` of the same ``passage_id``, in either
order of arrival (the last 10 000 valid passages are kept; at most 1 000 measurements
wait), diagnoses it (``service.physics.diagnosis.Diagnoser``) and publishes the ``Diagnosis``
on ``railtwin/<site>/diagnosis/<passage>``. A measurement whose passage has not come
within the site's ``diagnosis.pairing_timeout`` gets an ``unpaired`` ServiceError; a
bad or duplicate one an ``invalid_measurement`` one (``invalid_json`` if not JSON).
"""

from __future__ import annotations

import base64
import contextlib
import heapq
import json
import queue
import sys
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

import zenoh
from pydantic import BaseModel, ValidationError

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.errors import format_path
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
    encoding_schema,
)
from schemas.site import SiteConfig
from service.physics.port import PassageSimulator
from service.physics.worker import (
    BudgetExceededError,
    DiagnosisOutcome,
    MeasurementError,
    Series,
    WorkerCrashedError,
    diagnose_locally,
    series_json,
)
from service.recording.input_journal import InputJournal
from service.recording.recorder import RecorderFront
from service.twin.kept_passages import KeptPassages
from service.wire import limits
from service.wire.keyspace import HEALTH_KEY, SiteKeys

DiagnoseFn = Callable[[WheelPassage, MeasuredPassage], DiagnosisOutcome]

LOGGED_PREFIX_BYTES = 4096
"""Bytes kept in the MCAP log of a payload refused for its size."""

Pace = Literal["fast", "realtime"]


def json_encoding(model: type[BaseModel]) -> zenoh.Encoding:
    """``application/json;railtwin.<Model>/<version>``."""
    return zenoh.Encoding.APPLICATION_JSON.with_schema(encoding_schema(model))


JOURNALED_OUTPUTS: tuple[type[BaseModel], ...] = (PassageResult, Diagnosis, ServiceError)
"""Outputs also appended to the journal when published (the series are in the result)."""


@dataclass(frozen=True)
class Inbound:
    """A payload as it arrived, before anything was made of it."""

    key: str
    payload: bytes
    received_ns: int
    received_mono: float


@dataclass(order=True)
class _Due:
    """A paced publication: at ``due`` (monotonic s)."""

    due: float
    seq: int
    key: str = field(compare=False)
    model: type[BaseModel] = field(compare=False)
    data: bytes = field(compare=False)


@dataclass(frozen=True)
class _Waiting:
    """A valid measurement waiting for its passage."""

    measured: MeasuredPassage
    item: Inbound
    deadline: float


_STOP = object()

MAX_WAITING_MEASUREMENTS = 1_000
"""Measurements waiting for their passage; beyond, the oldest is dropped as unpaired."""

KEPT_DIAGNOSED = 10_000
"""Passage ids already diagnosed (by id, the latest): a second measurement is refused."""


def service_error_from_validation(
    exc: ValidationError, payload: bytes, site_id: str, received_at: float,
    model: type[BaseModel] = WheelPassage,
) -> ServiceError:
    """A ServiceError naming the offending fields of a payload that is not a ``model``
    (a WheelPassage: kind ``invalid_passage``; a MeasuredPassage: ``invalid_measurement``)."""
    try:
        raw: Any = json.loads(payload)
    except ValueError:
        raw = None
    problems = []
    errors = exc.errors(include_url=False)
    for e in errors[:limits.MAX_PROBLEMS]:  # paths and messages clipped: inputs are not echoed
        path = limits.clip(format_path(tuple(e["loc"]), raw, e.get("ctx")))
        ctx = e.get("ctx") or {}
        custom = e["type"] == "invalid_field" and "reason" in ctx
        message = limits.clip(str(ctx["reason"]) if custom else e["msg"])
        problems.append(FieldProblem(field=path, message=message, type=e["type"]))
    invalid_json = any(p.type == "json_invalid" for p in problems)
    first = problems[0] if problems else None
    field_name = first.field if first is not None and first.field else None
    head = "not JSON" if invalid_json else f"not a valid {model.__name__}"
    detail = f"{first.field or '(whole message)'}: {first.message}" if first else ""
    more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
    passage_id = raw.get("passage_id") if isinstance(raw, dict) else None
    measurement = model is MeasuredPassage
    invalid: ErrorKind = "invalid_measurement" if measurement else "invalid_passage"
    what = "measurement" if measurement else "passage"
    return ServiceError(
        site_id=site_id,
        kind="invalid_json" if invalid_json else invalid,
        message=f"{what} rejected, {head}: {detail}{more}",
        field=field_name,
        problems=problems,
        passage_id=limits.valid_id(passage_id),
        received_at=received_at,
    )


class Twin:
    """The service of one site on an open Zenoh session (the caller owns the session)."""

    def __init__(
        self,
        site: SiteConfig,
        session: zenoh.Session,
        physics: PassageSimulator,
        *,
        recorder: RecorderFront | None = None,
        journal: InputJournal | None = None,
        pace: Pace = "fast",
        chunk_period: float = 0.02,
        queue_capacity: int = 10_000,
    ) -> None:
        self.site = site
        self.journal = journal
        self.keys = SiteKeys(site.site_id)
        self.session = session
        self.physics = physics
        self.recorder = recorder
        self.pace = pace
        self.chunk_period = chunk_period
        self.queue_capacity = queue_capacity
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=queue_capacity)
        self._encodings: dict[type[BaseModel], zenoh.Encoding] = {
            m: json_encoding(m)
            for m in (PassageSeries, PassageResult, ServiceError, RailState, Health, Diagnosis)
        }
        self.started_at = time.time()
        self._started_mono = time.monotonic()
        self.passages_received = 0
        self.passages_done = 0
        self.errors = 0
        self._counts = threading.Lock()
        self.last_error: ServiceError | None = None
        self.measured_received = 0
        self.diagnoses_done = 0
        self.diagnoser: DiagnoseFn | None = None
        site_physics = sys.modules.get("service.physics.site_physics")  # loaded if physics is one
        if getattr(physics, "diagnoses", False):  # a ProcessPhysics: diagnosed in its worker
            self.diagnoser = physics.diagnose  # type: ignore[attr-defined]
        elif site_physics is not None and isinstance(physics, site_physics.SitePhysics):
            from service.physics.diagnosis import Diagnoser

            local = Diagnoser(site, physics=physics)
            self.diagnoser = lambda p, m: diagnose_locally(local, p, m)
        self._passages: KeptPassages[WheelPassage] = KeptPassages()
        self._waiting: OrderedDict[str, _Waiting] = OrderedDict()
        self._diagnosed: OrderedDict[str, None] = OrderedDict()
        self._worker = threading.Thread(target=self._work, name="railtwin-worker", daemon=True)
        # a PhysicsPool: passages are submitted as they are validated, published in order
        self._pool: Any = physics if hasattr(physics, "submit") else None
        pool_size = int(getattr(physics, "size", 1))
        self._inflight = threading.Semaphore(2 * pool_size)
        self._ordered: queue.Queue[Any] = queue.Queue()
        self._publisher = threading.Thread(target=self._publish_in_order,
                                           name="railtwin-publisher", daemon=True)
        self._due: list[_Due] = []
        self._due_seq = 0
        self._due_cv = threading.Condition()
        self._pacer: threading.Thread | None = None
        self._pacer_stop = False
        self._declared: list[Any] = []

    # --- life cycle --------------------------------------------------------------------

    def start(self) -> None:
        """Declare the subscriber and queryables, start the threads."""
        if self.recorder is not None:
            self.recorder.rail(self.physics.rail_state())
        self._worker.start()
        if self._pool is not None:
            self._publisher.start()
        if self.pace == "realtime":
            self._pacer = threading.Thread(target=self._pace, name="railtwin-pacer", daemon=True)
            self._pacer.start()
        s = self.session
        self._declared = [
            s.declare_queryable(self.keys.rail, self._on_rail_query),
            s.declare_queryable(HEALTH_KEY, self._on_health_query),
            s.declare_queryable(self.keys.health, self._on_health_query),
            s.declare_subscriber(self.keys.passage, self._on_sample),
            s.declare_subscriber(self.keys.measured, self._on_measured),
            # clients see the twin come and go: a liveliness subscriber gets PUT/DELETE
            s.liveliness().declare_token(self.keys.alive),
        ]

    def stop(self) -> None:
        """Stop taking input, finish what is queued (paced output at once), close the log."""
        for d in reversed(self._declared):
            with contextlib.suppress(Exception):  # the session may already be closing
                d.undeclare()
        self._declared = []
        self._queue.put(_STOP)
        self._worker.join()
        if self._pool is not None:
            self._ordered.put(_STOP)
            self._publisher.join()
        if self._pacer is not None:
            with self._due_cv:
                self._pacer_stop = True
                self._due_cv.notify()
            self._pacer.join()
        if self.recorder is not None:
            self.recorder.close()

    # --- Zenoh callbacks (never block) -------------------------------------------------

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self.passages_received += 1
        self._take(sample, measured=False)

    def _on_measured(self, sample: zenoh.Sample) -> None:
        self.measured_received += 1
        self._take(sample, measured=True)

    def _take(self, sample: zenoh.Sample, measured: bool) -> None:
        """Queue an input; refuse it at once when it is too large or the queue is full."""
        received_ns, received_mono = time.time_ns(), time.monotonic()
        key = str(sample.key_expr)
        too_large = limits.payload_problem(len(sample.payload), measured)
        if self.journal is not None:  # on disk before it is queued (survives kill -9)
            raw = sample.payload.to_bytes()
            self.journal.append(key, received_ns,
                                raw if too_large is None else raw[:LOGGED_PREFIX_BYTES])
        if too_large is not None:  # refused unread: only its first bytes are logged
            head = sample.payload.to_bytes()[:LOGGED_PREFIX_BYTES]
            item = Inbound(key, head, received_ns, received_mono)
            self._log_input(item, None, payload_bytes=len(sample.payload))
            what = "measurement" if measured else "passage"
            self._publish_error(ServiceError(
                site_id=self.site.site_id,
                kind="invalid_measurement" if measured else "invalid_passage",
                message=f"{what} rejected: {too_large}", field=None,
                problems=[FieldProblem(field="", message=too_large, type="payload_too_large")],
                passage_id=limits.peek_passage_id(head), received_at=received_ns / 1e9,
            ))
            return
        item = Inbound(key, sample.payload.to_bytes(), received_ns, received_mono)
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self._log_input(item, None)
            what = "measurement" if measured else "passage"
            self._publish_error(ServiceError(
                site_id=self.site.site_id, kind="overloaded",
                message=f"{what} dropped: {self.queue_capacity} inputs already waiting",
                field=None, passage_id=limits.peek_passage_id(item.payload),
                received_at=item.received_ns / 1e9,
            ))

    def _on_rail_query(self, query: zenoh.Query) -> None:
        with query:
            try:
                data = self.physics.rail_state().model_dump_json().encode()
                query.reply(self.keys.rail, data, encoding=self._encodings[RailState])
            except Exception as exc:
                query.reply_err(f"rail state unavailable: {exc}")

    def _on_health_query(self, query: zenoh.Query) -> None:
        with query:
            data = self.health().model_dump_json().encode()
            query.reply(query.key_expr, data, encoding=self._encodings[Health])

    def health(self) -> Health:
        mcap_path = self.recorder.mcap_path() if self.recorder is not None else None
        rrd_path = self.recorder.rrd_path() if self.recorder is not None else None
        return Health(
            site_id=self.site.site_id, started_at=self.started_at,
            uptime=time.monotonic() - self._started_mono,
            passages_received=self.passages_received, passages_done=self.passages_done,
            errors=self.errors, queue_depth=self._queue.qsize(),
            queue_capacity=self.queue_capacity, last_error=self.last_error,
            mcap_path=mcap_path,
            rrd_path=rrd_path,
        )

    # --- worker ------------------------------------------------------------------------

    def _work(self) -> None:
        while True:
            timeout = None
            if self._waiting:
                first = next(iter(self._waiting.values()))
                timeout = max(0.0, first.deadline - time.monotonic())
            try:
                item = self._queue.get(timeout=timeout)
            except queue.Empty:
                item = None
            if item is _STOP:
                return
            if item is not None:
                try:
                    if item.key == self.keys.measured:
                        self._serve_measured(item)
                    else:
                        self._serve(item)
                except Exception as exc:  # never let one input kill the service
                    self._publish_error(ServiceError(
                        site_id=self.site.site_id, kind="simulation_failed",
                        message=f"internal error: {type(exc).__name__}: {exc}", field=None,
                        received_at=item.received_ns / 1e9,
                    ))
            self._expire_waiting()

    def _too_deep(self, item: Inbound, measured: bool) -> bool:
        """Refuse JSON nested deeper than ``limits.MAX_NESTING`` before it is parsed."""
        problem = limits.structure_problem(item.payload)
        if problem is None:
            return False
        self._log_input(item, None)
        what = "measurement" if measured else "passage"
        error_type, message = problem
        kind: ErrorKind = "invalid_json" if error_type == "json_too_deep" else (
            "invalid_measurement" if measured else "invalid_passage")
        self._publish_error(ServiceError(
            site_id=self.site.site_id, kind=kind,
            message=f"{what} rejected before it was read: {message}", field=None,
            problems=[FieldProblem(field="", message=message, type=error_type)],
            passage_id=limits.peek_passage_id(item.payload), received_at=item.received_ns / 1e9,
        ))
        return True

    def _serve(self, item: Inbound) -> None:
        if self._too_deep(item, measured=False):
            return
        try:
            passage = WheelPassage.model_validate_json(item.payload)
        except ValidationError as exc:
            self._log_input(item, None)
            self._publish_error(service_error_from_validation(
                exc, item.payload, self.site.site_id, item.received_ns / 1e9))
            return
        problem = limits.passage_problem(self.site, passage)
        if problem is not None:  # valid, but more than this site may spend on one passage
            self._log_input(item, None)
            field_name, message = problem
            self._publish_error(ServiceError(
                site_id=self.site.site_id, kind="invalid_passage",
                message=f"passage rejected, over a limit: {field_name}: {message}",
                field=field_name,
                problems=[FieldProblem(field=field_name, message=message, type="over_limit")],
                passage_id=passage.passage_id, received_at=item.received_ns / 1e9,
            ))
            return
        self._log_input(item, passage)
        if self._already_applied(item, passage):
            return
        self._passages.add(passage.passage_id, passage, len(item.payload))
        try:
            self._simulate(item, passage)
        finally:  # the result goes out first; then the measurement waiting for it
            waiting = self._waiting.pop(passage.passage_id, None)
            if waiting is not None:
                self._diagnose(passage, waiting.measured, waiting.item)

    def _simulate(self, item: Inbound, passage: WheelPassage) -> None:
        if self._pool is not None:  # published in order by the publisher thread
            self._inflight.acquire()
            light = self.pace == "fast"  # the worker makes the series' JSON too
            self._ordered.put((item, passage, self._pool.submit(passage, light)))
            return

        def run() -> tuple[PassageResult, bytes | None, RailState | None, Series | None]:
            simulate_json = getattr(self.physics, "simulate_json", None)
            if simulate_json is not None:
                result, data = simulate_json(passage)
                return result, data, None, None
            return self.physics.simulate(passage), None, None, None

        self._finish(item, passage, run)

    def _publish_in_order(self) -> None:
        """The publisher thread (with a ``PhysicsPool``): results in the passages' order."""
        while True:
            entry = self._ordered.get()
            try:
                if entry is _STOP:
                    return
                item, passage, future = entry
                try:
                    self._finish(item, passage, future.result)
                except Exception as exc:  # never let one passage kill the service
                    self._publish_error(ServiceError(
                        site_id=self.site.site_id, kind="simulation_failed",
                        message=f"internal error: {type(exc).__name__}: {exc}", field=None,
                        passage_id=passage.passage_id, received_at=item.received_ns / 1e9,
                    ))
                finally:
                    self._inflight.release()
            finally:
                self._ordered.task_done()

    def _finish(self, item: Inbound, passage: WheelPassage,
                run: Callable[[], tuple[PassageResult, bytes | None, RailState | None,
                                        Series | None]]) -> None:
        """Wait for the passage's simulation (``run``) and publish its result or error."""
        try:
            result, result_data, rail_after, series = run()
        except (BudgetExceededError, WorkerCrashedError) as exc:
            self._publish_error(ServiceError(
                site_id=self.site.site_id, kind="simulation_failed", message=str(exc),
                field=None, passage_id=passage.passage_id, received_at=item.received_ns / 1e9,
            ))
            return
        except (ValueError, ArithmeticError, ValidationError) as exc:
            self._publish_error(ServiceError(
                site_id=self.site.site_id, kind="simulation_failed",
                message=f"passage {passage.passage_id} could not be simulated: {exc}",
                field=None, passage_id=passage.passage_id,
                received_at=item.received_ns / 1e9,
            ))
            return
        result_data = self._publish_result(result, item.received_mono, result_data, series)
        self.passages_done += 1
        if self.recorder is not None:
            self.recorder.passage(result, result_data)
            if result.summary.max_dent > 0.0:
                self.recorder.dent(result.passage_id, rail_after or self.physics.rail_state())

    # --- diagnosis ---------------------------------------------------------------------

    def _already_applied(self, item: Inbound, passage: WheelPassage) -> bool:
        """A passage id seen before (this run, or applied in an earlier one) is not applied
        twice: it gets an error saying so."""
        pid = passage.passage_id
        where = "earlier in this run" if pid in self._passages else None
        applied = getattr(self.physics, "already_applied", None)
        revision = applied(pid) if applied is not None and where is None else None
        if revision is not None:
            where = f"at rail revision {revision} (state on disk)"
        if where is None:
            return False
        self._publish_error(ServiceError(
            site_id=self.site.site_id, kind="invalid_passage",
            message=f"passage_id {pid!r} was already received {where}: not applied twice",
            field="passage_id",
            problems=[FieldProblem(field="passage_id", message="duplicate passage id",
                                   type="duplicate")],
            passage_id=pid, received_at=item.received_ns / 1e9,
        ))
        return True

    def _measurement_error(self, item: Inbound, kind: Literal["invalid_measurement", "unpaired",
                                                              "simulation_failed"],
                           message: str, passage_id: str, field_name: str | None = None) -> None:
        self._publish_error(ServiceError(
            site_id=self.site.site_id, kind=kind, message=message, field=field_name,
            passage_id=passage_id, received_at=item.received_ns / 1e9,
        ))

    def _serve_measured(self, item: Inbound) -> None:
        if self._too_deep(item, measured=True):
            return
        try:
            measured = MeasuredPassage.model_validate_json(item.payload)
        except ValidationError as exc:
            self._log_input(item, None)
            self._publish_error(service_error_from_validation(
                exc, item.payload, self.site.site_id, item.received_ns / 1e9, MeasuredPassage))
            return
        self._log_input(item, measured)
        pid = measured.passage_id
        if self.diagnoser is None:
            self._measurement_error(
                item, "simulation_failed", f"measurement of {pid} not diagnosed: diagnosis is "
                "unavailable (it needs the site's own physics, --physics sim_core)", pid)
            return
        if pid in self._diagnosed or pid in self._waiting:
            self._measurement_error(
                item, "invalid_measurement", f"measurement of {pid} dropped: duplicate (the "
                "passage already has a measurement)", pid, "passage_id")
            return
        passage = self._passages.get(pid)
        if passage is not None:
            self._diagnose(passage, measured, item)
            return
        timeout = self.site.diagnosis.pairing_timeout
        self._waiting[pid] = _Waiting(measured, item, item.received_mono + timeout)
        while len(self._waiting) > MAX_WAITING_MEASUREMENTS:
            old_pid, old = self._waiting.popitem(last=False)
            self._measurement_error(
                old.item, "unpaired", f"measurement of {old_pid} dropped: its passage has not "
                f"come and {MAX_WAITING_MEASUREMENTS} measurements are waiting", old_pid)

    def _expire_waiting(self) -> None:
        """Measurements whose passage did not come within the pairing timeout (oldest first)."""
        now = time.monotonic()
        timeout = self.site.diagnosis.pairing_timeout
        while self._waiting:
            pid, first = next(iter(self._waiting.items()))
            if first.deadline > now:
                return
            del self._waiting[pid]
            self._measurement_error(
                first.item, "unpaired", f"measurement of {pid} not diagnosed: no passage "
                f"{pid} within the pairing timeout of {timeout:g} s", pid)

    def _diagnose(self, passage: WheelPassage, measured: MeasuredPassage, item: Inbound) -> None:
        assert self.diagnoser is not None
        pid = passage.passage_id
        if self._pool is not None:
            self._ordered.join()  # the passage's result goes out first
        try:
            outcome = self.diagnoser(passage, measured)
        except MeasurementError as exc:
            self._measurement_error(item, "invalid_measurement",
                                    f"measurement of {pid} rejected: {exc}", pid, exc.field)
            return
        except (BudgetExceededError, WorkerCrashedError) as exc:
            self._measurement_error(item, "simulation_failed", str(exc), pid)
            return
        except Exception as exc:  # never let one diagnosis kill the service
            self._measurement_error(
                item, "simulation_failed",
                f"measurement of {pid} could not be diagnosed: {type(exc).__name__}: {exc}", pid)
            return
        diag = outcome.diagnosis
        self._diagnosed[pid] = None  # a refused measurement may be sent again, corrected
        while len(self._diagnosed) > KEPT_DIAGNOSED:
            self._diagnosed.popitem(last=False)
        data = diag.model_dump_json().encode()
        self._put(self.keys.diagnosis(pid), f"{self.keys.prefix}/diagnosis", Diagnosis, data)
        self.diagnoses_done += 1
        if self.recorder is not None:
            self.recorder.diagnosis(diag, outcome.t, outcome.measured, outcome.fitted, outcome.x,
                                    outcome.impacts_x)

    def _log_input(self, item: Inbound, message: BaseModel | None,
                   payload_bytes: int | None = None) -> None:
        if self.recorder is None:
            return
        measured = item.key == self.keys.measured
        key = self.keys.measured if measured else self.keys.passage
        if message is not None:
            model = MeasuredPassage if measured else WheelPassage
            at = (round(message.timestamp * 1e9) if isinstance(message, WheelPassage)
                  else None)  # the passage's own time, as publish_time in the log
            self.recorder.message(key, model, item.payload, item.received_ns, at)
            return
        rejected = RejectedInput(
            key=item.key, payload_base64=base64.b64encode(item.payload).decode("ascii"),
            payload_text=item.payload.decode("utf-8", errors="replace"),
            payload_bytes=payload_bytes,
        )
        self.recorder.message(
            f"{key}/rejected", RejectedInput, rejected.model_dump_json().encode(), item.received_ns,
        )

    def _publish_error(self, error: ServiceError) -> None:
        with self._counts:  # the callbacks, the worker and the publisher all report errors
            self.errors += 1
            self.last_error = error
        self._put(self.keys.error, self.keys.error, ServiceError, error.model_dump_json().encode())

    def _put(self, key: str, topic: str, model: type[BaseModel], data: bytes,
             publish_time_ns: int | None = None) -> None:
        """Publish; log (MCAP with ``publish_time_ns``: the passage's own time, if given)."""
        self.session.put(
            key, data, encoding=self._encodings[model],
            congestion_control=zenoh.CongestionControl.BLOCK, express=True,
        )
        now = time.time_ns()
        if self.journal is not None and model in JOURNALED_OUTPUTS:
            # the record of what the twin said, on disk now: the recorder may lag behind
            self.journal.append(topic, now, data)
        if self.recorder is not None:
            self.recorder.message(topic, model, data, now, publish_time_ns)

    def _series(self, r: PassageResult, quantity: Literal["force", "indentation"],
                first: int, last: int, chunk: int, chunks: int) -> bytes:
        return series_json(r, quantity, first, last, chunk, chunks)

    def _publish_result(self, r: PassageResult, received_mono: float,
                        result_data: bytes | None = None, series: Series | None = None) -> bytes:
        """Publish (or schedule) the series and the result; returns the result's JSON.

        ``series``: the force and indentation series' JSON made by the worker (fast pacing);
        then ``r`` may come without its arrays and ``result_data`` is the whole result."""
        k = self.keys
        pid = r.passage_id
        at = round(r.timestamp * 1e9)  # the passage's own time, as publish_time in the log
        if result_data is None:
            result_data = r.model_dump_json().encode()
        if series is not None:
            self._put(k.force(pid), f"{k.prefix}/force", PassageSeries, series[0], at)
            self._put(k.indentation(pid), f"{k.prefix}/indentation", PassageSeries, series[1],
                      at)
            self._put(k.result(pid), f"{k.prefix}/result", PassageResult, result_data, at)
            return result_data
        if self.pace == "fast":
            n = len(r.x)
            self._put(k.force(pid), f"{k.prefix}/force", PassageSeries,
                      self._series(r, "force", 0, n, 0, 1), at)
            self._put(k.indentation(pid), f"{k.prefix}/indentation", PassageSeries,
                      self._series(r, "indentation", 0, n, 0, 1), at)
            self._put(k.result(pid), f"{k.prefix}/result", PassageResult, result_data, at)
            return result_data
        n = len(r.x)
        per_chunk = max(1, round(self.chunk_period * r.sample_rate))
        chunks = max(1, -(-n // per_chunk))
        for c in range(chunks):
            first, last = c * per_chunk, min(n, (c + 1) * per_chunk)
            due = received_mono + (last - 1) / r.sample_rate
            quantities: tuple[Literal["force", "indentation"], ...] = ("force", "indentation")
            for quantity in quantities:
                key = k.force(pid) if quantity == "force" else k.indentation(pid)
                self._schedule(due, key, PassageSeries,
                               self._series(r, quantity, first, last, c, chunks))
        self._schedule(received_mono + r.site_length / r.speed, k.result(pid), PassageResult,
                       result_data)
        return result_data

    # --- pacer (realtime) --------------------------------------------------------------

    def _schedule(self, due: float, key: str, model: type[BaseModel], data: bytes) -> None:
        with self._due_cv:
            self._due_seq += 1
            heapq.heappush(self._due, _Due(due, self._due_seq, key, model, data))
            self._due_cv.notify()

    def _pace(self) -> None:
        while True:
            with self._due_cv:
                while True:
                    if self._pacer_stop and not self._due:
                        return
                    now = time.monotonic()
                    if self._due and (self._due[0].due <= now or self._pacer_stop):
                        item = heapq.heappop(self._due)
                        break
                    timeout = self._due[0].due - now if self._due else None
                    self._due_cv.wait(timeout)
            kind = self.keys.kind_of(item.key) or "output"
            self._put(item.key, f"{self.keys.prefix}/{kind}", item.model, item.data)
