"""The twin's diagnosis of one measured passage: messages in, ``Diagnosis`` out.

Composes ``sim_core.diagnosis`` with the site file: the site's rail (as the round
wheel's constraint, kept per radius), contact law, foundation and measuring chain
(``[diagnosis]``), and the limits that make the verdict. Bad measurements are refused
with ``MeasurementError`` naming the field; the service turns it into a ServiceError,
the CLI into exit status 2.

Two measurements, two fits: a contact force on a rigid or compliant (one-mass) site
(``sim_core.diagnosis.estimate``), or a detector's crib channels on a rail on discrete
supports or slab (``sim_core.diagnosis.crib_fit``: the twin simulates the site's cribs
through the site's chain on the site file's track). Every ``Diagnosis`` names the
calibration of the track it used (``calibration_ref``); ``Diagnoser.recalibrated`` swaps in
a site file with a new foundation or calibration at run time.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import NDArray

from schemas.diagnosis import Diagnosis, FlatFinding, MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.physics import inputs as physics_inputs
from service.physics.measurement_error import MeasurementError
from service.physics.model_version import calibration_ref, model_version
from service.physics.site_physics import SitePhysics
from service.wire.measured_channels import CHANNELS_FIELD, channels_mismatch
from sim_core.diagnosis.crib_fit import CribEstimate, fit_channels, flat_of
from sim_core.diagnosis.crib_forward import CribSite, CribWheel, line_times
from sim_core.diagnosis.crib_screen import rough_rail_load, round_template
from sim_core.diagnosis.estimate import (
    DEFAULT_OPTIONS,
    DEPTH_FACTORS,
    EXPLAINED_RATIO,
    FlatEstimate,
    estimate_flat,
    explains,
    make_flat,
    residual_ratio,
)
from sim_core.diagnosis.forked import Forked
from sim_core.diagnosis.forward import (
    Flat,
    FlatKind,
    RailTables,
    WheelOnSite,
    damping_ratio_of,
    flat_times,
    simulate_passage_run_in,
    with_damping_ratio,
)
from sim_core.diagnosis.sensor import SensorModel
from sim_core.diagnosis.verdict import Limits, verdict
from sim_core.passage import IntegrationError
from sim_core.track.spec import TrackSpec

__all__ = ["EXPLAINED_RATIO", "Diagnoser", "FitCurves", "IntegrationError", "MeasurementError"]

MIN_RECORD_FRACTION = 0.5
"""A record must cover at least this fraction of the wheel's time on the site."""

SPEED_MISMATCH = 0.05
"""A measured speed further than this (relative) from the passage's is refused."""

LINE_DAMPING_BAND = 0.5
"""Relative band of the fitted damping ratio over which the line-speed forecast is taken."""

LINE_DAMPING_FLOOR = 0.02
"""Added to the band's upper damping ratio (a fit at ζ = 0 still has a band)."""


UNSIMULATED_REASON = (
    "the line-speed forecast could not be simulated (the integrator did not resolve it): the "
    "verdict stands on the measured peaks and the length"
)


class _Fit(NamedTuple):
    """How well a fit explains its record: the verdict's ``_judge`` reads it."""

    explained: bool
    rms: float
    noise: float
    ratio: float

    @classmethod
    def of(cls, rms: float, noise: float) -> _Fit:
        """A fit of residual ``rms`` on a record of noise ``noise`` (N)."""
        return cls(explains(rms, noise), rms, noise, residual_ratio(rms, noise))

    @property
    def reported_ratio(self) -> float | None:
        """The residual ratio as a diagnosis reports it (None where it is not finite)."""
        return self.ratio if math.isfinite(self.ratio) else None


