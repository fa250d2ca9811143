"""The site's physics in a worker process, so that the twin never goes deaf.

The compiled physics (numba) never releases the GIL: run in the service's own
process, one long passage would stop the Zenoh callbacks, the health and rail
queryables, the overload policy and the signal handler for as long as it runs.
``ProcessPhysics`` runs a ``SitePhysics`` (and the diagnosis) in a child process
started with the ``spawn`` context; the twin's worker thread sends it a validated
passage and waits for the result on a pipe, with the GIL released.

Each call has a wall-time budget (``--passage-budget``, default 30 s). A call
that overruns it is aborted by killing the child; a new child is started from
the rail as it was after the last passage (a plastic site's dents are kept: the
child returns the dented rail with every result that dented it) and the call
raises ``BudgetExceededError``, which the twin reports as ``simulation_failed``.

The rail state (``RailState``) is cached here, so ``railtwin/<site>/rail`` is
answered without asking the child.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import multiprocessing
import os
import queue
import threading
import time
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from schemas.diagnosis import MeasuredPassage
from schemas.messages import PassageResult, RailState, WheelPassage
from schemas.site import SiteConfig
from service.physics.local import diagnose_with, make_model
from service.physics.parent_watch import exit_when_orphaned
from service.physics.port import (
    BudgetExceededError,
    DiagnosisOutcome,
    MeasurementError,
    PhysicsKind,
    RailSnapshot,
    Series,
    Simulated,
    SiteModel,
    WorkerCrashedError,
)
from service.physics.rail_store import RailStore
from service.wire.child_process import ignore_stop_signals, start_shielded
from service.wire.encoding import RESULT_ARRAYS, series_json
from sim_core.rail import RailProfile

if TYPE_CHECKING:
    from multiprocessing.connection import Connection
    from multiprocessing.process import BaseProcess

    from schemas.diagnosis import Diagnosis
    from service.physics.diagnosis import Diagnoser
    from service.physics.online_calibration import SharedCalibration
    from service.physics.site_physics import SitePhysics

log = logging.getLogger("railtwin.physics")

T = TypeVar("T")

CALIBRATION_INTERVAL = 300.0
"""s: by default a site's twin learns from at most one round wheel per this time: each new
calibration costs every worker a reduction of the new track (seconds)."""

START_TIMEOUT = 600.0
"""s a new worker may take to import, compile (first run without a cache) and warm up."""


# --- the child ---------------------------------------------------------------------------------


def _child_main(
    site: SiteConfig,
    kind: PhysicsKind,
    conn: Connection,
    snapshot: RailSnapshot | None,
    parent_pid: int,
    calibration: OnlineSetting | None = None,
) -> None:
    ignore_stop_signals()  # the service stops us (through the pipe), not the terminal
    exit_when_orphaned(parent_pid)  # even while compiling, when the pipe is not read
    from pydantic import ValidationError

    own: SitePhysics | None = None  # the site's own physics: it diagnoses too
    physics: SiteModel
    if kind == "sim_core":
        from service.physics.site_physics import SitePhysics

        physics = own = SitePhysics(site)
    else:
        physics = make_model(kind, site)
    if snapshot is not None:
        physics.restore_rail(*snapshot)
    diagnoser: Diagnoser | None = None
    shared = None if own is None or calibration is None else _shared(site, calibration)

    def new_diagnoser() -> Diagnoser:
        from service.physics.diagnosis import Diagnoser

        assert own is not None
        made = Diagnoser(site, physics=own)
        return made if shared is None else _adopt(shared, made)

    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):  # the service is gone
            return
        op = msg[0]
        try:
            if op == "warm_up":
                start = time.perf_counter()
                if msg[1]:
                    physics.warm_up()
                if own is not None and msg[1]:  # ready before the first measurement
                    diagnoser = new_diagnoser()
                    diagnoser.warm_up()
                conn.send(("ok", time.perf_counter() - start, physics.rail_state()))
            elif op == "simulate":
                result = physics.simulate(msg[1])
                data = result.model_dump_json().encode()
                dented = None
                if result.summary.max_dent > 0.0:
                    dented = (physics.rail_snapshot(), physics.rail_state())
                series: Series | None = None
                if msg[
                    2
                ]:  # the series too; the result crosses without its arrays (its JSON has them)
                    n = len(result.x)
                    series = (
                        series_json(result, "force", 0, n, 0, 1),
                        series_json(result, "indentation", 0, n, 0, 1),
                    )
                    light: dict[str, object] = {key: [] for key in RESULT_ARRAYS}
                    result = result.model_copy(update={**light, "channels": None})
                conn.send(("ok", result, data, dented, series))
            elif op == "diagnose":
                if diagnoser is None:
                    if own is None:
                        raise ValueError(
                            "this physics does not diagnose (it needs the site's "
                            "own physics, --physics sim_core)"
                        )
                    diagnoser = new_diagnoser()
                outcome = diagnose_with(diagnoser, msg[1], msg[2])
                if shared is not None:
                    line = shared.cal.drift().line()
                    outcome = dataclasses.replace(outcome, calibration=line)
                conn.send(("ok", outcome))
                if shared is not None:  # after the verdict is sent: not in its latency
                    diagnoser = _learn(shared, diagnoser, msg[1], msg[2], outcome.diagnosis)
            elif op == "stop":
                conn.send(("ok",))
                return
            else:
                conn.send(("internal", f"unknown request {op!r}"))
        except MeasurementError as exc:
            conn.send(("refused", exc.field, exc.message))
        except (ValueError, ArithmeticError, ValidationError) as exc:
            conn.send(("failed", str(exc)))
        except Exception as exc:  # reported to the twin, the worker goes on
            conn.send(("internal", f"{type(exc).__name__}: {exc}"))


@dataclasses.dataclass(frozen=True)
class OnlineSetting:
    """Where the online calibration persists (the service's state dir) and the least time
    between two calibration wheels at the site (``service.physics.online_calibration``)."""

    state_dir: Path
    interval: float


def _shared(site: SiteConfig, setting: OnlineSetting) -> SharedCalibration | None:
    """The site's shared online calibration, or None where there is none to learn (no
    detector, or not a rail on supports) or it cannot start (logged)."""
    from schemas.track import DiscreteFoundation, SlabFoundation
    from service.physics.online_calibration import SharedCalibration

    if site.detector is None or not isinstance(
        site.foundation, (DiscreteFoundation, SlabFoundation)
    ):
        return None
    try:
        return SharedCalibration(site, setting.state_dir, setting.interval)
    except Exception:  # the diagnosis goes on, on the site file's values
        log.exception("online calibration of %s could not start", site.site_id)
        return None


def _adopt(shared: SharedCalibration, diagnoser: Diagnoser) -> Diagnoser:
    """``diagnoser`` on the shared calibration's current values (itself when it has them)."""
    cal = shared.cal
    if cal.state.wheels == 0 or cal.ref().id == diagnoser.calibration.id:
        return diagnoser
    new = cal.recalibrate(diagnoser)
    new.warm_up()  # the new track's reduction (seconds; then from the disk store)
    log.info("online calibration: %s, id %s", cal.drift().line(), new.calibration.id)
    return new


