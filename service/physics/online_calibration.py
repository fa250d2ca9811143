"""The twin's online calibration: the track's values updated from the round wheels it sees.

A measured passage the diagnosis dismisses as round (no flat found) is a calibration wheel:
its channels' residual and Jacobian (``sim_core.calibration``) update
the values recursively (``sim_core.calibration.recursive``), each value moving by at most
``Limits.max_step`` per wheel and staying within ``Limits.max_range`` of the site file's, so
that one odd wheel cannot move the calibration; a wheel whose channels the current track
explains worse than ``ODD`` times their noise is not round after all (or not what its
passage says) and is left out. Each wheel's residual and Jacobian are taken at the values of
the last linearisation (the track's reductions there, one per value plus one, are kept in
memory), linearised to the current values, until those have moved by ``RELINEARISE``: a
wheel costs one simulation per value plus one, and a reduction only now and then.

The state (values, information, the last ``HISTORY`` updates) is kept in
``<state dir>/<site_id>.calibration.json``, written atomically after each update and read at
start: it survives a restart. It belongs to the site file's foundation it started from
(``start_id``); a site file with another foundation starts afresh (logged).

``site()`` is the site with the current values and a ``[calibration]`` table (source
``online``), ``ref()`` its ``CalibrationRef``, ``recalibrate(diagnoser)`` the diagnoser on it
(``Diagnoser.recalibrated``), ``drift()`` how far the values have moved.

``SharedCalibration`` is how the service's worker processes run it: several workers share
one state file, each taking an exclusive ``flock`` on ``<site_id>.calibration.lock`` beside it
around load-observe-save and reading the file again whenever another worker has changed it;
at most one calibration wheel per ``interval`` seconds per site (the state file's time), since
each new calibration makes every worker reduce the new track anew (seconds, after its reply).
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import math
import os
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from pydantic import ValidationError

from schemas.calibration import (
    HISTORY,
    CalibratedParameter,
    CalibrationRef,
    OnlineCalibrationState,
    OnlineStep,
    SiteCalibration,
)
from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from schemas.track import DiscreteFoundation, SlabFoundation
from service.physics import inputs as physics_inputs
from service.physics.calibration import check_site, check_wheel, foundation_with, passage_of
from service.physics.model_version import foundation_fingerprint
from sim_core.calibration import parameters, recursive
from sim_core.calibration.estimator import PRIOR_SD, Z95
from sim_core.calibration.identifiability import judge
from sim_core.calibration.residuals import Site, noise_sigma, residual
from sim_core.calibration.sensitivities import jacobian
from sim_core.diagnosis.sensor import SensorModel

if TYPE_CHECKING:
    from service.physics.diagnosis import Diagnoser

__all__ = ["ODD", "RELINEARISE", "Drift", "OnlineCalibration", "SharedCalibration"]

log = logging.getLogger(__name__)

ODD = 2.0
"""A wheel whose residual rms exceeds this many times its noise is left out."""

RELINEARISE = 0.05
"""The track is reduced anew when a log-factor has moved this far since the last linearisation."""


@dataclass(frozen=True)
class Drift:
    """How far the calibration has moved: each value over the site file's, now and
    ``window`` wheels ago, and the wheels in all."""

    names: tuple[str, ...]
    factors: tuple[float, ...]
    factors_before: tuple[float, ...]
    window: int
    wheels: int

    def line(self) -> str:
        """One line for a log or Health."""
        parts = [
            f"{n} x{f:.3f} ({100 * (f / b - 1):+.1f} % in {self.window})"
            for n, f, b in zip(self.names, self.factors, self.factors_before, strict=True)
        ]
        return f"calibration after {self.wheels} wheels: " + ", ".join(parts)


class OnlineCalibration:
    """The calibration of one site's track as the twin learns it (module docstring)."""

    def __init__(
        self,
        site: SiteConfig,
        state_dir: Path | None = None,
        limits: recursive.Limits | None = None,
    ) -> None:
        self.start_site = site
        self.track = check_site(site)
        self.limits = limits or recursive.Limits()
        self.names = parameters.names(self.track)
        self.start_values = parameters.values(self.track)
        f = site.foundation
        assert isinstance(f, (DiscreteFoundation, SlabFoundation))
        self.start_id = foundation_fingerprint(f)
        self.sim_site = Site(
            physics_inputs.cribs(site.detector),
            SensorModel(site.diagnosis.sensor_lowpass_hz, site.diagnosis.sensor_lowpass_order),
        )
        self.path = None if state_dir is None else state_dir / f"{site.site_id}.calibration.json"
        self.state = recursive.start(len(self.names), PRIOR_SD)
        self.history: list[OnlineStep] = []
        self._lin: np.ndarray | None = None
        """Where the track's reductions were last made (they are kept in memory)."""
        self._load()

    # --- persistence ----------------------------------------------------------------------

    def _load(self) -> None:
        if self.path is None or not self.path.exists():
            return
        try:
            kept = OnlineCalibrationState.model_validate_json(self.path.read_text("utf-8"))
        except (OSError, UnicodeDecodeError, ValidationError) as exc:
            log.warning("online calibration %s unreadable, starting afresh: %s", self.path, exc)
            return
        if kept.start_id != self.start_id or tuple(kept.names) != self.names:
            log.warning(
                "online calibration %s was learned on another foundation (%s, now %s): "
                "starting afresh",
                self.path,
                kept.start_id,
                self.start_id,
            )
            return
        self.state = recursive.State(
            tuple(kept.z), tuple(tuple(r) for r in kept.information), kept.wheels
        )
        self.history = list(kept.history)

    def reload(self) -> None:
        """Read the state file again (another process has changed it)."""
        self.state = recursive.start(len(self.names), PRIOR_SD)
        self.history = []
        self._load()

    def _save(self) -> None:
        if self.path is None:
            return
        doc = OnlineCalibrationState(
            site_id=self.start_site.site_id,
            start_id=self.start_id,
            names=list(self.names),  # type: ignore[arg-type]
            start=list(self.start_values),
            z=list(self.state.z),
            information=[list(r) for r in self.state.information],
            wheels=self.state.wheels,
            history=self.history[-HISTORY:],
        )
        self.path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{self.path.name}.", dir=self.path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as f:
                f.write(doc.model_dump_json(indent=1))
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise

    # --- learning -------------------------------------------------------------------------

    @property
    def factors(self) -> tuple[float, ...]:
        """Each value over the site file's, now."""
        return tuple(math.exp(z) for z in self.state.z)

    def observe(
        self, passage: WheelPassage, measured: MeasuredPassage, diagnosis: Diagnosis | None
    ) -> OnlineStep | None:
        """Learn from one measured passage if it is a round wheel the diagnosis dismissed
        (``diagnosis.flat`` None) and the current track explains it within ``ODD`` times its
        noise; the update made, or None."""
        if diagnosis is not None and diagnosis.flat is not None:
            return None
        if check_wheel(self.start_site, passage, measured) is not None:
            return None
        wheel = passage_of(self.start_site, passage.passage_id, passage, measured)
        z = np.array(self.state.z)
        if self._lin is None or float(np.max(np.abs(z - self._lin))) >= RELINEARISE:
            self._lin = z.copy()
        z_lin = self._lin
        track = parameters.scaled(self.track, z_lin)
        raw = residual(track, wheel, self.sim_site, 1.0)
        sigma = noise_sigma(raw)
        if not (sigma > 0.0 and math.isfinite(sigma)):
            return None
        r_lin = raw / sigma
        jac = jacobian(self.track, z_lin, [wheel], self.sim_site, [sigma], [r_lin])[0]
        r = r_lin - jac @ (z - z_lin)  # the residual at the current values, linearised
        ratio = float(np.sqrt(np.mean(r**2)))
        if ratio > ODD:
            log.info(
                "online calibration: %s left out, residual %.2f x its noise",
                passage.passage_id,
                ratio,
            )
            return None
        self.state, upd = recursive.update(self.state, jac, r, self.limits)
        step = OnlineStep(
            passage_id=passage.passage_id,
            timestamp=passage.timestamp,
            requested=list(upd.requested),
            applied=list(upd.applied),
            factors=list(self.factors),
            residual_ratio=ratio,
        )
        self.history.append(step)
        del self.history[:-HISTORY]
        self._save()
        return step

    # --- what the twin uses ---------------------------------------------------------------

    def site(self) -> SiteConfig:
        """The site file with the current values and a ``[calibration]`` table (``online``)."""
        f = self.start_site.foundation
        assert isinstance(f, (DiscreteFoundation, SlabFoundation))
        values = [v * k for v, k in zip(self.start_values, self.factors, strict=True)]
        new = foundation_with(f, values)
        sd = self.state.sd()
        verdicts = judge(sd, PRIOR_SD)
        params = [
            CalibratedParameter(
                name=n,  # type: ignore[arg-type]
                nominal=v0,
                estimate=v,
                low=v * math.exp(-Z95 * s),
                high=v * math.exp(Z95 * s),
                identifiable=j,
            )
            for n, v0, v, s, j in zip(
                self.names, self.start_values, values, sd, verdicts, strict=True
            )
        ]
        before = self.start_site.calibration
        wheels = self.state.wheels + (before.wheels if before is not None else 0)
        cal = SiteCalibration(
            source="online", id=foundation_fingerprint(new), wheels=wheels, parameters=params
        )
        return self.start_site.model_copy(update={"foundation": new, "calibration": cal})

    def ref(self) -> CalibrationRef:
        """The reference a diagnosis on ``site()`` carries."""
        cal = self.site().calibration
        assert cal is not None
        return cal.ref()

    def recalibrate(self, diagnoser: Diagnoser) -> Diagnoser:
        """The diagnoser on the current calibration (``Diagnoser.recalibrated``)."""
        return diagnoser.recalibrated(self.site())

    def drift(self, window: int = 100) -> Drift:
        """How far the values have moved in all and over the last ``window`` updates."""
        if len(self.history) > window:
            before = tuple(self.history[-window - 1].factors)
        else:
            before = (1.0,) * len(self.names)
        return Drift(
            self.names, self.factors, before, min(window, len(self.history)), self.state.wheels
        )


