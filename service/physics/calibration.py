"""The site's track calibrated from round wheels: the contract's objects to ``sim_core.calibration``
and back (``railtwin calibrate``; docs/service.md "Calibration").

In: the site (its foundation must be a rail on discrete supports or a slab, with a detector),
and pairs of a round wheel's ``WheelPassage`` and its ``MeasuredPassage`` of crib channels.
Out: ``sim_core.calibration.estimator.Estimate``, the site with the estimates in its
``foundation`` and a ``[calibration]`` table (``SiteCalibration``: source, the new
foundation's fingerprint, the wheels, each value's interval and identifiability, the
combinations the wheels cannot tell apart, the largest residual / noise), and the report as
a table for people or JSON.

Errors in the inputs are ``CalibrationInputError``, one line naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from schemas.calibration import CalibratedParameter, CalibrationSource, SiteCalibration
from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage
from schemas.scenario import RoundOutline
from schemas.site import SiteConfig
from schemas.track import DiscreteFoundation, SlabFoundation, TrackSupport
from service.physics import inputs as physics_inputs
from service.physics.model_version import foundation_fingerprint
from service.wire.measured_channels import channels_mismatch
from sim_core.calibration.estimator import Estimate, calibrate
from sim_core.calibration.forward import Wheel
from sim_core.calibration.residuals import Passage, Site
from sim_core.calibration.sensitivities import Progress
from sim_core.diagnosis.sensor import SensorModel
from sim_core.track.spec import TrackSpec

__all__ = [
    "CalibrationInputError",
    "calibrated_site",
    "check_site",
    "check_wheel",
    "estimate",
    "foundation_with",
    "passage_of",
    "report",
    "table",
]


class CalibrationInputError(ValueError):
    """An input the calibration cannot use; the message is one line naming the field."""


def check_site(site: SiteConfig) -> TrackSpec:
    """The site's track, or ``CalibrationInputError``: a rigid or compliant site has no track
    to calibrate, and without a detector there are no channels."""
    f = site.foundation
    if not isinstance(f, (DiscreteFoundation, SlabFoundation)):
        raise CalibrationInputError(
            f"foundation.kind: {f.kind!r} has no track values to calibrate (pads, sleepers, "
            "ballast): calibration needs a 'discrete' or 'slab' foundation"
        )
    if site.detector is None or not site.detector.cribs:
        raise CalibrationInputError(
            "detector: the site has no cribs, so no channels to calibrate from"
        )
    if site.diagnosis.sample_rate is None:
        raise CalibrationInputError(
            "diagnosis.sample_rate: the detector's sampling rate is needed to read its channels"
        )
    return physics_inputs.track(f)


def check_wheel(site: SiteConfig, passage: WheelPassage, measured: MeasuredPassage) -> str | None:
    """What makes a pair unusable, in one line naming the field, or None."""
    if not isinstance(passage.outline, RoundOutline):
        return f"outline: calibration takes round wheels only, got {passage.outline.kind!r}"
    if measured.channels is None:
        return "channels: a contact force (t_s,force_N) is not a detector's channels"
    problem = channels_mismatch(measured, site)
    if problem is not None:
        return f"channels: {problem}"
    if site.diagnosis.sample_rate is not None and not math.isclose(
        measured.sample_rate, site.diagnosis.sample_rate, rel_tol=0.01
    ):
        return (
            f"sample_rate: {measured.sample_rate:g} Hz, the site's detector samples at "
            f"{site.diagnosis.sample_rate:g} Hz"
        )
    return None


def passage_of(site: SiteConfig, name: str, p: WheelPassage, m: MeasuredPassage) -> Passage:
    """A round wheel and its channels as ``sim_core.calibration``'s ``Passage``."""
    contact, _ = physics_inputs.contact_model(
        site.contact, site.material, radius=p.radius, load=p.load, mass=p.mass
    )
    assert m.channels is not None and site.detector is not None
    n = len(next(iter(m.channels.values())))
    t = m.t_start + np.arange(n) / m.sample_rate
    channels = np.array([m.channels[c.id] for c in site.detector.cribs], dtype=np.float64).T
    return Passage(name, Wheel(p.speed, p.load, p.mass, contact), t, channels)


def estimate(
    site: SiteConfig,
    wheels: Sequence[tuple[str, WheelPassage, MeasuredPassage]],
    progress: Progress | None = None,
) -> Estimate:
    """The track's values at ``site`` from the named round ``wheels`` (checked first)."""
    track = check_site(site)
    for name, p, m in wheels:
        problem = check_wheel(site, p, m)
        if problem is not None:
            raise CalibrationInputError(f"{name}: {problem}")
    if not wheels:
        raise CalibrationInputError("no wheels to calibrate from")
    chain = SensorModel(site.diagnosis.sensor_lowpass_hz, site.diagnosis.sensor_lowpass_order)
    passages = [passage_of(site, n, p, m) for n, p, m in wheels]
    sim_site = Site(physics_inputs.cribs(site.detector), chain)
    if progress is None:
        return calibrate(track, passages, sim_site)
    return calibrate(track, passages, sim_site, progress=progress)


