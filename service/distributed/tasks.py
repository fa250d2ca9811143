"""What runs on a Dask worker: the same physics calls a single process makes, a batch at
a time, and the worker plugin that warms the physics once per worker.

Each task gets the site as JSON (the loaded ``SiteConfig``, a file rail already read into
its samples: a remote worker needs no file) and a batch of items; one ``Diagnoser`` is
kept per site and worker process. A task never raises for one bad item: the item's
error comes back in its outcome, and the batch goes on.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from distributed.diagnostics.plugin import WorkerPlugin

if TYPE_CHECKING:
    from service.physics.diagnosis import Diagnoser

_DIAGNOSERS: dict[str, Diagnoser] = {}
"""One Diagnoser per site (by the SHA-256 of its JSON) in this worker process."""


def diagnoser_for(site_json: str) -> Diagnoser:
    """This process's ``Diagnoser`` of the site ``site_json``, made (and warmed) once."""
    key = hashlib.sha256(site_json.encode()).hexdigest()
    d = _DIAGNOSERS.get(key)
    if d is None:
        from schemas.site import SiteConfig
        from service.physics.diagnosis import Diagnoser

        d = Diagnoser(SiteConfig.model_validate_json(site_json))
        d.warm_up()
        _DIAGNOSERS[key] = d
    return d


class WarmUp(WorkerPlugin):
    """Loads the compiled physics on each worker before its first task (and on a worker
    Dask restarts): the site's diagnoser when ``site_json`` is given, else the scenario
    runner's paths. Numba's cache (``NUMBA_CACHE_DIR``) makes this a load, not a compile,
    once any process of the machine has compiled."""

    name = "railtwin-warm-up"

    def __init__(self, site_json: str | None = None) -> None:
        self.site_json = site_json

    def setup(self, worker: Any) -> None:
        if self.site_json is not None:
            diagnoser_for(self.site_json)
        else:
            from service.physics.scenario_runner import warm_up

            warm_up()


@dataclass(frozen=True)
class Outcome:
    """One item's result: its JSON document or its error, and the seconds it took."""

    key: str
    data: str | None
    error: str | None
    seconds: float


def diagnose_batch(items: list[tuple[str, bytes, bytes]], site_json: str) -> list[Outcome]:
    """Diagnose each (passage id, WheelPassage JSON, MeasuredPassage JSON) at the site;
    each Diagnosis carries the passage's wheel and timestamp (as the twin's does)."""
    from schemas.diagnosis import MeasuredPassage
    from schemas.messages import WheelPassage
    from service.physics.measurement_error import MeasurementError

    d = diagnoser_for(site_json)
    out = []
    for pid, passage_json, measured_json in items:
        start = time.perf_counter()
        try:
            passage = WheelPassage.model_validate_json(passage_json)
            measured = MeasuredPassage.model_validate_json(measured_json)
            diag, _ = d.diagnose(passage, measured)
            diag = diag.model_copy(update={"wheel": passage.wheel, "timestamp": passage.timestamp})
            data, error = diag.model_dump_json(), None
        except MeasurementError as exc:
            data, error = None, f"invalid_measurement: {exc}"
        except Exception as exc:  # one wheel's failure is its row's, not the batch's
            data, error = None, f"simulation_failed: {type(exc).__name__}: {exc}"
        out.append(Outcome(pid, data, error, time.perf_counter() - start))
    return out


def noop_batch(items: list[Any], *_: Any) -> list[Outcome]:
    """Does nothing: the benchmark's measure of Dask's own cost per task."""
    return [Outcome(str(i), None, None, 0.0) for i in items]
