"""Passages: validated, checked against the site's limits and the ids applied before,
simulated through the physics port and published (in the passages' order).

With a concurrent port (worker processes) passages are submitted as they are validated and a
publisher thread publishes each result when its turn comes; at most 2 x ``size`` are in
flight. With ``pace="realtime"`` the series and result are handed to the ``Pacer``.
"""

from __future__ import annotations

import queue
import threading
from concurrent.futures import Future
from typing import Final, Literal

from pydantic import ValidationError

from schemas.messages import FieldProblem, PassageResult, PassageSeries, WheelPassage
from schemas.site import SiteConfig
from service.physics.port import (
    BudgetExceededError,
    PhysicsPort,
    Series,
    Simulated,
    WorkerCrashedError,
)
from service.twin.errors import service_error_from_validation
from service.twin.inbound import Inbound
from service.twin.intake import refused_unread
from service.twin.kept_passages import KeptPassages
from service.twin.output import Output
from service.twin.pacer import Pacer
from service.twin.unknown_fields import UnknownFields
from service.wire import limits
from service.wire.encoding import Quantity, series_json

Pace = Literal["fast", "realtime"]


class _Stop:
    """Ends the publisher thread, after what was submitted before."""


_STOP: Final = _Stop()

_Entry = tuple[Inbound, WheelPassage, "Future[Simulated]"]


