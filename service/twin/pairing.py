"""Measured passages: each paired with the ``WheelPassage`` of the same ``passage_id`` (in
either order of arrival), diagnosed through the physics port, the ``Diagnosis`` published.

A measurement whose passage has not come within the site's ``diagnosis.pairing_timeout`` gets
an ``unpaired`` ServiceError; a bad or duplicate one an ``invalid_measurement`` one
(``invalid_json`` if not JSON). A measurement of crib channels gets an
``invalid_measurement`` one (field ``channels``) as soon as it arrives if its ids are not
the site's cribs (naming the missing and extra ids) or the site's rail is not modelled (a
rigid or compliant site); valid channels are paired and diagnosed like a force (the
diagnosis fits the twin's crib channels, ``service.physics.diagnosis``). Every rejection is
logged and counted; nothing else waits.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from pydantic import ValidationError

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.physics.port import (
    BudgetExceededError,
    MeasurementError,
    PhysicsPort,
    WorkerCrashedError,
)
from service.twin.diagnoses import DiagnosisStore
from service.twin.errors import service_error_from_validation
from service.twin.inbound import Inbound
from service.twin.intake import refused_unread
from service.twin.kept_passages import KeptPassages
from service.twin.output import Output
from service.wire.measured_channels import CHANNELS_FIELD, channels_problem

MAX_WAITING_MEASUREMENTS = 1_000
"""Measurements waiting for their passage; beyond, the oldest is dropped as unpaired."""

KEPT_DIAGNOSED = 10_000
"""Passage ids already diagnosed (by id, the latest): a second measurement is refused."""

MeasurementErrorKind = Literal["invalid_measurement", "unpaired", "simulation_failed"]


@dataclass(frozen=True)
class _Waiting:
    """A valid measurement waiting for its passage."""

    measured: MeasuredPassage
    item: Inbound
    deadline: float


class Pairing:
    """Pairs measurements with passages and diagnoses them (on the twin's worker thread)."""

    def __init__(
        self,
        site: SiteConfig,
        output: Output,
        physics: PhysicsPort,
        passages: KeptPassages[WheelPassage],
        *,
        before_diagnosis: Callable[[], None] = lambda: None,
        diagnoses: DiagnosisStore | None = None,
    ) -> None:
        self.site = site
        # what catch-up queries are answered from (in memory when the caller keeps no state)
        self.diagnoses = diagnoses if diagnoses is not None else DiagnosisStore(None)
        self.output = output
        self.physics = physics
        self.passages = passages
        self.before_diagnosis = before_diagnosis
        self.done = 0
        self.calibration: str | None = None
        """The online calibration's drift as the last diagnosis used it (Health)."""
        self._waiting: OrderedDict[str, _Waiting] = OrderedDict()
        self._diagnosed: OrderedDict[str, None] = OrderedDict()

    def next_deadline(self) -> float | None:
        """When (monotonic s) the oldest waiting measurement times out, if one waits."""
        if not self._waiting:
            return None
        return next(iter(self._waiting.values())).deadline

    def _error(
        self,
        item: Inbound,
        kind: MeasurementErrorKind,
        message: str,
        passage_id: str,
        field_name: str | None = None,
    ) -> None:
        self.output.error(item, kind, message, field=field_name, passage_id=passage_id)

    def serve(self, item: Inbound) -> None:
        """A measured passage off the queue."""
        out = self.output
        if refused_unread(out, item, measured=True):
            return
        try:
            measured = MeasuredPassage.model_validate_json(item.payload)
        except ValidationError as exc:
            out.log_input(item, None)
            out.publish_error(
                service_error_from_validation(
                    exc, item.payload, self.site.site_id, item.received_at, MeasuredPassage
                )
            )
            return
        out.log_input(item, measured)
        pid = measured.passage_id
        problem = channels_problem(measured, self.site)
        if problem is not None:  # not the site's cribs, or no modelled rail to fit them on
            self._error(
                item,
                "invalid_measurement",
                f"measurement of {pid} rejected: {CHANNELS_FIELD}: {problem}",
                pid,
                CHANNELS_FIELD,
            )
            return
        if not self.physics.diagnoses:
            self._error(
                item,
                "simulation_failed",
                f"measurement of {pid} not diagnosed: diagnosis is "
                "unavailable (it needs the site's own physics, --physics sim_core)",
                pid,
            )
            return
        if pid in self._diagnosed or pid in self._waiting:
            self._error(
                item,
                "invalid_measurement",
                f"measurement of {pid} dropped: duplicate (the passage already has a measurement)",
                pid,
                "passage_id",
            )
            return
        passage = self.passages.get(pid)
        if passage is not None:
            self._diagnose(passage, measured, item)
            return
        timeout = self.site.diagnosis.pairing_timeout
        self._waiting[pid] = _Waiting(measured, item, item.received_mono + timeout)
        while len(self._waiting) > MAX_WAITING_MEASUREMENTS:
            old_pid, old = self._waiting.popitem(last=False)
            self._error(
                old.item,
                "unpaired",
                f"measurement of {old_pid} dropped: its passage has not "
                f"come and {MAX_WAITING_MEASUREMENTS} measurements are waiting",
                old_pid,
            )

    def passage_came(self, passage: WheelPassage) -> None:
        """A passage was simulated: diagnose the measurement waiting for it, if one is."""
        waiting = self._waiting.pop(passage.passage_id, None)
        if waiting is not None:
            self._diagnose(passage, waiting.measured, waiting.item)

    def expire(self) -> None:
        """Measurements whose passage did not come within the pairing timeout (oldest first)."""
        now = time.monotonic()
        timeout = self.site.diagnosis.pairing_timeout
        while self._waiting:
            pid, first = next(iter(self._waiting.items()))
            if first.deadline > now:
                return
            del self._waiting[pid]
            self._error(
                first.item,
                "unpaired",
                f"measurement of {pid} not diagnosed: no passage "
                f"{pid} within the pairing timeout of {timeout:g} s",
                pid,
            )

    def _diagnose(self, passage: WheelPassage, measured: MeasuredPassage, item: Inbound) -> None:
        pid = passage.passage_id
        self.before_diagnosis()  # the passage's result goes out first
        try:
            outcome = self.physics.diagnose(passage, measured)
        except MeasurementError as exc:
            self._error(
                item, "invalid_measurement", f"measurement of {pid} rejected: {exc}", pid, exc.field
            )
            return
        except (BudgetExceededError, WorkerCrashedError) as exc:
            self._error(item, "simulation_failed", str(exc), pid)
            return
        except Exception as exc:  # never let one diagnosis kill the service
            self._error(
                item,
                "simulation_failed",
                f"measurement of {pid} could not be diagnosed: {type(exc).__name__}: {exc}",
                pid,
            )
            return
        if outcome.calibration is not None:
            self.calibration = outcome.calibration
        # the wheel and the passage's time, whatever the diagnoser filled in (the fleet files
        # each diagnosis under its wheel, site and date)
        diag = outcome.diagnosis.model_copy(
            update={"wheel": passage.wheel, "timestamp": passage.timestamp}
        )
        self._diagnosed[pid] = None  # a refused measurement may be sent again, corrected
        while len(self._diagnosed) > KEPT_DIAGNOSED:
            self._diagnosed.popitem(last=False)
        data = diag.model_dump_json().encode()
        self.diagnoses.add(pid, made_at=time.time(), timestamp=passage.timestamp, data=data)
        keys = self.output.keys
        self.done += 1  # counted before it is published, as a passage's result
        self.output.put(keys.diagnosis(pid), f"{keys.prefix}/diagnosis", Diagnosis, data)
        recorder = self.output.recorder
        if recorder is not None:
            recorder.diagnosis(
                diag, outcome.t, outcome.measured, outcome.fitted, outcome.x, outcome.impacts_x
            )
