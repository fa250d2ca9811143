"""``FleetService``: every site's diagnoses in, each wheel's history, trend and alarms out.

- subscribes ``railtwin/*/diagnosis/**`` (the Diagnosis) and ``railtwin/*/result/**``
  (only the passage's speed is kept from a PassageResult);
- a callback only queues the payload; one ingest thread validates, stores in batches
  (one transaction each), evaluates the touched wheels' alarms and publishes each new
  alarm on ``railtwin/fleet/alarm/<vehicle_id>/<wheelset>/<side>`` (and logs it); the
  alarm table is an outbox: an alarm stored and not published (the service stopped
  between the two, or a put failed) is published on the next start, or after a backoff
  of 1 s doubling to 60 s while puts fail, in the order raised, so every alarm is
  delivered at least once, under its stable ``alarm_id``;
- catches up: on start (after subscribing) it queries ``railtwin/*/diagnoses?since=T``,
  and again ``railtwin/<site>/diagnoses?since=T`` whenever a twin's liveliness token
  ``railtwin/<site>/alive`` appears (a twin reachable only later, restarted, or back after
  a network partition), with T = min(latest passage time, latest receipt) stored -
  ``catch_up_margin`` (0 when the store is empty); every reply goes through the same queue,
  and the store's key (site_id, passage_id) drops what it already has;
- queryables ``railtwin/fleet/wheel/<vehicle_id>/<wheelset>/<side>`` (the wheel's history
  document, ``service.fleet.history``; a wildcard query gets one reply per known wheel, at
  most ``MAX_WHEEL_REPLIES``) and ``railtwin/fleet/alarms`` (open alarms; ``?all=true``:
  every alarm; ``?vehicle=V``), each replying on its own concrete key;
- polls ``railtwin/*/health`` every ``health_period`` s for the dashboard.
"""

from __future__ import annotations

import contextlib
import json
import logging
import queue
import threading
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Any, Literal

import zenoh

from schemas.fleet import FleetAlarm
from service.fleet import keys
from service.fleet.alarms import DEFAULT_HORIZON_DAYS, apply, evaluate_due
from service.fleet.entry import Entry, EntryError, entry_from_payload, speed_of_result
from service.fleet.history import wheel_document
from service.fleet.limits import FleetLimits
from service.fleet.store import AlarmRow, Store

log = logging.getLogger("railtwin.fleet")

DEFAULT_CATCH_UP_MARGIN = 3600.0
"""s subtracted from the latest stored time when catching up (clock skew, late diagnoses)."""
MAX_BATCH = 500
"""Diagnoses stored per transaction at most."""
MAX_QUEUE = 200_000
"""Payloads waiting to be stored at most; past it new ones are dropped (and counted)."""
MAX_WHEEL_REPLIES = 1000
KEPT_SPEEDS = 20_000
"""Speeds of results whose diagnosis has not been stored yet, kept at most."""
OUTBOX_PAGE = 1000
"""Alarms read from the outbox per query (a pass reads pages until none is left)."""
MAX_OUTBOX_RETRY = 60.0
"""s: the longest wait between tries while alarms cannot be published."""
JSON = zenoh.Encoding.APPLICATION_JSON

Kind = Literal["diagnosis", "result"]


def _log_alarm(what: str, a: FleetAlarm) -> None:
    log.warning(
        "%s %s %s [%s] %s (evidence: %s)",
        what,
        a.wheel_id,
        a.level,
        a.severity,
        a.reason,
        ", ".join(a.evidence[-5:]),
    )


@dataclass
class Counters:
    received: int = 0
    stored: int = 0
    duplicates: int = 0
    rejected: int = 0
    dropped: int = 0
    alarms: int = 0
    published_late: int = 0
    outbox_passes: int = 0
    caught_up: int = 0
    last_error: str | None = None
    started_at: float = field(default_factory=time.time)


