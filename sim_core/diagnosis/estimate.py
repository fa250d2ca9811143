"""The fit: which flat, if any, makes the twin's force look like the measured one.

MODEL.md §7: after a flat's impact the bounces are chaotic (µm of unknown roughness move
them by milliseconds), so a fit over the whole record is dominated by that drift. What a
simulation and a measurement share is the deterministic part of each turn: the approach,
the unloading dip while the flat passes under the wheel (about l/V long) and the first
impact. So the fit compares only *windows*, one per turn, around each turn's anchor
(``sim_core.diagnosis.turns``): from ``WINDOW_BEFORE`` m of travel (plus 2 ms) before the
anchor to ``WINDOW_AFTER`` s after it (plus the sensor's delay).

For a candidate flat (kind, length) the twin simulates one turn's *template*: the wheel
rolling steadily onto the flat (from static equilibrium, ``PRE_ROLL`` s before the flat's
leading end), through the impact and ``POST_ROLL`` s of what follows, at the measured
speed, passed through the site's sensor model. Each turn's window is matched by the
template shifted in time (the shift is the time the flat's centre passed under the
wheel: it gives the phase), and the candidate's cost is the sum of squared differences
over all windows. Every candidate is compared on the same samples.

The search is coarse to fine: a grid of lengths for each kind (``LENGTH_GRID``), then a
golden-section refinement around each kind's best grid point. The kind is the one with
the lower cost. The length interval is where the cost stays within the 95 % band of a
χ² profile, J(l) <= J_min·(1 + 3.84/N_eff), widened by the speed's 1 % uncertainty.
A flat is reported only if it explains the windows significantly better than a round
wheel, (J_round - J_flat)/(J_flat/N_eff) >= ``detection``, and is at least the detection
floor long: 8 mm below 75 km/h, 16 mm above (where a few µm of unknown rail roughness
excite as much dynamic force as a 10-15 mm flat; measured on the tuning set).

Worked example (tests/test_diagnosis_estimate.py runs it on noisy synthetic records):
a 50 mm fresh flat at 100 km/h is found as a ``flat`` of 50 ± 2 mm.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint_table import ConstraintTable
from sim_core.diagnosis.forward import (
    Flat,
    FlatKind,
    RailTables,
    WheelOnSite,
    simulate_window,
    wheel_table,
)
from sim_core.diagnosis.sensor import SensorModel
from sim_core.diagnosis.turns import find_anchors
from sim_core.passage import Foundation
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI

__all__ = ["DEFAULT_OPTIONS", "FitOptions", "FlatEstimate", "estimate_flat"]

LENGTH_GRID = (0.006, 0.01, 0.015, 0.02, 0.03, 0.04, 0.055, 0.07, 0.09, 0.115, 0.14)
"""m: the coarse grid of flat lengths tried for each kind."""

WINDOW_BEFORE = 0.14
"""m of travel before the anchor that each window covers (the longest flat's dip)."""

WINDOW_AFTER = 2.5e-3
"""s after the anchor each window covers (the first impact), plus the sensor's delay."""

PRE_ROLL = 4e-3
"""s of steady rolling simulated before the flat's leading end in a template."""

POST_ROLL = 0.03
"""s simulated after the flat's trailing end in a template."""

SHIFT_STEP = 5e-5
"""s: the coarse step of the per-turn time alignment (refined tenfold around the best)."""


@dataclass(frozen=True)
class FitOptions:
    """Knobs of the search, with the values the validation was run with."""

    lengths: tuple[float, ...] = LENGTH_GRID
    kinds: tuple[FlatKind, ...] = ("flat", "rounded_flat")
    refine_evaluations: int = 7
    min_length: float = 0.008
    min_length_fast: float = 0.016
    fast_speed: float = 75.0 / 3.6
    detection: float = 40.0
    speed_uncertainty: float = 0.01
    damping_ratios: tuple[float, ...] = (0.0, 0.12, 0.3, 0.5)
    dof_per_window: float = 4.0


DEFAULT_OPTIONS = FitOptions()


@dataclass(frozen=True)
class Candidate:
    """One evaluated candidate: its cost over all windows and the flat-centre time per turn."""

    kind: FlatKind
    length: float
    zeta: float
    cost: float
    centres: NDArray[np.float64]


@dataclass(frozen=True)
class FlatEstimate:
    """What the fit found.

    ``flat`` is None when no flat is reported; ``length_low``/``length_high`` bound the
    best candidate's length either way (m). ``speed`` is the speed the turn spacing
    implies (m/s). ``windows`` are the compared (t0, t1) of each turn. ``profile`` lists
    every candidate evaluated: (kind, length, cost).
    """

    flat: Flat | None
    best_kind: FlatKind | None
    best_length: float
    length_low: float
    length_high: float
    cost_round: float
    cost_best: float
    n_samples: int
    significance: float
    speed: float
    damping_ratio: float
    windows: tuple[tuple[float, float], ...]
    profile: tuple[tuple[str, float, float], ...] = field(repr=False)
    wall_time: float = 0.0

    @property
    def fit_rms(self) -> float:
        """rms difference (N) over the windows of the reported model (round if no flat)."""
        cost = self.cost_best if self.flat is not None else self.cost_round
        return math.sqrt(cost / max(self.n_samples, 1))


@dataclass
class _Problem:
    wheel: WheelOnSite
    speed: float
    sensor: SensorModel
    fine_rate: float
    t: NDArray[np.float64]
    f: NDArray[np.float64]
    win: list[tuple[int, int]]
    anchors: NDArray[np.float64]
    rails: RailTables
    evaluated: dict[tuple[str, float, float], Candidate] = field(default_factory=dict)
    tables: dict[tuple[str, float], ConstraintTable] = field(default_factory=dict)

    def wheel_with(self, zeta: float) -> WheelOnSite:
        """The wheel on the site's foundation with damping ratio ``zeta`` (rigid: as is)."""
        f = self.wheel.foundation
        if not f.is_compliant:
            return self.wheel
        c = 2.0 * zeta * math.sqrt(f.stiffness * f.mass)
        return replace(self.wheel, foundation=Foundation.compliant(f.mass, f.stiffness, c))

    def template(self, flat: Flat, zeta: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(τ, filtered force): the flat's centre under the wheel at τ = 0."""
        v = self.speed
        half = 0.5 * flat.length / v
        t0, t1 = -(half + PRE_ROLL), half + POST_ROLL
        key = (flat.kind, flat.length)
        table = self.tables.get(key)
        if table is None:  # the same flat is tried at several damping ratios
            table = wheel_table(self.wheel.radius, flat.with_phase(0.0), self.rails, v * t0, v * t1)
            self.tables[key] = table
        out = simulate_window(self.wheel_with(zeta), v, table, t0, t1, self.fine_rate)
        return out.t, _clip(self.sensor.filter(out.force, self.fine_rate), self.wheel.load)

    def evaluate(self, kind: FlatKind, length: float, zeta: float) -> Candidate:
        key = (kind, round(length, 9), round(zeta, 9))
        got = self.evaluated.get(key)
        if got is not None:
            return got
        R = self.wheel.radius
        flat = Flat.ideal(R, length) if kind == "flat" else Flat.rounded(R, length)
        tau, tf = self.template(flat, zeta)
        half = 0.5 * length / self.speed
        total = 0.0
        centres = np.empty(len(self.win))
        for k, (i0, i1) in enumerate(self.win):
            tw, fw = self.t[i0:i1], self.f[i0:i1]
            a = self.anchors[k]
            s, c = _align(tau, tf, tw, fw, a - half - 0.012, a + half + 0.002)
            total += c
            centres[k] = s
        cand = Candidate(kind, length, zeta, total, centres)
        self.evaluated[key] = cand
        return cand


CLIP = 2.0
"""Forces are compared clipped to [0, CLIP·P]: the impacts' timing counts, their height
(which unknown foundation damping changes by tens of per cent) does not dominate."""


def _clip(f: NDArray[np.float64], load: float) -> NDArray[np.float64]:
    return np.clip(f, 0.0, CLIP * load)


def _align(
    tau: NDArray[np.float64], tf: NDArray[np.float64], tw: NDArray[np.float64],
    fw: NDArray[np.float64], s_lo: float, s_hi: float,
) -> tuple[float, float]:
    """(best shift, its cost): the template at τ = t - shift against the window's samples."""
    step = SHIFT_STEP
    best_s, best_c = s_lo, math.inf
    for _ in range(2):
        shifts = np.arange(s_lo, s_hi + 0.5 * step, step)
        pred = np.interp(tw[None, :] - shifts[:, None], tau, tf)
        cost = np.sum((fw[None, :] - pred) ** 2, axis=1)
        i = int(np.argmin(cost))
        if cost[i] < best_c:
            best_s, best_c = float(shifts[i]), float(cost[i])
        s_lo, s_hi, step = best_s - step, best_s + step, step / 10.0
    return best_s, best_c


def _golden(
    fn: object, lo: float, hi: float, n: int
) -> None:
    """Golden-section search of a unimodal fn on [lo, hi] with n evaluations (results cached)."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = fn(c), fn(d)  # type: ignore[operator]
    for _ in range(max(0, n - 2)):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = fn(c)  # type: ignore[operator]
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = fn(d)  # type: ignore[operator]


def _interval(points: list[tuple[float, float]], j_max: float, best: float) -> tuple[float, float]:
    """Where the profile J(l) (sorted points) crosses j_max on each side of ``best``."""
    pts = sorted(points)
    ls = np.array([p[0] for p in pts])
    js = np.array([p[1] for p in pts])
    ib = int(np.argmin(np.abs(ls - best)))
    lo = ls[0]
    for i in range(ib, 0, -1):
        if js[i - 1] > j_max:
            u = (j_max - js[i]) / (js[i - 1] - js[i])
            lo = ls[i] + u * (ls[i - 1] - ls[i])
            break
    hi = ls[-1]
    for i in range(ib, ls.size - 1):
        if js[i + 1] > j_max:
            u = (j_max - js[i]) / (js[i + 1] - js[i])
            hi = ls[i] + u * (ls[i + 1] - ls[i])
            break
    return float(min(lo, best)), float(max(hi, best))


def estimate_flat(
    wheel: WheelOnSite,
    speed: float,
    t: NDArray[np.float64],
    force: NDArray[np.float64],
    sensor: SensorModel,
    options: FitOptions = DEFAULT_OPTIONS,
) -> FlatEstimate:
    """Fit a flat to the measured ``force`` at times ``t`` (s; t = 0 at the site's start).

    ``speed`` is the best speed known (measured or reported); the turn spacing refines it.
    """
    start = time.perf_counter()
    t = np.asarray(t, dtype=np.float64)
    f = np.asarray(force, dtype=np.float64)
    if t.size < 16 or t.shape != f.shape:
        raise ValueError(f"diagnosis: need at least 16 samples of t and force, got {t.size}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(f))):
        raise ValueError("diagnosis: the measured record has non-finite values")
    R, P = wheel.radius, wheel.load
    rate = (t.size - 1) / (t[-1] - t[0])
    anchors = find_anchors(t, f, P, R, speed)
    v = speed
    if anchors.times.size >= 2:
        v = min(max(TWO_PI * R / anchors.period, 0.97 * speed), 1.03 * speed)
    before = WINDOW_BEFORE / v + 2e-3
    after = WINDOW_AFTER + (2.0 * sensor.order / (TWO_PI * sensor.cutoff_hz)
                            if sensor.cutoff_hz else 0.0)
    win: list[tuple[int, int]] = []
    kept: list[float] = []
    for a in anchors.times:
        if a - before >= t[0] and a + after <= t[-1]:
            win.append((int(np.searchsorted(t, a - before)), int(np.searchsorted(t, a + after))))
            kept.append(float(a))
    if not win:  # no whole turn in the record: compare what there is around the anchors
        for a in anchors.times:
            i0, i1 = int(np.searchsorted(t, a - before)), int(np.searchsorted(t, a + after))
            if i1 - i0 > 4:
                win.append((i0, i1))
                kept.append(float(a))
    n = sum(i1 - i0 for i0, i1 in win)
    f = _clip(f, P)
    cost_round = float(sum(np.sum((f[i0:i1] - P) ** 2) for i0, i1 in win))
    windows = tuple((float(t[i0]), float(t[i1 - 1])) for i0, i1 in win)
    if not win:
        return FlatEstimate(None, None, 0.0, 0.0, 0.0, cost_round, cost_round, 0, 0.0, v,
                            0.0, windows, (), time.perf_counter() - start)
    prob = _Problem(wheel, v, sensor, sensor.fine_rate(rate), t, f, win, np.array(kept),
                    RailTables(RailProfile.flat()))
    grid = tuple(sorted(options.lengths))
    f_site = wheel.foundation
    zetas: tuple[float, ...] = (0.0,)
    zeta_site = 0.0
    if f_site.is_compliant:
        zeta_site = f_site.damping / (2.0 * math.sqrt(f_site.stiffness * f_site.mass))
        zetas = tuple(sorted({round(zeta_site, 6), *options.damping_ratios}))
    # 1. coarse: every kind, length and damping ratio of the grids
    for kind in options.kinds:
        for z in zetas:
            for ln in grid:
                prob.evaluate(kind, ln, z)
    coarse = min(prob.evaluated.values(), key=lambda c: c.cost)
    zeta = coarse.zeta
    # 2. the foundation's damping, then each kind's length, by golden sections
    if len(zetas) > 1:
        iz = zetas.index(zeta)
        _golden(lambda z: prob.evaluate(coarse.kind, coarse.length, z).cost,
                zetas[max(iz - 1, 0)], zetas[min(iz + 1, len(zetas) - 1)],
                options.refine_evaluations - 2)
        zeta = min((c for c in prob.evaluated.values()
                    if c.kind == coarse.kind and c.length == coarse.length),
                   key=lambda c: c.cost).zeta
    for kind in options.kinds:
        costs = [prob.evaluate(kind, ln, zeta).cost for ln in grid]
        i = int(np.argmin(costs))
        lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
        _golden(lambda ln, kind=kind: prob.evaluate(kind, ln, zeta).cost, lo, hi,
                options.refine_evaluations)
    at_zeta = [c for c in prob.evaluated.values() if c.zeta == zeta]
    best = min(at_zeta, key=lambda c: c.cost)
    n_eff = n * (min(1.0, 2.0 * sensor.cutoff_hz / rate) if sensor.cutoff_hz else 1.0)
    n_eff = max(n_eff, 1.0)
    significance = (cost_round - best.cost) / (best.cost / n_eff) if best.cost > 0 else math.inf
    # the residuals are model error, correlated over a window: a few degrees of freedom each
    j_max = best.cost * (1.0 + 3.84 / (options.dof_per_window * len(win)))
    points = [(c.length, c.cost) for c in at_zeta if c.kind == best.kind]
    lo, hi = _interval(points, j_max, best.length)
    lo *= 1.0 - options.speed_uncertainty
    hi *= 1.0 + options.speed_uncertainty
    # the detection floor: above ~75 km/h a few µm of unknown roughness excite as much dynamic
    # force as a 10-15 mm flat (tuning set: round wheels fitted up to 14.7 mm there)
    floor = options.min_length_fast if v >= options.fast_speed else options.min_length
    found = best.length >= floor and significance >= options.detection
    flat: Flat | None = None
    if found:
        phases = np.exp(1j * (-(v * best.centres) / R))
        phase = float(np.angle(np.mean(phases))) % TWO_PI
        flat = (Flat.ideal(R, best.length, phase) if best.kind == "flat"
                else Flat.rounded(R, best.length, None, phase))
    profile = tuple((c.kind, c.length, c.cost) for c in
                    sorted(at_zeta, key=lambda c: (c.kind, c.length)))
    return FlatEstimate(flat, best.kind, best.length, lo, hi, cost_round, best.cost, n,
                        float(significance), v, best.zeta, windows, profile,
                        time.perf_counter() - start)