def foundation_with(
    f: DiscreteFoundation | SlabFoundation, values: Sequence[float]
) -> DiscreteFoundation | SlabFoundation:
    pad = TrackSupport(stiffness=values[0], damping=values[1])
    if isinstance(f, SlabFoundation):
        return f.model_copy(update={"pad": pad})
    return f.model_copy(
        update={
            "pad": pad,
            "sleeper_mass": values[2],
            "ballast": TrackSupport(stiffness=values[3], damping=values[4]),
        }
    )


def calibrated_site(
    site: SiteConfig, est: Estimate, source: CalibrationSource = "offline"
) -> SiteConfig:
    """``site`` with the estimates in its foundation and the ``[calibration]`` table."""
    f = site.foundation
    assert isinstance(f, (DiscreteFoundation, SlabFoundation))
    new = foundation_with(f, est.estimate)
    params = []
    for i, name in enumerate(est.names):
        lo, hi = est.interval(i)
        params.append(
            CalibratedParameter.model_validate(
                {
                    "name": name,
                    "nominal": est.nominal[i],
                    "estimate": est.estimate[i],
                    "low": min(lo, est.estimate[i]),
                    "high": max(hi, est.estimate[i]),
                    "identifiable": est.identifiability.identifiable[i],
                }
            )
        )
    cal = SiteCalibration(
        source=source,
        id=foundation_fingerprint(new),
        wheels=len(est.wheels),
        parameters=params,
        unresolved=[c.label(est.names) for c in est.identifiability.weak] or None,
        residual_ratio=max(est.rms_calibrated),
    )
    return site.model_copy(update={"foundation": new, "calibration": cal})


def report(est: Estimate, site: SiteConfig, wall: float) -> dict[str, Any]:
    """The calibration as JSON-ready data (``railtwin calibrate --json``)."""
    ident = est.identifiability
    return {
        "site_id": site.site_id,
        "wheels": len(est.wheels),
        "steps": est.steps,
        "wall_time": wall,
        "chi2_reduced": est.chi2_reduced,
        "parameters": [
            {
                "name": n,
                "nominal": est.nominal[i],
                "estimate": est.estimate[i],
                "low": est.interval(i)[0],
                "high": est.interval(i)[1],
                "sd_log": est.sd[i],
                "sd_log_fisher": est.fisher_sd[i],
                "sd_log_jackknife": est.jackknife_sd[i],
                "data_sd_log": None if math.isinf(ident.data_sd[i]) else ident.data_sd[i],
                "identifiable": ident.identifiable[i],
            }
            for i, n in enumerate(est.names)
        ],
        "cannot_tell_apart": [
            {
                "combination": c.label(est.names),
                "weights": list(c.weights),
                "data_sd_log": None if math.isinf(c.data_sd) else c.data_sd,
            }
            for c in ident.weak
        ],
        "determined": [
            {
                "combination": c.label(est.names),
                "weights": list(c.weights),
                "data_sd_log": c.data_sd,
            }
            for c in ident.strong
        ],
        "passages": [
            {
                "name": w,
                "noise_sigma": est.sigma[k],
                "rms_over_sigma_nominal": est.rms_nominal[k],
                "rms_over_sigma_calibrated": est.rms_calibrated[k],
            }
            for k, w in enumerate(est.wheels)
        ],
    }


def _num(v: float) -> str:
    return f"{v:.4g}"


def table(est: Estimate, wall: float) -> str:
    """The calibration for people: one row a parameter, the identifiability, the residuals."""
    ident = est.identifiability
    head = ("parameter", "nominal", "estimate", "95 % interval", "identifiable")
    rows = [head]
    for i, n in enumerate(est.names):
        lo, hi = est.interval(i)
        rows.append(
            (
                n,
                _num(est.nominal[i]),
                _num(est.estimate[i]),
                f"[{_num(lo)}, {_num(hi)}]",
                ident.identifiable[i],
            )
        )
    widths = [max(len(r[c]) for r in rows) for c in range(len(head))]
    lines = ["  ".join(f"{v:<{w}}" for v, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    if ident.weak:
        lines.append("the wheels cannot tell apart (estimate held near the nominal along):")
        lines += [
            f"  {c.label(est.names)}  (data alone: ±{100 * c.data_sd:.0f} % in log)"
            if math.isfinite(c.data_sd)
            else f"  {c.label(est.names)}  (not seen by the data)"
            for c in ident.weak
        ]
    else:
        lines.append("every parameter and combination is determined by the wheels")
    lines.append(
        f"residual rms / noise: nominal {min(est.rms_nominal):.2f}–{max(est.rms_nominal):.2f}, "
        f"calibrated {min(est.rms_calibrated):.2f}–{max(est.rms_calibrated):.2f} "
        f"over {len(est.wheels)} wheels ({est.steps} steps, {wall:.1f} s)"
    )
    return "\n".join(lines) + "\n"