class SharedCalibration:
    """One site's ``OnlineCalibration`` as the service's worker processes share it (module
    docstring): ``learn`` after a diagnosis, ``refresh`` to take up another worker's update.
    ``interval``: s between calibration wheels at the site (0: every round wheel)."""

    def __init__(self, site: SiteConfig, state_dir: Path, interval: float) -> None:
        if not (math.isfinite(interval) and interval >= 0.0):
            raise ValueError(f"calibration interval must be >= 0 s, got {interval!r}")
        self.cal = OnlineCalibration(site, state_dir)
        assert self.cal.path is not None
        self.path: Path = self.cal.path
        self.lock_path = self.path.with_suffix(".lock")
        self.interval = interval
        self._seen = self._stamp()

    def _stamp(self) -> tuple[int, int, int] | None:
        try:
            st = self.path.stat()
        except OSError:
            return None
        return (st.st_ino, st.st_mtime_ns, st.st_size)

    def refresh(self) -> bool:
        """Read the state again if another process has written it since; whether it had."""
        stamp = self._stamp()
        if stamp == self._seen:
            return False
        self.cal.reload()
        self._seen = stamp
        return True

    def learn(
        self, passage: WheelPassage, measured: MeasuredPassage, diagnosis: Diagnosis
    ) -> OnlineStep | None:
        """``OnlineCalibration.observe`` under the site's lock, on the state as the file has
        it, unless the last calibration wheel was less than ``interval`` s ago."""
        if diagnosis.flat is not None or measured.channels is None:
            return None  # no lock taken for what cannot calibrate
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with self.lock_path.open("a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
            self.refresh()
            last = None if self._seen is None else self._seen[1] / 1e9  # the last update
            if last is not None and time.time() - last < self.interval:
                return None
            step = self.cal.observe(passage, measured, diagnosis)
            self._seen = self._stamp()
        return step