class Simulation:
    """The passages' way through the twin, from a queued input to a published result."""

    def __init__(
        self,
        site: SiteConfig,
        output: Output,
        physics: PhysicsPort,
        passages: KeptPassages[WheelPassage],
        *,
        pace: Pace = "fast",
        chunk_period: float = 0.02,
        pacer: Pacer | None = None,
    ) -> None:
        if pace == "realtime" and pacer is None:
            raise ValueError("realtime pacing needs a Pacer")
        self.site = site
        self.output = output
        self.physics = physics
        self.passages = passages
        self.pace = pace
        self.chunk_period = chunk_period
        self.pacer = pacer
        self.done = 0
        self.without_wheel = 0
        """Passages taken without a wheel (no ``wheel``, or its fields misplaced)."""
        self.unknown_fields = UnknownFields()
        self._inflight = threading.Semaphore(2 * physics.size)
        self._ordered: queue.Queue[_Entry | _Stop] = queue.Queue()
        self._publisher = (
            threading.Thread(target=self._publish_in_order, name="railtwin-publisher", daemon=True)
            if physics.concurrent
            else None
        )

    def start(self) -> None:
        if self._publisher is not None:
            self._publisher.start()

    def stop(self) -> None:
        """Publish what was submitted, then end the publisher thread."""
        if self._publisher is not None and self._publisher.is_alive():
            self._ordered.put(_STOP)
            self._publisher.join()

    def drain(self) -> None:
        """Wait until every submitted passage is published (a diagnosis comes after it)."""
        if self._publisher is not None:
            self._ordered.join()

    # --- intake ------------------------------------------------------------------------

    def accept(self, item: Inbound) -> WheelPassage | None:
        """The passage in ``item``, logged, if it is valid, within the limits and new;
        otherwise None (it got an error)."""
        out = self.output
        if refused_unread(out, item, measured=False):
            return None
        try:
            passage = WheelPassage.model_validate_json(item.payload)
        except ValidationError as exc:
            out.log_input(item, None)
            out.publish_error(
                service_error_from_validation(
                    exc, item.payload, self.site.site_id, item.received_at
                )
            )
            return None
        problem = limits.passage_problem(self.site, passage)
        if problem is not None:  # valid, but more than this site may spend on one passage
            out.log_input(item, None)
            field_name, message = problem
            out.error(
                item,
                "invalid_passage",
                f"passage rejected, over a limit: {field_name}: {message}",
                field=field_name,
                passage_id=passage.passage_id,
                problems=[FieldProblem(field=field_name, message=message, type="over_limit")],
            )
            return None
        out.log_input(item, passage)
        if self._already_applied(item, passage):
            return None
        self.unknown_fields.warn(passage.passage_id, item.payload, item.sender)
        if passage.wheel is None:
            self.without_wheel += 1
        self.passages.add(passage.passage_id, passage, len(item.payload))
        return passage

    def _already_applied(self, item: Inbound, passage: WheelPassage) -> bool:
        """A passage id seen before (this run, or applied in an earlier one) is not applied
        twice: it gets an error saying so."""
        pid = passage.passage_id
        where = "earlier in this run" if pid in self.passages else None
        revision = self.physics.already_applied(pid) if where is None else None
        if revision is not None:
            where = f"at rail revision {revision} (state on disk)"
        if where is None:
            return False
        self.output.error(
            item,
            "invalid_passage",
            f"passage_id {pid!r} was already received {where}: not applied twice",
            field="passage_id",
            passage_id=pid,
            problems=[
                FieldProblem(field="passage_id", message="duplicate passage id", type="duplicate")
            ],
        )
        return True

    # --- simulation and publication ----------------------------------------------------

    def simulate(self, item: Inbound, passage: WheelPassage) -> None:
        """Submit ``passage``; published here (an in-process port) or by the publisher."""
        light = self.pace == "fast"  # the worker makes the series' JSON too
        if self._publisher is None:
            self._finish(item, passage, self.physics.submit(passage, light))
            return
        self._inflight.acquire()
        self._ordered.put((item, passage, self.physics.submit(passage, light)))

    def _publish_in_order(self) -> None:
        """The publisher thread: results in the passages' order."""
        while True:
            entry = self._ordered.get()
            try:
                if isinstance(entry, _Stop):
                    return
                item, passage, future = entry
                try:
                    self._finish(item, passage, future)
                except Exception as exc:  # never let one passage kill the service
                    self.output.error(
                        item,
                        "simulation_failed",
                        f"internal error: {type(exc).__name__}: {exc}",
                        passage_id=passage.passage_id,
                    )
                finally:
                    self._inflight.release()
            finally:
                self._ordered.task_done()

    def _finish(self, item: Inbound, passage: WheelPassage, future: Future[Simulated]) -> None:
        """Wait for the passage's simulation and publish its result or error."""
        pid = passage.passage_id
        try:
            done = future.result()
        except (BudgetExceededError, WorkerCrashedError) as exc:
            self.output.error(item, "simulation_failed", str(exc), passage_id=pid)
            return
        except (ValueError, ArithmeticError, ValidationError) as exc:
            self.output.error(
                item,
                "simulation_failed",
                f"passage {pid} could not be simulated: {exc}",
                passage_id=pid,
            )
            return
        result = done.result
        # counted before it is published: a consumer that has the result and asks for the
        # health sees it counted (a router in between once showed the race)
        self.done += 1
        result_data = self._publish_result(result, item.received_mono, done.data, done.series)
        recorder = self.output.recorder
        if recorder is not None:
            recorder.passage(result, result_data)
            if result.summary.max_dent > 0.0:
                recorder.dent(result.passage_id, done.rail_after or self.physics.rail_state())

    def _publish_result(
        self,
        r: PassageResult,
        received_mono: float,
        result_data: bytes | None = None,
        series: Series | None = None,
    ) -> bytes:
        """Publish (or schedule) the series and the result; returns the result's JSON.

        ``series``: the force and indentation series' JSON made by the worker (fast pacing);
        then ``r`` may come without its arrays and ``result_data`` is the whole result."""
        k = self.output.keys
        put = self.output.put
        pid = r.passage_id
        at = round(r.timestamp * 1e9)  # the passage's own time, as publish_time in the log
        if result_data is None:
            result_data = r.model_dump_json().encode()
        if series is None and self.pace == "fast":
            n = len(r.x)
            series = (
                series_json(r, "force", 0, n, 0, 1),
                series_json(r, "indentation", 0, n, 0, 1),
            )
        if series is not None:
            put(k.force(pid), f"{k.prefix}/force", PassageSeries, series[0], at)
            put(k.indentation(pid), f"{k.prefix}/indentation", PassageSeries, series[1], at)
            put(k.result(pid), f"{k.prefix}/result", PassageResult, result_data, at)
            return result_data
        assert self.pacer is not None
        n = len(r.x)
        per_chunk = max(1, round(self.chunk_period * r.sample_rate))
        chunks = max(1, -(-n // per_chunk))
        quantities: tuple[Quantity, ...] = ("force", "indentation")
        for c in range(chunks):
            first, last = c * per_chunk, min(n, (c + 1) * per_chunk)
            due = received_mono + (last - 1) / r.sample_rate
            for quantity in quantities:
                key = k.force(pid) if quantity == "force" else k.indentation(pid)
                self.pacer.schedule(
                    due, key, PassageSeries, series_json(r, quantity, first, last, c, chunks)
                )
        self.pacer.schedule(
            received_mono + r.site_length / r.speed, k.result(pid), PassageResult, result_data
        )
        return result_data