class FleetService:
    """See the module doc. ``start()``, then ``stop()`` (or use it as a context manager)."""

    def __init__(
        self,
        session: zenoh.Session,
        store: Store,
        *,
        limits: FleetLimits | None = None,
        horizon: float = DEFAULT_HORIZON_DAYS * 86400.0,
        catch_up_margin: float = DEFAULT_CATCH_UP_MARGIN,
        catch_up_timeout: float = 10.0,
        health_period: float = 15.0,
        outbox_retry: float = 1.0,
    ) -> None:
        self.session = session
        self.store = store
        self.limits = limits or FleetLimits.defaults()
        self.horizon = horizon
        self.catch_up_margin = catch_up_margin
        self.catch_up_timeout = catch_up_timeout
        self.health_period = health_period
        self.counters = Counters()
        self.health: dict[str, dict[str, Any]] = {}
        self._queue: queue.Queue[tuple[Kind, bytes, float]] = queue.Queue(MAX_QUEUE)
        self._speeds: OrderedDict[tuple[str, str], float] = OrderedDict()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._declared: list[Any] = []
        self._catch_up_requests: queue.Queue[str] = queue.Queue()
        self.outbox_retry = outbox_retry
        self._outbox_dirty = False
        self._outbox_retry_in = outbox_retry / 2.0
        self._outbox_retry_at = 0.0

    # --- life cycle --------------------------------------------------------------------

    def start(self, catch_up: bool = True) -> None:
        s = self.session
        self._declared += [
            s.declare_subscriber(keys.DIAGNOSES_SUB, lambda smp: self._enqueue("diagnosis", smp)),
            s.declare_subscriber(keys.RESULTS_SUB, lambda smp: self._enqueue("result", smp)),
            s.declare_queryable(keys.WHEEL_QUERYABLE, self._on_wheel_query),
            s.declare_queryable(keys.ALARMS_KEY, self._on_alarms_query),
        ]
        loops = [(self._ingest_loop, "fleet-ingest"), (self._health_loop, "fleet-health")]
        if catch_up:
            loops.append((self._catch_up_loop, "fleet-catch-up"))
        for target, name in loops:
            t = threading.Thread(target=target, name=name, daemon=True)
            t.start()
            self._threads.append(t)
        if catch_up:
            self.catch_up()
            self._declared.append(
                s.liveliness().declare_subscriber(keys.ALIVE_SUB, self._on_alive, history=True)
            )

    def stop(self) -> None:
        self._stop.set()
        for d in self._declared:
            with contextlib.suppress(Exception):  # the session may already be closed
                d.undeclare()
        self._declared.clear()
        for t in self._threads:
            t.join(timeout=10.0)
        self._threads.clear()

    def __enter__(self) -> FleetService:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait_idle(self, timeout: float = 10.0) -> bool:
        """True once everything queued so far has been stored (for tests and the demo)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if self._queue.unfinished_tasks == 0:
                return True
            time.sleep(0.01)
        return False

    # --- catch-up ----------------------------------------------------------------------

    def catch_up_since(self) -> float:
        latest = self.store.latest_times()
        if latest is None:
            return 0.0
        return max(0.0, min(latest) - self.catch_up_margin)

    def _on_alive(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            site = keys.site_of_key(str(sample.key_expr))
            if site is not None:
                self._catch_up_requests.put(site)

    def _catch_up_loop(self) -> None:
        while not self._stop.is_set():
            try:
                site = self._catch_up_requests.get(timeout=0.2)
            except queue.Empty:
                continue
            self.catch_up(site)

    def catch_up(self, site: str | None = None) -> int:
        """Ask the twin of ``site`` (every twin if None) for what it diagnosed since the
        latest stored time; the replies are queued for storing. How many came."""
        since = self.catch_up_since()
        selector = keys.CATCH_UP_SELECTOR if site is None else keys.catch_up_key(site)
        n = 0
        try:
            replies = self.session.get(
                f"{selector}?since={since:.3f}",
                timeout=self.catch_up_timeout,
                accept_replies=zenoh.ReplyKeyExpr.ANY,
                consolidation=zenoh.ConsolidationMode.NONE,
                target=zenoh.QueryTarget.ALL,
            )
            for reply in replies:
                if reply.ok is None:
                    err = reply.err
                    text = err.payload.to_string() if err is not None else "?"
                    log.warning("catch-up: a twin answered with an error: %s", text[:300])
                    continue
                self._put("diagnosis", reply.ok.payload.to_bytes())
                n += 1
        except zenoh.ZError as exc:
            log.warning("catch-up query failed: %s", exc)
        self.counters.caught_up += n
        log.info("catch-up from %s since %.0f: %d diagnoses received", selector, since, n)
        return n

    # --- ingest ------------------------------------------------------------------------

    def _enqueue(self, kind: Kind, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        self._put(kind, sample.payload.to_bytes())

    def _put(self, kind: Kind, payload: bytes) -> None:
        try:
            self._queue.put_nowait((kind, payload, time.time()))
        except queue.Full:
            self.counters.dropped += 1

    def evaluate_due(self) -> list[FleetAlarm]:
        """``alarms.evaluate_due`` on this service's store: the alarms of every wheel whose
        diagnosis was stored and not evaluated (published by the outbox's next pass)."""
        raised = evaluate_due(self.store, self.limits, self.horizon)
        for a in raised:
            self.counters.alarms += 1
            _log_alarm("ALARM (evaluated after a restart)", a)
        return raised

    def _ingest_loop(self) -> None:
        self._outbox_dirty = True  # on start: what the last run stored and did not publish
        try:
            self.evaluate_due()
        except Exception as exc:  # the stored alarms' outbox still runs
            self.counters.last_error = f"{type(exc).__name__}: {exc}"
            log.exception("evaluating the alarms due after a restart failed")
        while not self._stop.is_set():
            if self._outbox_dirty and time.monotonic() >= self._outbox_retry_at:
                self._drain_outbox(frozenset())
            try:
                first = self._queue.get(timeout=0.1)
            except queue.Empty:
                continue
            batch = [first]
            while len(batch) < MAX_BATCH:
                try:
                    batch.append(self._queue.get_nowait())
                except queue.Empty:
                    break
            try:
                self.ingest(batch)
            except Exception as exc:  # never let one bad batch stop the service
                self._outbox_dirty = True  # it may have stored an alarm it did not publish
                self.counters.last_error = f"{type(exc).__name__}: {exc}"
                log.exception("ingest failed for a batch of %d", len(batch))
            finally:
                for _ in batch:
                    self._queue.task_done()

    def ingest(self, batch: list[tuple[Kind, bytes, float]]) -> list[FleetAlarm]:
        """Store a batch of payloads; the alarms raised (logged, stored, and published unless
        a put failed: then they wait in the outbox, see ``_drain_outbox``). Call it from one
        thread at a time (the ingest thread, once started)."""
        entries: list[Entry] = []
        for kind, payload, received_at in batch:
            if kind == "result":
                found = speed_of_result(payload)
                if found is not None:
                    self._remember_speed(*found)
                continue
            self.counters.received += 1
            try:
                e = entry_from_payload(payload, received_at)
            except EntryError as exc:
                self.counters.rejected += 1
                self.counters.last_error = str(exc)
                log.warning("diagnosis refused: %s", exc)
                continue
            entries.append(e.with_speed(self._speeds.pop((e.site_id, e.passage_id), None)))
        new = self.store.insert(entries) if entries else []
        self.counters.stored += len(new)
        self.counters.duplicates += len(entries) - len(new)
        raised: list[FleetAlarm] = []
        for wheel_id in dict.fromkeys(e.wheel_id for e in new if e.wheel_id is not None):
            for a in apply(self.store, wheel_id, self.limits, self.horizon):
                self.counters.alarms += 1
                _log_alarm("ALARM", a)
                raised.append(a)
        if raised or self._outbox_dirty:
            self._outbox_dirty = True
            if time.monotonic() >= self._outbox_retry_at:
                self._drain_outbox(frozenset(a.alarm_id for a in raised))
        return raised

    def _drain_outbox(self, fresh: frozenset[str]) -> None:
        """Publish every alarm stored and not yet published, oldest first, recording each;
        ``fresh``: the ids raised in this batch (the others are published late: the service
        stopped between storing and publishing them, or a put failed).

        The alarm table is an outbox, so an alarm is delivered at least once (a stop between
        the put and its record delivers it twice, under the same ``alarm_id``), and in the
        order raised. A failed put stops the pass; the next is tried after ``outbox_retry``
        s, doubling up to ``MAX_OUTBOX_RETRY``, and the alarms wait meanwhile (new ones
        behind them). An alarm cleared while it waited is still published: it was raised.
        Called only from the thread that ingests."""
        self.counters.outbox_passes += 1
        try:
            while True:
                rows = self.store.unpublished_alarms(OUTBOX_PAGE)
                for row in rows:
                    if not self._publish_row(row, fresh):
                        self._outbox_retry_in = self._next_retry()
                        self._outbox_retry_at = time.monotonic() + self._outbox_retry_in
                        return  # still dirty
                if len(rows) < OUTBOX_PAGE:
                    break
        except Exception as exc:  # the database: try again later
            self.counters.last_error = f"{type(exc).__name__}: {exc}"
            log.exception("publishing the stored alarms failed")
            self._outbox_retry_at = time.monotonic() + self._outbox_retry_in
            return
        self._outbox_dirty = False
        self._outbox_retry_in = self.outbox_retry / 2.0  # the first failure waits outbox_retry
        self._outbox_retry_at = 0.0

    def _next_retry(self) -> float:
        """s until the next try after a failed put: twice the last wait, at most
        ``MAX_OUTBOX_RETRY``."""
        return min(2.0 * self._outbox_retry_in, MAX_OUTBOX_RETRY)

    def _publish_row(self, row: AlarmRow, fresh: frozenset[str]) -> bool:
        """Publish one stored alarm and record it; False if the put failed."""
        try:
            a = FleetAlarm.model_validate_json(row.body)
        except ValueError as exc:  # stored by this service, so never expected
            log.error(
                "alarm %s/%s/%s/%s unreadable, left out of the outbox (still listed): %s",
                row.wheel_id,
                row.kind,
                row.level,
                row.episode,
                exc,
            )
            self.store.mark_published(row.wheel_id, row.kind, row.level, row.episode, -1.0)
            return True
        key = keys.alarm_key(a.wheel.vehicle_id, a.wheel.wheelset, a.wheel.side)
        try:
            self.session.put(
                key,
                a.model_dump_json(),
                encoding=JSON.with_schema(f"railtwin.FleetAlarm/{a.schema_version}"),
            )
        except zenoh.ZError as exc:
            log.warning(
                "alarm %s not published (kept, tried again in %.0f s): %s",
                a.alarm_id,
                self._next_retry(),
                exc,
            )
            return False
        self.store.mark_published(a.wheel_id, a.kind, a.level, a.episode, time.time())
        if a.alarm_id not in fresh:
            self.counters.published_late += 1
            _log_alarm("ALARM (stored earlier, published now)", a)
        return True

    def _remember_speed(self, site_id: str, passage_id: str, speed: float) -> None:
        if self.store.set_speed(site_id, passage_id, speed):
            return
        self._speeds[(site_id, passage_id)] = speed
        while len(self._speeds) > KEPT_SPEEDS:
            self._speeds.popitem(last=False)

    # --- queries -----------------------------------------------------------------------

    def wheel_document(self, wheel_id: str) -> dict[str, Any] | None:
        w = self.store.wheel(wheel_id)
        if w is None:
            return None
        return wheel_document(wheel_id, self.store.history(wheel_id), self.limits, w.last_verdict)

    def alarms_document(
        self, all_alarms: bool = False, vehicle: str | None = None
    ) -> dict[str, Any]:
        rows = self.store.alarms(open_only=not all_alarms)
        docs = [r.json() for r in rows]
        if vehicle is not None:
            docs = [d for d in docs if d.get("wheel", {}).get("vehicle_id") == vehicle]
        return {"open_only": not all_alarms, "alarms": docs}

    def _on_wheel_query(self, query: zenoh.Query) -> None:
        with query:
            try:
                key = str(query.key_expr)
                wheel_id = keys.wheel_id_of_key(key)
                if wheel_id is not None:
                    doc = self.wheel_document(wheel_id)
                    if doc is None:
                        query.reply_err(
                            json.dumps({"error": "unknown_wheel", "wheel_id": wheel_id})
                        )
                    else:
                        query.reply(keys.wheel_key(wheel_id), json.dumps(doc), encoding=JSON)
                    return
                asked = zenoh.KeyExpr(key)
                replied = 0
                for w in self.store.wheels(limit=100_000):
                    wkey = keys.wheel_key(w.wheel_id)
                    if replied < MAX_WHEEL_REPLIES and asked.intersects(zenoh.KeyExpr(wkey)):
                        doc = self.wheel_document(w.wheel_id)
                        if doc is not None:
                            query.reply(wkey, json.dumps(doc), encoding=JSON)
                            replied += 1
            except Exception as exc:
                log.exception("wheel query failed")
                query.reply_err(json.dumps({"error": "internal", "message": str(exc)}))

    def _on_alarms_query(self, query: zenoh.Query) -> None:
        with query:
            try:
                params = query.parameters
                all_alarms = (params.get("all") or "").lower() in ("1", "true", "yes")
                doc = self.alarms_document(all_alarms, params.get("vehicle"))
                query.reply(keys.ALARMS_KEY, json.dumps(doc), encoding=JSON)
            except Exception as exc:
                log.exception("alarms query failed")
                query.reply_err(json.dumps({"error": "internal", "message": str(exc)}))

    # --- health of the sites -----------------------------------------------------------

    def _health_loop(self) -> None:
        while not self._stop.wait(0.5 if not self.health else self.health_period):
            try:
                for reply in self.session.get(keys.HEALTH_SELECTOR, timeout=2.0):
                    if reply.ok is None:
                        continue
                    try:
                        doc = json.loads(reply.ok.payload.to_bytes())
                    except ValueError:
                        continue
                    if not isinstance(doc, dict):
                        continue
                    site = doc.get("site_id") or keys.site_of_key(str(reply.ok.key_expr))
                    if isinstance(site, str):
                        self.health[site] = {"seen_at": time.time(), **doc}
            except zenoh.ZError:
                continue

    def status(self) -> dict[str, Any]:
        c = self.counters
        return {
            "received": c.received,
            "stored": c.stored,
            "duplicates": c.duplicates,
            "rejected": c.rejected,
            "dropped": c.dropped,
            "alarms": c.alarms,
            "alarms_published_late": c.published_late,
            "alarms_waiting": self._outbox_dirty,
            "caught_up": c.caught_up,
            "queued": self._queue.qsize(),
            "last_error": c.last_error,
            "uptime": time.time() - c.started_at,
            "db": f"{self.store.dialect}: {self.store.where}",
        }
