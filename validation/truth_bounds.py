"""What the truth itself gives the twin, for a validation row of either source.

Both questions are asked of every flat of both sources as it is validated
(``wide_set.run_case``, ``own_generator.run_case``), and their answers stored in the row:

- ``cost_fields``: the true flat's cost on the fit's own windows, the answer's cost and
  the χ² bound of the length interval (``validation.fit_bound`` classifies each miss);
- ``forecast_fields``: the twin's line-speed peak with the true flat on the site's exact
  foundation, and its spread under perturbations no measurement resolves
  (``validation.forecast_bound`` says which forecast misses the twin itself cannot avoid).

``truth_fields`` asks both. The fit that answers ``cost_fields`` is a second, untimed run: asking for a candidate's
cost changes nothing of the answer (``tests/test_fit_bound.py``) but costs CPU the timed
run must not include.

    >>> true_depth_factor("flat", 0.46, 0.05, 0.0)
    1.0
"""

from __future__ import annotations

from typing import Any

from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage
from service.physics.diagnosis import Diagnoser
from sim_core.diagnosis.estimate import FitOptions, FlatEstimate, bound_factor, make_flat
from sim_core.diagnosis.forward import (
    FlatKind,
    damping_ratio_of,
    typical_rounded_depth,
    with_damping_ratio,
)

PERTURBATIONS = (
    (0.9, 0.0, 1.0),
    (1.1, 0.0, 1.0),
    (1.0, 0.0, 0.995),
    (1.0, 0.0, 1.005),
    (1.0, -0.005, 1.0),
    (1.0, 0.005, 1.0),
)
"""(damping ratio ×, phase + rad, line speed ×) of the forecast's conditioning check."""


def true_depth_factor(kind: FlatKind, radius: float, length: float, depth: float) -> float:
    """A worn flat's depth over l²/16R (1.0 for a fresh flat, whose depth follows from l)."""
    if kind != "rounded_flat":
        return 1.0
    return depth / typical_rounded_depth(radius, length)


def cost_fields(
    d: Diagnoser,
    passage: WheelPassage,
    measured: MeasuredPassage,
    kind: FlatKind,
    length: float,
    depth_factor: float,
) -> dict[str, Any]:
    """``cost_best`` (the answer's), ``cost_truth`` (the true flat's, on the same windows)
    and ``cost_bound`` (J_max / J_best of the interval); all None where the fit compares no
    windows (a record the screen dismissed)."""
    _, curves = d.diagnose(passage, measured, compare=[(kind, length, depth_factor)])
    return costs_of(curves.force_estimate, d.options)


def costs_of(est: FlatEstimate, options: FitOptions) -> dict[str, Any]:
    """``cost_fields`` of a fit asked for one candidate's cost (``compare``)."""
    if not est.compared:
        return {"cost_best": None, "cost_truth": None, "cost_bound": None}
    return {
        "cost_best": est.cost_best,
        "cost_truth": est.compared[0],
        "cost_bound": bound_factor(max(len(est.windows), 1), options),
    }


def forecast_fields(
    d: Diagnoser,
    passage: WheelPassage,
    kind: FlatKind,
    length: float,
    depth_factor: float,
    phase: float,
    sample_rate: float,
) -> dict[str, Any]:
    """``line_oracle``: the twin's peak at the site's line speed with the true flat (its
    phase as the truth's generator sets it) on the site's exact foundation and even rail;
    ``line_oracle_low`` / ``_high``: its range over ``PERTURBATIONS``; all None where the
    site has no line speed or the integrator resolves none of it."""
    none: dict[str, Any] = {"line_oracle": None, "line_oracle_low": None, "line_oracle_high": None}
    line = d.site.diagnosis.line_speed
    if line is None:
        return none
    wheel = d.wheel(passage)
    zeta = damping_ratio_of(wheel.foundation)
    flat = make_flat(passage.radius, kind, length, depth_factor)
    peaks: list[float] = []
    for dz, dphi, dv in ((1.0, 0.0, 1.0), *PERTURBATIONS):
        w = with_damping_ratio(wheel, zeta * dz)
        got = d.line_peak(w, line * dv, flat.with_phase(phase + dphi), sample_rate)
        if got is None:
            if not peaks:
                return none
            continue
        peaks.append(got)
    return {"line_oracle": peaks[0], "line_oracle_low": min(peaks), "line_oracle_high": max(peaks)}


def truth_fields(
    d: Diagnoser,
    passage: WheelPassage,
    measured: MeasuredPassage,
    kind: FlatKind,
    length: float,
    depth: float,
    phase: float,
    line_truth: float | None,
) -> dict[str, Any]:
    """``cost_fields`` and, where there is a line-speed truth to set it against,
    ``forecast_fields`` of the true flat (``depth`` in m)."""
    df = true_depth_factor(kind, passage.radius, length, depth)
    out = cost_fields(d, passage, measured, kind, length, df)
    if line_truth is not None:
        out |= forecast_fields(d, passage, kind, length, df, phase, measured.sample_rate)
    return out


__all__ = [
    "PERTURBATIONS",
    "cost_fields",
    "costs_of",
    "forecast_fields",
    "true_depth_factor",
    "truth_fields",
]