def _learn(
    shared: SharedCalibration,
    diagnoser: Diagnoser,
    passage: WheelPassage,
    measured: MeasuredPassage,
    diagnosis: Diagnosis,
) -> Diagnoser:
    """Learn from a diagnosed wheel and take up the current calibration; a failure is logged
    and the diagnoser kept (the diagnosis was sent already)."""
    try:
        shared.learn(passage, measured, diagnosis)
        shared.refresh()
        return _adopt(shared, diagnoser)
    except Exception:
        log.exception("online calibration: %s not learned from", passage.passage_id)
        return diagnoser


# --- the twin's side ---------------------------------------------------------------------------


class StartCancelledError(WorkerCrashedError):
    """The service was told to stop while a worker was starting."""


class ProcessPhysics:
    """One ``SiteModel`` (and the diagnosis) in a worker process.

    One call at a time; ``rail_state`` never waits for the worker.
    """

    def __init__(
        self,
        site: SiteConfig,
        kind: PhysicsKind = "sim_core",
        *,
        budget: float = 30.0,
        warm_up: bool = True,
        start_timeout: float = START_TIMEOUT,
        store: RailStore | None = None,
        calibration: OnlineSetting | None = None,
    ) -> None:
        self.site = site
        self.store = store
        self.calibration = calibration
        """Where and how often the worker calibrates online (None: it does not)."""
        self.calibration_line: str | None = None
        """The online calibration's drift as the last diagnosis used it."""
        self.kind = kind
        self.budget = budget
        self.warm_up_enabled = warm_up
        self.start_timeout = start_timeout
        self.restarts = 0
        self.warm_up_seconds = 0.0
        self._ctx = multiprocessing.get_context("spawn")
        self._proc: BaseProcess | None = None
        self._conn: Connection | None = None
        self._lock = threading.Lock()
        self.cancelled = threading.Event()
        """Set (``PhysicsPool.cancel``) to abandon a start under way (the service stops)."""
        self._snapshot: RailSnapshot | None = None
        self._state: RailState | None = None
        self._done = 0
        if store is not None:  # go on from the rail as the last run left it
            self._done = store.applied_count()
            saved = store.load()
            if saved is not None:
                self._snapshot = (RailProfile.sampled(saved.x, saved.y), saved.revision, self._done)

    @property
    def diagnoses(self) -> bool:
        """Whether this physics can diagnose measurements (the site's own physics)."""
        return self.kind == "sim_core"

    @property
    def pid(self) -> int | None:
        return self._proc.pid if self._proc is not None else None

    def start(self) -> float:
        """Start the worker and warm it up; returns the warm-up's seconds (in the worker)."""
        with self._lock:
            self._spawn()
        return self.warm_up_seconds

    def _spawn(self) -> None:
        parent, child = self._ctx.Pipe()
        proc = self._ctx.Process(
            target=_child_main,
            name="railtwin-physics",
            args=(self.site, self.kind, child, self._snapshot, os.getpid(), self.calibration),
            daemon=True,
        )
        start_shielded(proc)  # a signal to the group while it starts is not its death
        child.close()
        self._proc, self._conn = proc, parent
        parent.send(("warm_up", self.warm_up_enabled))
        deadline = time.monotonic() + self.start_timeout
        while not parent.poll(0.1):  # in slices: a stop during warm-up is heard
            if self.cancelled.is_set():
                self._kill()
                raise StartCancelledError("the physics worker's start was cancelled")
            if time.monotonic() > deadline:
                self._kill()
                raise RuntimeError(
                    f"the physics worker did not start within {self.start_timeout:g} s"
                )
        try:
            reply = parent.recv()
        except (EOFError, OSError) as exc:
            self._kill()
            raise RuntimeError("the physics worker died while starting") from exc
        if reply[0] != "ok":
            raise RuntimeError(f"the physics worker failed to start: {reply[1:]}")
        self.warm_up_seconds = float(reply[1])
        if self._state is None:
            self._state = reply[2]

    def _kill(self) -> None:
        proc, conn = self._proc, self._conn
        self._proc = self._conn = None
        if conn is not None:
            conn.close()
        if proc is not None and proc.is_alive():
            proc.kill()
        if proc is not None:
            proc.join(5.0)

    def _call(self, what: str, msg: tuple[Any, ...]) -> tuple[Any, ...]:
        with self._lock:
            if self._conn is None:
                self._spawn()
            conn = self._conn
            assert conn is not None
            try:
                conn.send(msg)
                if not conn.poll(self.budget):
                    self._kill()  # a new worker is started for the next call
                    self.restarts += 1
                    log.warning(
                        "%s: over the budget of %g s; the worker was killed and is restarted",
                        what,
                        self.budget,
                    )
                    raise BudgetExceededError(what, self.budget)
                reply: tuple[Any, ...] = conn.recv()
            except (EOFError, OSError, BrokenPipeError) as exc:
                code = self._proc.exitcode if self._proc is not None else None
                self._kill()
                self.restarts += 1
                log.warning(
                    "%s: the physics worker died (exit code %s); it is restarted", what, code
                )
                raise WorkerCrashedError(
                    f"{what}: the physics worker died (exit code {code}); it was restarted"
                ) from exc
        kind = reply[0]
        if kind == "ok":
            return reply
        if kind == "refused":
            raise MeasurementError(reply[1], reply[2])
        if kind == "failed":
            raise ValueError(reply[1])
        raise RuntimeError(f"{what}: {reply[1]}")

    # --- simulation ------------------------------------------------------------------------

    def simulate_json(self, passage: WheelPassage) -> tuple[PassageResult, bytes]:
        """The result of ``passage`` and its JSON (made in the worker)."""
        result, data, _ = self.simulate_parts(passage, light=False)
        return result, data

    def simulate_parts(
        self, passage: WheelPassage, light: bool
    ) -> tuple[PassageResult, bytes, Series | None]:
        """The result, its JSON and, when ``light``, the series' JSON with a result whose
        arrays are empty (less to send across and to decode: the JSON is complete)."""
        _, result, data, dented, series = self._call(
            f"passage {passage.passage_id}", ("simulate", passage, light)
        )
        self._done += 1
        if dented is not None:  # a plastic site's new rail: a restarted worker goes on from it
            self._snapshot, self._state = dented
        elif self._snapshot is not None:
            profile, revision, _ = self._snapshot
            self._snapshot = (profile, revision, self._done)
        if self.store is not None:  # committed before it is published
            snap = self._snapshot
            dented_rail = snap[0] if dented is not None and snap is not None else None
            self.store.commit(
                passage.passage_id,
                snap[1] if snap is not None else 0,
                None if dented_rail is None else dented_rail.x,
                None if dented_rail is None else dented_rail.y,
            )
        return result, data, series

    def already_applied(self, passage_id: str) -> int | None:
        """The rail revision ``passage_id`` was applied at in this or an earlier run, or None."""
        return None if self.store is None else self.store.applied_revision(passage_id)

    def simulate(self, passage: WheelPassage) -> PassageResult:
        return self.simulate_json(passage)[0]

    def diagnose(self, passage: WheelPassage, measured: MeasuredPassage) -> DiagnosisOutcome:
        out: DiagnosisOutcome = self._call(
            f"measurement of {passage.passage_id}", ("diagnose", passage, measured)
        )[1]
        if out.calibration is not None and out.calibration != self.calibration_line:
            self.calibration_line = out.calibration
            log.info("%s: online %s", self.site.site_id, out.calibration)
        return out

    @property
    def passages_done(self) -> int:
        return self._done

    def rail_state(self) -> RailState:
        state = self._state
        if state is None:
            raise RuntimeError("the physics worker has not started")
        return state.model_copy(update={"passages_done": self._done})

    def close(self, timeout: float = 5.0) -> None:
        """Stop the worker (at once if it is busy: the caller has stopped sending)."""
        conn, proc = self._conn, self._proc
        if conn is not None and proc is not None and self._lock.acquire(timeout=0.1):
            try:
                with contextlib.suppress(OSError, EOFError, BrokenPipeError):
                    conn.send(("stop",))
                    if conn.poll(timeout):
                        conn.recv()
                proc.join(timeout)
            finally:
                self._lock.release()
        self._kill()