@dataclass(frozen=True)
class FitCurves:
    """What the Rerun recording draws: measured and best-fit force at the measured times,
    the fitted windows and the impacts (flat under the wheel) along the site."""

    t: NDArray[np.float64]
    x: NDArray[np.float64]
    measured: NDArray[np.float64]
    fitted: NDArray[np.float64]
    impacts_t: NDArray[np.float64]
    estimate: FlatEstimate | CribEstimate
    """The fit's own answer: a ``FlatEstimate`` for a contact force, a ``CribEstimate``
    for channels (``force_estimate`` narrows to the first)."""

    @property
    def force_estimate(self) -> FlatEstimate:
        """``estimate`` of a contact-force fit (``TypeError`` for a channel fit)."""
        if not isinstance(self.estimate, FlatEstimate):
            raise TypeError("FitCurves: a channel fit has no FlatEstimate")
        return self.estimate


class Diagnoser:
    """Diagnoses measured passages at one site (one instance per site, reused).

    ``cores``: how many cores one diagnosis may use (2: a forked child searches one kind of
    flat and runs half the line-speed band, ``sim_core.diagnosis.forked``). ``railtwin
    diagnose`` uses the machine's; the service keeps 1, its workers diagnose one wheel each.
    The result does not depend on it.
    """

    def __init__(
        self, site: SiteConfig, physics: SitePhysics | None = None, cores: int = 1
    ) -> None:
        if cores < 1:
            raise ValueError(f"Diagnoser: cores must be at least 1, got {cores}")
        self.site = site
        self.options = replace(DEFAULT_OPTIONS, cores=cores)
        self.physics = physics if physics is not None else SitePhysics(site)
        cfg = site.diagnosis
        self.sensor = SensorModel(cfg.sensor_lowpass_hz, cfg.sensor_lowpass_order)
        self.model_version = model_version(site)
        self.calibration = calibration_ref(site)
        self.rails = RailTables(self.physics.base_rail)
        self.cores = cores
        # the detector on the site's track, where the rail lies on supports and has cribs
        found = self.physics.foundation
        self.crib_site = (
            CribSite(found, self.physics.cribs, self.sensor, site.length)
            if isinstance(found, TrackSpec) and self.physics.cribs
            else None
        )
        self.limits = Limits(
            cfg.watch_force,
            cfg.inspect_force,
            cfg.remove_force,
            cfg.watch_length,
            cfg.inspect_length,
            cfg.remove_length,
        )

    @property
    def diagnoses_here(self) -> bool:
        """Whether this site's measurements can be diagnosed: a contact force on a rigid or
        one-mass foundation, or crib channels on a rail on supports with a detector."""
        return (
            physics_inputs.lumped(self.physics.foundation) is not None or self.crib_site is not None
        )

    def recalibrated(self, site: SiteConfig) -> Diagnoser:
        """A diagnoser for ``site``: the same site with a new foundation or ``[calibration]``
        (``railtwin calibrate``'s file, or the twin's online calibration). Every later
        ``Diagnosis`` names the new calibration. The site's rail physics are rebuilt (the
        dents the twin tracks live in ``SitePhysics``, not here); this instance is left as it
        was, so a diagnosis under way finishes on the calibration it started with.
        The track's reduction to modes is redone for a new track (seconds, once; ``warm_up``
        does it ahead of the first wheel)."""
        if site.site_id != self.site.site_id:
            raise ValueError(
                f"Diagnoser.recalibrated: site {site.site_id!r} is not {self.site.site_id!r}"
            )
        return Diagnoser(site, cores=self.cores)

    def warm_up(self) -> float:
        """Diagnose one synthetic flat wheel (compiles the fit's kernels); returns seconds.

        Nothing to warm (0 s) at a site the diagnosis does not model (``diagnoses_here``)."""
        from sim_core.diagnosis.synthetic import Perturbations, synthetic_measurement

        if not self.diagnoses_here:
            return 0.0
        start = time.perf_counter()
        if self.crib_site is not None:
            self.crib_site.prepare()
            if physics_inputs.lumped(self.physics.foundation) is None:
                return time.perf_counter() - start
        probe = WheelPassage(
            passage_id="warm-up",
            train_id="warm-up",
            axle_index=0,
            side="right",
            timestamp=0.0,
            speed=30.0,
            load=60e3,
            mass=600.0,
            radius=0.46,
        )
        wheel = self.wheel(probe)
        rate = self.site.diagnosis.sample_rate or 10_000.0
        m = synthetic_measurement(
            wheel,
            probe.speed,
            Flat.ideal(0.46, 0.04, 1.0),
            self.physics.base_rail,
            self.site.length,
            rate,
            self.sensor,
            Perturbations(roughness_rms=0.0, seed=0),
        )
        estimate_flat(wheel, probe.speed, m.t, m.force, self.sensor)
        return time.perf_counter() - start

    def wheel(self, passage: WheelPassage) -> WheelOnSite:
        """The passage's wheel on this site, as the fit models it; ``MeasurementError``
        (field ``foundation``) at a site whose rail lies on discrete supports."""
        foundation = physics_inputs.lumped(self.physics.foundation)
        if foundation is None:
            raise MeasurementError(
                "foundation",
                f"the site's foundation is {self.site.foundation.kind!r}: the diagnosis "
                "fits a rigid or compliant (one-mass) foundation only, not yet a rail on "
                "discrete supports",
            )
        return WheelOnSite(
            passage.mass,
            passage.load,
            passage.radius,
            self.physics.contact_model(passage),
            foundation,
            self.site.rtol,
        )

    def check_channels(self, measured: MeasuredPassage) -> None:
        """Refuse a channel measurement whose ids are not the site's cribs, or one at a site
        the channels cannot be fitted (``MeasurementError``, field ``channels``). A
        contact-force measurement passes."""
        if measured.channels is None:
            return
        mismatch = channels_mismatch(measured, self.site)
        if mismatch is not None:
            raise MeasurementError(CHANNELS_FIELD, mismatch)
        if self.crib_site is None:
            raise MeasurementError(
                CHANNELS_FIELD,
                f"the site's foundation is {self.site.foundation.kind!r}: crib channels are "
                "fitted on a rail on discrete supports or slab only",
            )

    def check(self, passage: WheelPassage, measured: MeasuredPassage) -> float:
        """Refuse what cannot be diagnosed; returns the speed to use (m/s)."""
        self.check_channels(measured)
        cfg = self.site.diagnosis
        if measured.passage_id != passage.passage_id:
            raise MeasurementError(
                "passage_id",
                f"{measured.passage_id!r} does not match the passage {passage.passage_id!r}",
            )
        if cfg.sample_rate is not None and not math.isclose(
            measured.sample_rate, cfg.sample_rate, rel_tol=1e-6
        ):
            raise MeasurementError(
                "sample_rate",
                f"{measured.sample_rate:g} Hz does not match the "
                f"site's measuring rate {cfg.sample_rate:g} Hz",
            )
        if (
            cfg.sensor_lowpass_hz is not None
            and cfg.sensor_lowpass_hz >= 0.5 * measured.sample_rate
        ):
            raise MeasurementError(
                "sample_rate",
                f"{measured.sample_rate:g} Hz is too low for the "
                f"site's {cfg.sensor_lowpass_hz:g} Hz measuring chain",
            )
        speed = passage.speed
        if measured.speed is not None:
            if abs(measured.speed / passage.speed - 1.0) > SPEED_MISMATCH:
                raise MeasurementError(
                    "speed",
                    f"measured {measured.speed:g} m/s is more than "
                    f"{SPEED_MISMATCH:.0%} from the passage's {passage.speed:g} m/s",
                )
            speed = measured.speed
        on_site = self.site.length / speed
        if measured.duration < MIN_RECORD_FRACTION * on_site:
            raise MeasurementError(
                "force",
                f"the record lasts {measured.duration * 1e3:.1f} ms, "
                f"less than {MIN_RECORD_FRACTION:.0%} of the "
                f"{on_site * 1e3:.1f} ms the wheel spends on the site",
            )
        overlap = min(measured.t_start + measured.duration, on_site) - max(measured.t_start, 0.0)
        if overlap < MIN_RECORD_FRACTION * on_site:
            raise MeasurementError(
                "t_start",
                f"the record [{measured.t_start:g}, "
                f"{measured.t_start + measured.duration:g}] s covers less than "
                f"{MIN_RECORD_FRACTION:.0%} of the wheel's time on the site [0, {on_site:g}] s",
            )
        if measured.force is not None:
            f = np.asarray(measured.force, dtype=np.float64)
            if float(np.ptp(f)) == 0.0:
                raise MeasurementError("force", "the record is constant: no sensor signal")
        else:
            chans = measured.channels or {}
            if all(float(np.ptp(np.asarray(v))) == 0.0 for v in chans.values()):
                raise MeasurementError(CHANNELS_FIELD, "every channel is constant: no signal")
        return speed

    def diagnose(
        self,
        passage: WheelPassage,
        measured: MeasuredPassage,
        compare: Sequence[tuple[FlatKind, float, float]] = (),
    ) -> tuple[Diagnosis, FitCurves]:
        """The ``Diagnosis`` of one measured passage, and what a recording draws of it.

        ``compare``: flats (kind, length, depth factor) whose cost on the fit's own windows
        comes back in ``FitCurves.estimate.compared`` (validation compares the truth's)."""
        start = time.perf_counter()
        self.check_channels(measured)  # first: ids that are not the site's cribs
        if measured.channels is not None:
            return self._diagnose_channels(passage, measured, start)
        wheel = self.wheel(passage)  # then: a site the fit does not model refuses any record
        speed = self.check(passage, measured)
        t = measured.t_start + np.arange(measured.samples) / measured.sample_rate
        f = np.asarray(measured.force, dtype=np.float64)
        # a round wheel on the site's own rail, as measured: what the screen compares with
        # (should the integrator not resolve it, the screen compares with the static load)
        baseline = self._measure_or_none(wheel, speed, None, float(t[0]), float(t[-1]), t)
        est = estimate_flat(
            wheel, speed, t, f, self.sensor, self.options, baseline=baseline, compare=compare
        )
        fit_wheel = with_damping_ratio(wheel, est.damping_ratio)
        fitted = baseline
        if not est.screened:
            fitted = self._measure_or_none(
                fit_wheel, est.speed, est.flat, float(t[0]), float(t[-1]), t
            )
        refit_failed = fitted is None
        if fitted is None:  # only the drawn curve and peak_force_fit lack it
            fitted = np.full_like(f, passage.load)
        cfg = self.site.diagnosis
        flat = est.flat
        fit = _Fit.of(est.fit_rms, est.noise_level)
        at_line: float | None = None
        line_low: float | None = None
        line_high: float | None = None
        if cfg.line_speed is not None:
            # the site's damper where it states one: the fitted ratio (within a factor 2 of
            # it) is the fit's nuisance, taking up what the twin does not model; the band
            # covers both
            stated = wheel.foundation.is_compliant and wheel.foundation.damping > 0.0
            line_wheel = wheel if stated else fit_wheel
            at_line = self.line_peak(line_wheel, cfg.line_speed, flat, measured.sample_rate)
            line_low, line_high = self._line_band(
                wheel, cfg.line_speed, est, at_line, measured.sample_rate
            )
        unsimulated = cfg.line_speed is not None and (at_line is None or line_high is None)
        finding = None
        if flat is not None:
            finding = FlatFinding(
                kind=flat.kind,
                length=flat.length,
                depth=flat.depth,
                phase=flat.phase,
                length_low=est.length_low,
                length_high=est.length_high,
                depth_factor=est.depth_factor,
            )
        peak_measured = float(np.max(f))
        level, reasons = self._judge(
            "measurement",
            peak_measured,
            flat,
            est.length_high,
            at_line,
            line_high,
            fit,
        )
        if refit_failed:
            reasons.append(
                "the fitted wheel could not be re-simulated over the record (the integrator "
                "did not resolve it): peak_force_fit is the static load"
            )
        if unsimulated:
            reasons.append(UNSIMULATED_REASON)
        impacts = (
            flat_times(passage.radius, est.speed, flat.phase, float(t[0]), float(t[-1]))
            if flat is not None
            else np.empty(0)
        )
        diag = Diagnosis(
            site_id=self.site.site_id,
            passage_id=passage.passage_id,
            flat=finding,
            verdict=level,  # type: ignore[arg-type]
            reasons=reasons,
            peak_force_measured=peak_measured,
            peak_force_fit=float(np.max(fitted)),
            fit_rms=est.fit_rms,
            peak_force_at_line_speed=at_line,
            peak_force_at_line_speed_low=line_low,
            peak_force_at_line_speed_high=line_high,
            noise_level=fit.noise,
            fit_residual_ratio=fit.reported_ratio,
            explained=fit.explained,
            wall_time=time.perf_counter() - start,
            model_version=self.model_version,
            calibration=self.calibration,
            measured="force",
        )
        return diag, FitCurves(t, t * est.speed, f, fitted, impacts, est)

    def _judge(
        self,
        what: Literal["measurement", "channels"],
        peak_measured: float,
        flat: Flat | None,
        length_high: float,
        at_line: float | None,
        line_high: float | None,
        fit: _Fit,
    ) -> tuple[str, list[str]]:
        """The verdict and its reasons, the same whatever was measured: from the fitted flat
        and the forecast where the fit explains the record; else from the measured peaks and
        the upper ends of the length interval and of the forecast's band (a flat is certainly
        there when the record stands this far above its noise, but not the fitted one).
        ``length_high``: the upper end of the fitted flat's length interval (unread without
        a flat)."""
        cfg = self.site.diagnosis
        length = flat.length if flat is not None else None
        top = length_high if flat is not None else None
        if fit.explained:
            return verdict(
                self.limits,
                peak_measured,
                at_line if at_line is not None else line_high,  # the point lost: the band's top
                length,
                cfg.line_speed,
                top,
            )
        level, reasons = verdict(self.limits, peak_measured, line_high, top, cfg.line_speed)
        basis = "the measured peaks" + (
            ", the upper end of the length interval and of the line-speed forecast"
            if length is not None
            else ""
        )
        reasons.insert(
            0,
            f"the fit does not explain the {what} (residual {fit.rms / 1e3:.1f} kN rms = "
            f"{fit.ratio:.1f} x the record's noise {fit.noise / 1e3:.2f} kN > "
            f"{EXPLAINED_RATIO:g}): verdict from {basis}",
        )
        return level, reasons

    def _diagnose_channels(
        self, passage: WheelPassage, measured: MeasuredPassage, start: float
    ) -> tuple[Diagnosis, FitCurves]:
        """The diagnosis from the detector's crib channels (``sim_core.diagnosis.crib_fit``)."""
        cs = self.crib_site
        assert cs is not None  # check_channels refused the measurement otherwise
        speed = self.check(passage, measured)
        channels = measured.channels or {}
        t = measured.t_start + np.arange(measured.samples) / measured.sample_rate
        chans = np.array([channels[c.id] for c in cs.cribs], dtype=np.float64)
        wheel = CribWheel(
            passage.mass, passage.load, passage.radius, self.physics.contact_model(passage)
        )
        est = fit_channels(cs, wheel, speed, t, chans)
        cfg = self.site.diagnosis
        flat = est.flat
        fit = _Fit.of(est.fit_rms, est.noise)
        line: tuple[float | None, ...] = (None,) * 6
        unsimulated = False
        if cfg.line_speed is not None:
            line = self._channel_line(cs, wheel, cfg.line_speed, est, measured.sample_rate)
            unsimulated = line[0] is None
        at_line, line_low, line_high, ch_line, ch_low, ch_high = line
        peak_measured = float(np.max(chans))
        level, reasons = self._judge(
            "channels",
            peak_measured,
            flat,
            est.length_high,
            at_line,
            line_high,
            fit,
        )
        if unsimulated:
            reasons.append(UNSIMULATED_REASON)
        finding = None
        if flat is not None:
            finding = FlatFinding(
                kind=flat.kind,
                length=flat.length,
                depth=flat.depth,
                phase=flat.phase,
                length_low=est.length_low,
                length_high=est.length_high,
                depth_factor=1.0,
            )
        impacts = (
            flat_times(passage.radius, speed, flat.phase, float(t[0]), float(t[-1]))
            if flat is not None
            else np.empty(0)
        )
        diag = Diagnosis(
            site_id=self.site.site_id,
            passage_id=passage.passage_id,
            flat=finding,
            verdict=level,  # type: ignore[arg-type]
            reasons=reasons,
            peak_force_measured=peak_measured,
            peak_force_fit=est.peak_force_fit,
            fit_rms=est.fit_rms,
            peak_force_at_line_speed=at_line,
            peak_force_at_line_speed_low=line_low,
            peak_force_at_line_speed_high=line_high,
            peak_channel_at_line_speed=ch_line,
            peak_channel_at_line_speed_low=ch_low,
            peak_channel_at_line_speed_high=ch_high,
            measured="channels",
            noise_level=fit.noise,
            fit_residual_ratio=fit.reported_ratio,
            explained=fit.explained,
            wall_time=time.perf_counter() - start,
            model_version=self.model_version,
            calibration=self.calibration,
        )
        curves = FitCurves(
            t, t * speed, np.sum(chans, axis=0), np.sum(est.fitted, axis=0), impacts, est
        )
        return diag, curves

    def _channel_line(
        self,
        cs: CribSite,
        wheel: CribWheel,
        line_speed: float,
        est: CribEstimate,
        sample_rate: float,
    ) -> tuple[float | None, float | None, float | None, float | None, float | None, float | None]:
        """(contact point, low, high, detector point, low, high) at line speed: the fitted
        flat re-simulated over the site's record window [0, length] on the site's track
        (same phase: the impacts fall where they fell), the band over the length interval's
        ends, and worn flats 0.7 x as deep at the short end and 1.3 x at the long one, widened
        either way by the rough rail's dynamic load at line speed (``rough_rail_load``: the
        twin's rail is even). A round wheel's forecast is its static load and its round
        template's peak (no simulation: the twin's rail is even)."""
        t_line = line_times(self.site.length, line_speed, sample_rate)
        if est.flat is None:
            tpl = round_template(cs.cribs, line_speed, wheel.load, t_line, cs.sensor)
            p, c = wheel.load, float(np.max(tpl))
            return p, p, p, c, c, c
        flat = est.flat
        low, high = max(est.length_low, 1e-3), est.length_high
        lo_df, hi_df = DEPTH_FACTORS
        runs = [
            flat,
            flat_of(wheel.radius, flat.kind, low, flat.phase),
            flat_of(wheel.radius, flat.kind, high, flat.phase),
            # a worn flat's depth is not fitted (l²/16R): the band spans the worn depths
            # met in service, shallow at the short end and deep at the long one, whichever
            # kind fitted (at speed the kinds hit very differently)
            flat_of(wheel.radius, "rounded_flat", low, flat.phase, lo_df),
            flat_of(wheel.radius, "rounded_flat", high, flat.phase, hi_df),
        ]
        contact: list[float | None] = []
        detector: list[float | None] = []
        for f in runs:
            try:
                got = cs.run(wheel, line_speed, f, t_line, line=True, measurement_rate=sample_rate)
            except IntegrationError:
                contact.append(None)
                detector.append(None)
                continue
            on_site = got.t * line_speed >= 0.0
            contact.append(float(np.max(got.force[on_site])))
            detector.append(float(np.max(got.channels)))
        cp = [p for p in contact if p is not None]
        dp = [p for p in detector if p is not None]
        if not cp:
            return None, None, None, None, None, None
        # the twin's rail is even: the site's roughness moves the peaks either way by up to
        # its dynamic load at line speed (the rough rail's bound, crib_screen)
        rough = rough_rail_load(line_speed, wheel.load)
        return (
            contact[0],
            max(min(cp) - rough, 0.0),
            max(cp) + rough,
            detector[0],
            max(min(dp) - rough, 0.0),
            max(dp) + rough,
        )

    def line_peak(
        self, wheel: WheelOnSite, line_speed: float, flat: Flat | None, sample_rate: float
    ) -> float | None:
        """The largest force the site would measure of ``wheel`` with ``flat`` at line speed
        (None if the integrator cannot resolve that passage)."""
        dur = self.site.length / line_speed
        rate = self.sensor.fine_rate(sample_rate)
        tl = np.arange(0.0, dur, 1.0 / sample_rate)
        got = self._measure_or_none(wheel, line_speed, flat, 0.0, dur, tl, rate)
        return None if got is None else float(np.max(got))

    def _line_band(
        self,
        wheel: WheelOnSite,
        line_speed: float,
        est: FlatEstimate,
        point: float | None,
        sample_rate: float,
    ) -> tuple[float | None, float | None]:
        """(low, high) of the line-speed forecast: the fitted wheel with the ends of the length
        interval, every kind that fits, and the damping ratio's band (see docs/diagnosis.md);
        a run the integrator cannot resolve is left out (None, None if all are)."""
        if est.best_kind is None or est.flat is None:
            return point, point
        # both kinds, whichever fitted: at speed a fresh flat and a worn one of the same length
        # hit very differently, and the kind is the fit's least certain answer there
        kinds: tuple[FlatKind, ...] = ("flat", "rounded_flat")
        zetas = {est.damping_ratio}
        if wheel.foundation.is_compliant:
            zetas |= {
                est.damping_ratio * (1.0 - LINE_DAMPING_BAND),
                est.damping_ratio * (1.0 + LINE_DAMPING_BAND) + LINE_DAMPING_FLOOR,
            }
            if wheel.foundation.damping > 0.0:  # the site's own, the point forecast's
                zetas.add(damping_ratio_of(wheel.foundation))
        R = wheel.radius
        phase = est.flat.phase if est.flat is not None else 0.0
        runs: list[tuple[WheelOnSite, Flat]] = []
        for kind in kinds:
            for length in (max(est.length_low, 1e-3), est.length_high):
                df = est.depth_factor if kind == est.best_kind else 1.0
                flat = make_flat(R, kind, length, df).with_phase(phase)
                runs += [(with_damping_ratio(wheel, z), flat) for z in sorted(zetas)]

        def peak(run: tuple[WheelOnSite, Flat]) -> float | None:
            return self.line_peak(run[0], line_speed, run[1], sample_rate)

        if self.options.cores > 1:  # a forked child runs every other one
            with Forked(lambda: [peak(r) for r in runs[::2]]) as forked:
                mine = [peak(r) for r in runs[1::2]]
                theirs = forked.value()
            got = [point, *theirs, *mine]
        else:
            got = [point, *map(peak, runs)]
        peaks = [p for p in got if p is not None]
        return (min(peaks), max(peaks)) if peaks else (None, None)

    def _measure_or_none(
        self,
        wheel: WheelOnSite,
        speed: float,
        flat: Flat | None,
        t0: float,
        t1: float,
        t_out: NDArray[np.float64],
        rate: float | None = None,
    ) -> NDArray[np.float64] | None:
        """``_measure``, or None where the integrator cannot resolve the passage (a verdict is
        still given: the fit's own candidates are treated alike, ``estimate._Problem``)."""
        try:
            return self._measure(wheel, speed, flat, t0, t1, t_out, rate)
        except IntegrationError:
            return None

    def _measure(
        self,
        wheel: WheelOnSite,
        speed: float,
        flat: Flat | None,
        t0: float,
        t1: float,
        t_out: NDArray[np.float64],
        rate: float | None = None,
    ) -> NDArray[np.float64]:
        """The wheel (with its run-in) over [t0, t1] as the site's sensor records it at ``t_out``."""
        if rate is None:
            rate = self.sensor.fine_rate(1.0 / float(np.median(np.diff(t_out))))
        out = simulate_passage_run_in(
            wheel, speed, flat, self.rails, speed * t0, speed * (t1 + 2.0 / rate), rate
        )
        return self.sensor.measure(out.t, out.force, t_out)