class PhysicsPool:
    """``workers`` worker processes; passages are submitted and their futures kept in order.

    With an elastic contact law the passages are independent and several workers simulate in
    parallel; a plastic site (``hertz_plastic``: each wheel rolls on the dents of the ones
    before) must have one. Even with one worker the twin publishes a result while the next
    passage is simulated.
    """

    def __init__(
        self,
        site: SiteConfig,
        kind: PhysicsKind = "sim_core",
        *,
        workers: int = 1,
        budget: float = 30.0,
        warm_up: bool = True,
        store: RailStore | None = None,
        calibration: OnlineSetting | None = None,
    ) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        if workers > 1 and site.contact == "hertz_plastic":
            raise ValueError(
                "a hertz_plastic site needs one worker: every passage rolls on the "
                "dents of the ones before"
            )
        self.site = site
        self.kind = kind
        self.store = store
        self.workers = [
            ProcessPhysics(
                site, kind, budget=budget, warm_up=warm_up, store=store, calibration=calibration
            )
            for _ in range(workers)
        ]
        self._idle: queue.SimpleQueue[ProcessPhysics] = queue.SimpleQueue()
        for w in self.workers:
            self._idle.put(w)
        self._executor = ThreadPoolExecutor(
            max_workers=workers, thread_name_prefix="railtwin-physics"
        )

    @property
    def size(self) -> int:
        return len(self.workers)

    @property
    def concurrent(self) -> bool:
        return True

    @property
    def diagnoses(self) -> bool:
        return self.kind == "sim_core"

    @property
    def pids(self) -> list[int | None]:
        return [w.pid for w in self.workers]

    @property
    def restarts(self) -> int:
        return sum(w.restarts for w in self.workers)

    def start(self) -> float:
        """Start the workers one after the other (the first one fills numba's cache, the
        others load it rather than all compiling at once); returns the longest warm-up, s."""
        return max(w.start() for w in self.workers)

    def cancel(self) -> None:
        """Abandon the starts under way (safe from a signal handler: it only sets flags)."""
        for w in self.workers:
            w.cancelled.set()

    def _with_worker(self, call: Callable[[ProcessPhysics], T]) -> T:
        worker = self._idle.get()
        try:
            return call(worker)
        finally:
            self._idle.put(worker)

    def submit(self, passage: WheelPassage, light: bool = False) -> Future[Simulated]:
        """Simulate ``passage`` on the next free worker; the future holds the result, its JSON,
        the rail right after it (a plastic site's dents as this passage left them) and, when
        ``light``, the series (``ProcessPhysics.simulate_parts``)."""

        def run(w: ProcessPhysics) -> Simulated:
            result, data, series = w.simulate_parts(passage, light)
            return Simulated(result, data, w.rail_state(), series)

        return self._executor.submit(self._with_worker, run)

    def already_applied(self, passage_id: str) -> int | None:
        """The rail revision ``passage_id`` was applied at (state on disk), or None."""
        return None if self.store is None else self.store.applied_revision(passage_id)

    def simulate_json(self, passage: WheelPassage) -> tuple[PassageResult, bytes]:
        done = self.submit(passage).result()
        assert done.data is not None  # a worker always sends the result's JSON
        return done.result, done.data

    def simulate(self, passage: WheelPassage) -> PassageResult:
        return self.simulate_json(passage)[0]

    def diagnose(self, passage: WheelPassage, measured: MeasuredPassage) -> DiagnosisOutcome:
        out: DiagnosisOutcome = self._executor.submit(
            self._with_worker, lambda w: w.diagnose(passage, measured)
        ).result()
        return out

    def rail_state(self) -> RailState:
        state = self.workers[0].rail_state()
        if len(self.workers) == 1:
            return state
        return state.model_copy(
            update={"passages_done": sum(w.passages_done for w in self.workers)}
        )

    def close(self, timeout: float = 5.0) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
        for w in self.workers:
            w.close(timeout)
