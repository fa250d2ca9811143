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
floor long (``detection_floor``: 6 mm up to 30 km/h, 17 mm from 100 km/h, linear between:
a few µm of unknown rail roughness excite as much dynamic force as a 10-15 mm flat at
speed; measured on the tuning set), unless it
stands out of its own record: its *contrast*, the significance over the largest
significance of the same flat fitted a fraction of a turn away (``NULL_OFFSETS``), is at
least ``contrast`` (round wheels of the tuning set reached 7.7).

Before any of this, a *screen* dismisses a round wheel in milliseconds: if the record stays
closer to a round wheel's (``baseline``) than the shortest reportable flat's template would
take it, no fit is made. A worn flat's depth is fitted within 0.7-1.3 × l²/16R after its
length (``_refine_depth``), and the record's own noise σ is estimated from its third
differences (``record_noise``) so that the service can say whether the fit explains the
record. A damper stated in the site file is trusted within ``site_damping_band``.
docs/diagnosis.md has the method, the validation on independent data and the misses.

Worked example (tests/test_diagnosis.py runs it on noisy synthetic records):
a 50 mm fresh flat at 100 km/h is found as a ``flat`` of 50 ± 2 mm.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from itertools import takewhile

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable
from sim_core.diagnosis.forked import Forked
from sim_core.diagnosis.forward import (
    Flat,
    FlatKind,
    RailTables,
    WheelOnSite,
    damping_ratio_of,
    simulate_window,
    typical_rounded_depth,
    wheel_table,
    with_damping_ratio,
)
from sim_core.diagnosis.sensor import SensorModel
from sim_core.diagnosis.turns import find_anchors
from sim_core.passage import InitialState, IntegrationError
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI

__all__ = [
    "DEFAULT_OPTIONS",
    "EXPLAINED_RATIO",
    "FitOptions",
    "FlatEstimate",
    "bound_factor",
    "contact_floor",
    "estimate_flat",
    "explains",
    "make_flat",
    "record_noise",
    "residual_ratio",
]

LENGTH_GRID = (0.006, 0.01, 0.015, 0.02, 0.03, 0.04, 0.055, 0.07, 0.09, 0.115, 0.14)
"""m: the coarse grid of flat lengths tried for each kind."""

WINDOW_BEFORE = 0.14
"""m of travel before the anchor that each window covers (the longest flat's dip)."""

WINDOW_AFTER = 2.5e-3
"""s after the anchor each window covers (the first impact), plus the sensor's delay."""

PRE_ROLL = 4e-3
"""s of steady rolling simulated before the flat's leading end in a template."""

POST_ROLL = 0.02
"""s simulated after the flat's trailing end in a template."""

TEMPLATE_RTOL = 1e-6
"""Integrator tolerance of the templates: forces to ~1e-5, far below what a fit resolves."""

SHIFT_STEP = 5e-5
"""s: the coarse step of the per-turn time alignment (refined tenfold around the best)."""


@dataclass(frozen=True)
class FitOptions:
    """Knobs of the search, with the values the validation was run with.

    ``max_earlier_turns``, ``ringing`` (``remove_ringing``), ``clean_arrivals``
    (``_clean_arrivals``), ``first_impact_lead`` (``turns.first_impact_lead``) and
    ``arrival_lifts`` (each window matched by whichever of the rolling template and
    templates whose wheel arrives lifted by these multiples of the static indentation fits
    it best, on a lightly damped site) are ways of giving the template the state a lightly
    damped wheel arrives with; each was measured on both validation sources and none
    improved both (docs/diagnosis.md, "Tried and not kept"), so all are off.

    ``rolling_anchors``: each turn's anchor is its first impact after the wheel last
    rolled, not a landing after the bounce a long flat throws it into
    (``turns.first_impact_after_rolling``; on). Measured on both sources and 20 own seeds
    (docs/diagnosis.md): windows that held only the landing now hold the flat.

    ``depth_profile``: a worn flat's length interval profiles the depth out (on).

    ``coarse_depth_factors``: the worn kind's coarse grid at these depth factors (default
    1.0 only). A grid over 0.7-1.3 finds long shallow worn flats followed at low speed
    (W39) but doubles the fit's time and takes fresh flats at speed for worn ones; measured,
    not kept (docs/diagnosis.md).

    ``slow_depth_factors`` / ``slow_speed_ratio``: below ``slow_speed_ratio`` ×
    ``shallow_following_speed`` (the following speed of the shallowest worn flat searched)
    the wheel follows a worn flat and its depth is told from its length, so the worn kind's
    coarse grid spans these factors (at the middle damping ratio); faster,
    ``coarse_depth_factors``.

    ``small_flat_floors``: a flat whose length interval lies wholly below this many times
    the detection floor and reaches below ``min_length`` is not told from a round wheel on
    an unknown rough rail, and is not reported (unless it stands out, ``contrast``).
    """

    lengths: tuple[float, ...] = LENGTH_GRID
    kinds: tuple[FlatKind, ...] = ("flat", "rounded_flat")
    refine_evaluations: int = 7
    min_length: float = 0.006
    min_length_fast: float = 0.017
    floor_speeds: tuple[float, float] = (30.0 / 3.6, 100.0 / 3.6)
    contrast: float = 20.0
    min_length_contrast: float = 0.005
    detection: float = 40.0
    speed_uncertainty: float = 0.01
    speed_uncertainty_fit: float = 0.015
    damping_ratios: tuple[float, ...] = (0.0, 0.15, 0.35, 0.6)
    refine_rounds: int = 2
    dof_per_window: float = 1.5
    site_damping_band: float = 2.0
    max_earlier_turns: int = 0
    screen: bool = True
    ringing: bool = False
    clean_arrivals: bool = False
    first_impact_lead: bool = False
    rolling_anchors: bool = True
    cores: int = 1
    depth_profile: bool = True
    coarse_depth_factors: tuple[float, ...] = (1.0,)
    slow_depth_factors: tuple[float, ...] = (0.8, 1.0, 1.2)
    slow_speed_ratio: float = 1.5
    small_flat_floors: float = 2.0
    arrival_lifts: tuple[float, ...] = ()


DEFAULT_OPTIONS = FitOptions()


@dataclass(frozen=True)
class Candidate:
    """One evaluated candidate: its cost over all windows and the flat-centre time per turn."""

    kind: FlatKind
    length: float
    zeta: float
    cost: float
    centres: NDArray[np.float64]
    depth_factor: float = 1.0


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
    contrast: float
    speed: float
    damping_ratio: float
    windows: tuple[tuple[float, float], ...]
    profile: tuple[tuple[str, float, float], ...] = field(repr=False)
    wall_time: float = 0.0
    depth_factor: float = 1.0
    interval_kinds: tuple[FlatKind, ...] = ()
    noise_level: float = 0.0
    screened: bool = False
    compared: tuple[float, ...] = ()

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
    evaluated: dict[tuple[str, float, float, float], Candidate] = field(default_factory=dict)
    tables: dict[tuple[str, float, float], ConstraintTable] = field(default_factory=dict)
    templates: dict[
        tuple[str, float, float, float, int], tuple[NDArray[np.float64], NDArray[np.float64]]
    ] = field(default_factory=dict)
    turns: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    period_band: tuple[float, float] = (0.0, 0.0)
    max_earlier_turns: int = 0
    lead: float = 0.0
    arrivals: tuple[InitialState | None, ...] = (None,)

    def template(
        self, flat: Flat, zeta: float, arrival: int = 0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(τ, filtered force): the flat's centre under the wheel at τ = 0 (kept); the wheel
        arrives rolling steadily, or in the state ``arrivals[arrival]``."""
        tkey = (flat.kind, round(flat.length, 9), round(flat.depth, 12), round(zeta, 9), arrival)
        got = self.templates.get(tkey)
        if got is not None:
            return got
        got = self._simulate_template(flat, zeta, self.arrivals[arrival])
        self.templates[tkey] = got
        return got

    def _simulate_template(
        self, flat: Flat, zeta: float, initial: InitialState | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        v = self.speed
        half = 0.5 * flat.length / v
        t0, t1 = -(half + PRE_ROLL), half + POST_ROLL
        # a wheel whose last impact has not died out by this one arrives ringing: start the
        # template that many turns earlier, so the same flat's earlier impacts set the state
        turns_before = earlier_turns(
            self.wheel, zeta, TWO_PI * self.wheel.radius / v, self.max_earlier_turns
        )
        t0 -= turns_before * TWO_PI * self.wheel.radius / v
        key = (flat.kind, flat.length, flat.depth)
        table = self.tables.get(key)
        if table is None:  # the same flat is tried at several damping ratios
            table = wheel_table(self.wheel.radius, flat.with_phase(0.0), self.rails, v * t0, v * t1)
            self.tables[key] = table
        wheel = with_damping_ratio(self.wheel, zeta)
        if wheel.rtol < TEMPLATE_RTOL:  # the fit's error is model error, not 1e-8
            wheel = replace(wheel, rtol=TEMPLATE_RTOL)
        out = simulate_window(wheel, v, table, t0, t1, self.fine_rate, initial)
        return out.t, _clip(self.sensor.filter(out.force, self.fine_rate), self.wheel.load)

    def evaluate(
        self, kind: FlatKind, length: float, zeta: float, depth_factor: float = 1.0
    ) -> Candidate:
        key = _key(kind, length, zeta, depth_factor)
        got = self.evaluated.get(key)
        if got is not None:
            return got
        flat = make_flat(self.wheel.radius, kind, length, depth_factor)
        templates = []
        for a in range(len(self.arrivals)):
            try:
                templates.append(self.template(flat, zeta, a))
            except IntegrationError:
                if a == 0:
                    # a candidate the integrator cannot resolve explains nothing
                    nan = np.full(len(self.win), np.nan)
                    cand = Candidate(kind, length, zeta, math.inf, nan, depth_factor)
                    self.evaluated[key] = cand
                    return cand
        half = 0.5 * length / self.speed
        windows = [(self.t[i0:i1], self.f[i0:i1]) for i0, i1 in self.win]
        centres, total = _align_periodic(
            templates, windows, self.anchors, self.turns, half, self.period_band, self.lead
        )
        cand = Candidate(kind, length, zeta, total, centres, depth_factor)
        self.evaluated[key] = cand
        return cand


def make_flat(radius: float, kind: FlatKind, length: float, depth_factor: float = 1.0) -> Flat:
    """A fresh flat of ``length``, or a worn one of depth ``depth_factor``·l²/16R."""
    if kind == "flat":
        return Flat.ideal(radius, length)
    return Flat.rounded(radius, length, depth_factor * typical_rounded_depth(radius, length))


CLIP = 2.0
"""Forces are compared clipped to [0, CLIP·P]: the impacts' timing counts, their height
(which unknown foundation damping changes by tens of per cent) does not dominate."""


def _clip(f: NDArray[np.float64], load: float) -> NDArray[np.float64]:
    return np.clip(f, 0.0, CLIP * load)


def _window_costs(
    tau: NDArray[np.float64],
    tf: NDArray[np.float64],
    tw: NDArray[np.float64],
    fw: NDArray[np.float64],
    shifts: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Sum of squared differences over one window for each flat-centre time in ``shifts``
    (the template ``tf`` is sampled uniformly on ``tau``)."""
    out = np.empty(shifts.size)
    _costs_kernel(float(tau[0]), float(tau[1] - tau[0]), tf, tw, fw, shifts, out)
    return out


@numba.njit(cache=True, nogil=True)
def _costs_kernel(
    tau0: float,
    dtau: float,
    tf: NDArray[np.float64],
    tw: NDArray[np.float64],
    fw: NDArray[np.float64],
    shifts: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    n = tf.size
    m = tw.size
    inv = 1.0 / dtau
    a = np.empty(m)  # the samples' positions on the template's grid, before the shift
    for i in range(m):
        a[i] = (tw[i] - tau0) * inv
    for j in range(shifts.size):
        b = shifts[j] * inv
        acc = 0.0
        for i in range(m):
            u = a[i] - b
            if u <= 0.0:
                v = tf[0]
            elif u >= n - 1:
                v = tf[n - 1]
            else:
                k = int(u)
                w = u - k
                v = tf[k] + w * (tf[k + 1] - tf[k])
            d = fw[i] - v
            acc += d * d
        out[j] = acc


@numba.njit(cache=True, nogil=True)
def _add_on_grid(
    total: NDArray[np.float64],
    s0: NDArray[np.float64],
    turns: float,
    period: NDArray[np.float64],
    c0: float,
    dc: float,
    cost: NDArray[np.float64],
) -> None:
    """total[j, i] += the window's ``cost`` (sampled every ``dc`` from ``c0``, held at its
    ends) linearly interpolated at the flat-centre time s0[i] + turns·period[j].

    ``s0`` is a uniform grid with the cost's step ``dc`` (as ``_align_periodic`` makes
    both): along a row the position on the cost's grid moves by one sample, so the
    interpolation weight is the row's and the row is three plain loops (held at the start,
    interpolated, held at the end), which the compiler vectorises. The row index is the
    period's (rows contiguous)."""
    n = cost.size
    ns = s0.size
    inv = 1.0 / dc
    for j in range(period.size):
        u0 = (s0[0] + turns * period[j] - c0) * inv
        k0 = math.floor(u0)
        w = u0 - k0
        # u = u0 + i: held at cost[0] while u <= 0, at cost[n-1] once u >= n-1
        i_lo = min(max(math.floor(-u0) + 1, 0), ns)
        i_hi = min(max(math.ceil(n - 1 - u0), i_lo), ns)
        row = total[j]
        first, last = cost[0], cost[n - 1]
        for i in range(i_lo):
            row[i] += first
        for i in range(i_lo, i_hi):
            k = k0 + i
            row[i] += cost[k] + w * (cost[k + 1] - cost[k])
        for i in range(i_hi, ns):
            row[i] += last


def _arrival_costs(
    templates: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    tw: NDArray[np.float64],
    fw: NDArray[np.float64],
    shifts: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``_window_costs`` of the window for each shift, the cheapest over ``templates`` (the
    rolling arrival first, then ``arrival_lifts``'): the window arrives in whichever fits."""
    cost = _window_costs(*templates[0], tw, fw, shifts)
    for tau, tf in templates[1:]:
        np.minimum(cost, _window_costs(tau, tf, tw, fw, shifts), out=cost)
    return cost


def _align_periodic(
    templates: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    windows: list[tuple[NDArray[np.float64], NDArray[np.float64]]],
    anchors: NDArray[np.float64],
    turns: NDArray[np.int64],
    half: float,
    band: tuple[float, float],
    lead: float = 0.0,
) -> tuple[NDArray[np.float64], float]:
    """(flat-centre time per window, total cost) with the centres once per turn.

    A flat meets the rail exactly once per turn, so the centres are s0 + n_k·T with one
    s0 and one period T in ``band`` (the speed's uncertainty): a round wheel's random
    bumps cannot be fitted turn by turn. Coarse grid on every window's cost curve, then a
    tenfold finer grid around the best (s0, T).
    """
    t_lo, t_hi = band
    n = turns.astype(np.float64)
    n_max = max(float(n.max()), 1.0)
    s0_grid = np.arange(
        anchors[0] - half - 0.012 - lead,
        anchors[0] + half + 0.002 + 0.5 * SHIFT_STEP,
        SHIFT_STEP,
    )
    n_t = max(3, int(np.ceil((t_hi - t_lo) * n_max / SHIFT_STEP)) + 1)
    t_grid = np.linspace(t_lo, t_hi, n_t)
    total = np.zeros((t_grid.size, s0_grid.size))
    for k, (tw, fw) in enumerate(windows):
        lo = s0_grid[0] + n[k] * t_lo - SHIFT_STEP
        hi = s0_grid[-1] + n[k] * t_hi + SHIFT_STEP
        sk = np.arange(lo, hi + 0.5 * SHIFT_STEP, SHIFT_STEP)
        ck = _arrival_costs(templates, tw, fw, sk)
        _add_on_grid(total, s0_grid, float(n[k]), t_grid, float(sk[0]), SHIFT_STEP, ck)
    # the first minimum in (s0, period) order, as ties have always been broken
    i, j = np.unravel_index(int(np.argmin(total.T)), (s0_grid.size, t_grid.size))
    s0, period = float(s0_grid[i]), float(t_grid[j])
    dt = (t_grid[1] - t_grid[0]) if t_grid.size > 1 else 0.0
    fine_s = s0 + np.linspace(-SHIFT_STEP, SHIFT_STEP, 11)
    fine_t = period + np.linspace(-dt, dt, 11) if windows[1:] else np.array([period])
    best = np.zeros((fine_s.size, fine_t.size))
    for k, (tw, fw) in enumerate(windows):
        shifts = (fine_s[:, None] + n[k] * fine_t[None, :]).ravel()
        best += _arrival_costs(templates, tw, fw, shifts).reshape(best.shape)
    i, j = np.unravel_index(int(np.argmin(best)), best.shape)
    s0, period = float(fine_s[i]), float(fine_t[j])
    return s0 + n * period, float(best[i, j])


NULL_OFFSETS = (0.2, 0.35, 0.5, 0.65, 0.8)
"""Fractions of a turn at which the best flat is also fitted, where there is no flat."""


def _contrast(
    prob: _Problem,
    best: Candidate,
    before: float,
    after: float,
    significance: float,
    rate: float,
    sensor: SensorModel,
) -> float:
    """How much better the best flat explains the once-per-turn windows than the same flat
    explains windows a fraction of a turn away (where a real flat has nothing): the
    significance over the largest of those null significances."""
    R = prob.wheel.radius
    flat = make_flat(R, best.kind, best.length, best.depth_factor)
    try:
        tau, tf = prob.template(flat, best.zeta)
    except IntegrationError:
        return 1.0  # not measurable: the flat does not stand out by this test
    half = 0.5 * best.length / prob.speed
    t, f = prob.t, prob.f
    period = TWO_PI * R / prob.speed
    worst = 1.0
    for frac in NULL_OFFSETS:
        anchors = prob.anchors + frac * period
        ok = (anchors - before >= t[0]) & (anchors + after <= t[-1])
        if not np.any(ok):
            continue
        win = [
            (
                t[int(np.searchsorted(t, a - before)) : int(np.searchsorted(t, a + after))],
                f[int(np.searchsorted(t, a - before)) : int(np.searchsorted(t, a + after))],
            )
            for a in anchors[ok]
        ]
        turns = prob.turns[ok] - prob.turns[ok][0]
        _, cost = _align_periodic(
            [(tau, tf)], win, anchors[ok], turns, half, prob.period_band, prob.lead
        )
        n = sum(w[0].size for w in win)
        load = prob.wheel.load
        c_round = float(sum(np.sum((w[1] - load) ** 2) for w in win))
        n_eff = max(n * (min(1.0, 2.0 * sensor.cutoff_hz / rate) if sensor.cutoff_hz else 1.0), 1.0)
        if cost > 0:
            worst = max(worst, (c_round - cost) / (cost / n_eff))
    return significance / worst


def detection_floor(speed: float, options: FitOptions = DEFAULT_OPTIONS) -> float:
    """The shortest flat reported without standing out of its record (m): ``min_length`` up
    to the first of ``floor_speeds``, ``min_length_fast`` from the second, linear between.

    On the tuning set (seeds 7-9), round wheels on 1-5 µm of unknown roughness were best
    fitted by flats of 5.4-6.6 mm below 75 km/h, 8.8-10.5 mm at 85-100 km/h and up to
    15.8 mm above: the dynamic force of the roughness grows with speed.
    """
    v0, v1 = options.floor_speeds
    u = min(max((speed - v0) / (v1 - v0), 0.0), 1.0)
    return options.min_length + u * (options.min_length_fast - options.min_length)


def _key(
    kind: str, length: float, zeta: float, depth_factor: float
) -> tuple[str, float, float, float]:
    """A candidate's key in ``_Problem.evaluated``."""
    return (kind, round(length, 9), round(zeta, 9), round(depth_factor, 6))


def following_speed(wheel: WheelOnSite) -> float:
    """m/s: the speed up to which a rigid wheel keeps contact over a worn flat of depth
    l²/16R, sqrt(8·R·P/m)/π (the same for every length).

    A haversine dip of depth d over the length l asks the wheel's centre for a downward
    acceleration of up to 2π²·d·V²/l²; contact is lost where that exceeds P/m. With
    d = l²/16R, V_c = sqrt(8RP/m)/π: 20-35 km/h for the wheels of the validation sets.

    >>> round(following_speed(WheelOnSite(537.8, 96762.0, 0.4353, None)) * 3.6, 1)  # W39's
    28.7
    """
    return math.sqrt(8.0 * wheel.radius * wheel.load / wheel.mass) / math.pi


def shallow_following_speed(wheel: WheelOnSite) -> float:
    """m/s: the speed up to which a rigid wheel keeps contact over the shallowest worn flat
    searched (depth factor ``DEPTH_FACTORS[0]``): ``following_speed`` / sqrt(0.7).

    The centre's acceleration over the dip scales with its depth, so a flat of depth factor
    df is followed up to ``following_speed`` / sqrt(df): a shallow worn flat is still
    followed where one of depth l²/16R is not (seed 777's o026: 0.73 × l²/16R at 1.52 ×
    ``following_speed``, 1.30 × its own).

    >>> w = WheelOnSite(537.8, 96762.0, 0.4353, None)
    >>> round(shallow_following_speed(w) / following_speed(w), 3)
    1.195
    """
    return following_speed(wheel) / math.sqrt(DEPTH_FACTORS[0])


def _coarse_keys(
    prob: _Problem,
    kinds: tuple[FlatKind, ...],
    zetas: tuple[float, ...],
    grid: tuple[float, ...],
    options: FitOptions,
) -> list[tuple[FlatKind, float, float, float]]:
    """(kind, length, ζ, depth factor) of every kinds' coarse grid, in the order searched.

    A worn flat is searched at several depth factors where the wheel (nearly) follows it
    (``slow_speed_ratio`` × ``shallow_following_speed``): the dip's shape then carries the depth
    apart from the length, and a long shallow flat fits no length at the factor 1.0. Faster,
    the wheel leaves the flat and depth, length and kind blur, so the extra freedom would
    only take fresh flats for worn ones (docs/diagnosis.md)."""
    slow = prob.speed <= options.slow_speed_ratio * shallow_following_speed(prob.wheel)
    keys: list[tuple[FlatKind, float, float, float]] = []
    for kind in kinds:
        dfs: tuple[float, ...] = (1.0,)
        if kind == "rounded_flat":
            dfs = options.slow_depth_factors if slow else options.coarse_depth_factors
        for df in dfs:
            # away from the factor 1.0 at the middle damping ratio only (the site's, where
            # it states one): the refinement that follows fits the ratio again
            zs = zetas if df == 1.0 else zetas[len(zetas) // 2 : len(zetas) // 2 + 1]
            keys += [(kind, ln, z, df) for z in zs for ln in grid]
    return keys


def _search_kind(
    prob: _Problem,
    kind: FlatKind,
    zetas: tuple[float, ...],
    grid: tuple[float, ...],
    options: FitOptions,
) -> Candidate:
    """The best ``kind`` of flat: the coarse grid, the length and damping refined, a worn
    flat's depth fitted."""
    for key in _coarse_keys(prob, (kind,), zetas, grid, options):
        prob.evaluate(*key)
    cur = _best(prob, kind, depth_factor=None)
    got = _refine(
        prob,
        kind,
        cur.length,
        cur.zeta,
        zetas,
        grid,
        options,
        options.refine_rounds,
        cur.depth_factor,
    )
    return _refine_depth(prob, got, options) if kind == "rounded_flat" else got


def _refine(
    prob: _Problem,
    kind: FlatKind,
    ln: float,
    z: float,
    zetas: tuple[float, ...],
    grid: tuple[float, ...],
    options: FitOptions,
    rounds: int,
    df: float = 1.0,
) -> Candidate:
    """Alternate golden sections on the damping ratio and the length of one kind.

    The first round brackets by the coarse grids' neighbours, later rounds by ±0.06 in
    damping ratio and ±10 % in length; a worn flat at the depth factor ``df``.
    """
    for rnd in range(rounds):
        if len(zetas) > 1:
            if rnd == 0:
                iz = zetas.index(z)
                zlo, zhi = zetas[max(iz - 1, 0)], zetas[min(iz + 1, len(zetas) - 1)]
            else:
                zlo, zhi = max(zetas[0], z - 0.06), min(zetas[-1], z + 0.06)
            _golden(
                lambda zz, ln=ln: prob.evaluate(kind, ln, zz, df).cost,
                zlo,
                zhi,
                options.refine_evaluations - 2,
            )
            z = _best(prob, kind, length=ln, depth_factor=df).zeta
        if rnd == 0:
            i = int(np.argmin([prob.evaluate(kind, g, z, df).cost for g in grid]))
            llo, lhi = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
        else:
            llo, lhi = 0.9 * ln, min(1.1 * ln, grid[-1])
        _golden(
            lambda ll, z=z: prob.evaluate(kind, ll, z, df).cost,
            llo,
            lhi,
            options.refine_evaluations,
        )
        ln = _best(prob, kind, zeta=z, depth_factor=df).length
    return _best(prob, kind, zeta=z, depth_factor=df)


def _best(
    prob: _Problem,
    kind: str,
    *,
    length: float | None = None,
    zeta: float | None = None,
    depth_factor: float | None = 1.0,
) -> Candidate:
    """The cheapest evaluated candidate of ``kind`` (at ``length``, ``zeta`` and
    ``depth_factor`` if given)."""
    return min(
        (
            c
            for c in prob.evaluated.values()
            if c.kind == kind
            and (length is None or c.length == length)
            and (zeta is None or c.zeta == zeta)
            and (depth_factor is None or c.depth_factor == depth_factor)
        ),
        key=lambda c: c.cost,
    )


def _golden(fn: object, lo: float, hi: float, n: int) -> None:
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


WALK_STEPS = (0.06, 0.15, 0.3, 0.5)
"""Relative steps in length by which the interval is walked out from a kind's best, each
side, until the cost passes the χ² band's bound."""


def _walk(length: float, longest: float) -> tuple[list[float], list[float]]:
    """The lengths the interval is walked out to from ``length``, shorter side then longer
    side, each in walking order, within 2 mm … 2 × ``longest``."""
    shorter, longer = (
        list(
            takewhile(
                lambda ln: 0.002 <= ln <= 2.0 * longest,
                (length * (1.0 + direction * step) for step in WALK_STEPS),
            )
        )
        for direction in (-1.0, 1.0)
    )
    return shorter, longer


def _same_depth(cand: Candidate, length: float) -> float:
    """The depth factor that keeps ``cand``'s depth at ``length`` (within ``DEPTH_FACTORS``)."""
    df = cand.depth_factor * (cand.length / length) ** 2
    return min(max(df, DEPTH_FACTORS[0]), DEPTH_FACTORS[1])


def _profile_cost(prob: _Problem, cand: Candidate, length: float, options: FitOptions) -> float:
    """The cost at ``length`` of ``cand``'s kind and damping, a worn flat's depth profiled out.

    A worn flat's depth and length trade off (a longer, shallower dip looks alike through the
    chain): at each length of the interval's walk the depth is the fitted factor's or the one
    that keeps the fitted depth, whichever fits better; a profile, not a slice at one factor.
    """
    cost = prob.evaluate(cand.kind, length, cand.zeta, cand.depth_factor).cost
    if cand.kind == "rounded_flat" and options.depth_profile:
        df = _same_depth(cand, length)
        if df != cand.depth_factor:
            cost = min(cost, prob.evaluate(cand.kind, length, cand.zeta, df).cost)
    return cost


def _profile_points(
    prob: _Problem, cand: Candidate, options: FitOptions
) -> list[tuple[float, float]]:
    """(length, cost) of every length evaluated at ``cand``'s kind, damping and depth factor;
    for a worn flat the cheapest over the depth factors tried at that length (a length tried
    only at another factor, in the depth's own search, is left out: one poor factor there is
    no bound on the profile)."""
    same = [c for c in list(prob.evaluated.values()) if c.kind == cand.kind and c.zeta == cand.zeta]
    best = {c.length: c.cost for c in same if c.depth_factor == cand.depth_factor}
    if cand.kind == "rounded_flat" and options.depth_profile:
        # a length seen at the fitted factor only (the depth's own golden sections) is a
        # slice, not the profile: where depth and length trade off it would cut the interval
        # short, so it counts only where the same-depth factor was tried too (the walk) or
        # coincides with the fitted one
        profiled = {
            c.length for c in same if abs(c.depth_factor - _same_depth(cand, c.length)) < 1e-9
        }
        best = {ln: j for ln, j in best.items() if ln in profiled or ln == cand.length}
        for c in same:
            if c.length in best:
                best[c.length] = min(best[c.length], c.cost)
    return list(best.items())


def _interval(points: list[tuple[float, float]], j_max: float, best: float) -> tuple[float, float]:
    """Where the profile J(l) (sorted points) crosses j_max on each side of ``best``.

    Between the last point inside and the first outside, the crossing is interpolated in
    sqrt(J - J_min), which is linear in the distance from the minimum where the profile is
    a parabola. Interpolating J itself puts the crossing far too close to the inside point
    when the outside one is many times j_max (a walk step that overshoots): with the
    points J = 1 at the best and 30 at +6 %, and j_max = 2.28, J's own interpolation
    gives +0.26 %, the parabola's +1.3 %.
    """
    pts = sorted(points)
    ls = np.array([p[0] for p in pts])
    js = np.array([p[1] for p in pts])
    ib = int(np.argmin(np.abs(ls - best)))
    j0 = min(float(js.min()), j_max)

    def cross(i_in: int, i_out: int) -> float:
        a, b, c = (math.sqrt(max(float(x) - j0, 0.0)) for x in (js[i_in], js[i_out], j_max))
        u = (c - a) / (b - a) if b > a else 0.0
        return float(ls[i_in] + u * (ls[i_out] - ls[i_in]))

    lo = ls[0]
    for i in range(ib, 0, -1):
        if js[i - 1] > j_max:
            lo = cross(i, i - 1)
            break
    hi = ls[-1]
    for i in range(ib, ls.size - 1):
        if js[i + 1] > j_max:
            hi = cross(i, i + 1)
            break
    return float(min(lo, best)), float(max(hi, best))


RING_LEFT = 0.01
"""The fraction of an impact's ringing that may be left when the next turn's flat arrives
for a template to start from steady rolling (1 %: a 10·P impact leaves 0.1·P, a few
times the sensor noise)."""


def slowest_decay(wheel: WheelOnSite, zeta: float) -> float:
    """1/s: the smallest decay rate of the linearised wheel on its foundation damped to
    ``zeta`` (the contact linearised at the static load); inf on a rigid foundation, whose
    only mode, the undamped contact spring, the model leaves ringing at the same flat
    through every turn (and so to the template's own pre-roll)."""
    if not wheel.foundation.is_compliant:
        return math.inf
    return float(np.min(-ringing_modes(wheel, zeta).real))


def earlier_turns(wheel: WheelOnSite, zeta: float, period: float, max_turns: int) -> int:
    """Turns before the flat a template starts: 0 when one turn's decay leaves at most
    ``RING_LEFT`` of the ringing, else enough turns for that (at most ``max_turns``)."""
    sigma = slowest_decay(wheel, zeta)
    if max_turns <= 0 or not math.isfinite(sigma):
        return 0
    if sigma <= 0.0:
        return max_turns
    need = math.log(1.0 / RING_LEFT) / (sigma * period)  # turns for the ringing to die out
    return min(max_turns, max(0, math.ceil(need) - 1))


RING_FIT = 0.04
"""s of record before each window over which the arriving wheel's ringing is fitted (a few
periods of the wheel-on-foundation mode, 60-130 Hz; well after the last turn's bounces)."""

RING_CONTACT = 0.2
"""The ringing is fitted only where the record stays within [0.2, 1.8]·P: the wheel in
contact and the contact near enough to its linearisation (a Hertz spring's stiffness
changes by ±30 % over that range, the foundation's not at all)."""

RING_SETTLE = 0.02
"""s after the previous window's end before the ringing fit may start (its bounces over)."""


def ringing_modes(wheel: WheelOnSite, zeta: float) -> NDArray[np.complex128]:
    """Eigenvalues (1/s) of the wheel on its foundation damped to ``zeta``, the contact
    linearised at the static load (as ``slowest_decay``)."""
    f = wheel.foundation
    m, M, k = wheel.mass, f.mass, f.stiffness
    c = 2.0 * zeta * math.sqrt(k * M)
    kc = 1.5 * wheel.load / (wheel.load / wheel.contact.coefficient) ** (2.0 / 3.0)
    a = np.array(
        [
            [0.0, 1.0, 0.0, 0.0],
            [-kc / m, 0.0, kc / m, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [kc / M, 0.0, -(kc + k) / M, -c / M],
        ]
    )
    return np.asarray(np.linalg.eigvals(a), dtype=np.complex128)


def remove_ringing(
    wheel: WheelOnSite,
    zeta: float,
    sensor: SensorModel,
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    win: list[tuple[int, int]],
) -> NDArray[np.float64]:
    """The record with the ringing the wheel brings to each window taken out of the window.

    A wheel on a lightly damped foundation arrives at its flat still ringing from the last
    turn's impact; a template from steady rolling cannot have that. Before the flat's dip
    the wheel rolls in contact on a round tread, where the wheel on its foundation is
    linear about the static load: its free motion is a sum of its modes (``ringing_modes``).
    Their amplitudes and phases (the state the wheel arrives with) are fitted by least
    squares to the record's last ``RING_FIT`` s before each window (the modes passed
    through the site's chain), and the free motion continued over the window is
    subtracted there; only over stretches where the record stays within ``RING_CONTACT``
    (the wheel in contact), and only when a turn's decay at the site's damping ratio
    ``zeta`` leaves more than ``RING_LEFT`` of an impact's ringing; else ``f`` unchanged.
    """
    fnd = wheel.foundation
    if not fnd.is_compliant or zeta <= 0.0:
        return f
    period_est = t[win[1][0]] - t[win[0][0]] if len(win) > 1 else 0.0
    lam = ringing_modes(wheel, zeta)
    if period_est > 0.0 and np.exp(np.max(lam.real) * period_est) < RING_LEFT:
        return f
    rate = (t.size - 1) / (t[-1] - t[0])
    fine = sensor.fine_rate(rate)
    out = f.copy()
    prev_end = t[0] - RING_SETTLE
    for i0, i1 in win:
        t_start = t[i0]
        a = max(t_start - RING_FIT, prev_end + RING_SETTLE, t[0])
        prev_end = t[i1 - 1]
        j0 = int(np.searchsorted(t, a))
        if i0 - j0 < 40:  # too little record before the window to fit four amplitudes
            continue
        load = wheel.load
        if np.min(f[j0:i0]) < RING_CONTACT * load or np.max(f[j0:i0]) > (2.0 - RING_CONTACT) * load:
            continue  # the wheel still bounces there: not the linear free motion in contact
        # the modes' free responses on a fine grid from before the fit (the chain settles)
        tf = np.arange(a - 3e-3, t[i1 - 1] + 1.0 / fine, 1.0 / fine) - t_start
        basis = []
        for lm in lam:
            if lm.imag < 0.0:
                continue
            e = np.exp(lm.real * tf)
            if lm.imag == 0.0:
                basis.append(e)
            else:
                basis += [e * np.cos(lm.imag * tf), e * np.sin(lm.imag * tf)]
        cols = [np.interp(t[j0:i1] - t_start, tf, sensor.filter(b, fine)) for b in basis]
        cols = [c / max(float(np.max(np.abs(c))), 1e-300) for c in cols]
        x = np.stack([*cols, np.ones(i1 - j0)], axis=1)
        n_fit = i0 - j0
        coef, *_ = np.linalg.lstsq(x[:n_fit], f[j0:i0], rcond=None)
        ring = x[n_fit:, :-1] @ coef[:-1]
        out[i0:i1] = f[i0:i1] - ring
    return out


ARRIVAL_LOOK = 0.03
"""s of record before a window in which the wheel must stay in contact for the window to
count as an arrival from rolling (a few periods of the wheel-on-foundation mode)."""

ARRIVAL_CONTACT = 0.1
"""The wheel is taken to be in contact while the record stays above this share of P (plus
4 noise σ: a record that touches zero has lost contact)."""


def contact_floor(load: float, noise: float) -> float:
    """N: the record above which the wheel is in contact (``ARRIVAL_CONTACT``).

    >>> contact_floor(80e3, 1e3)
    12000.0
    """
    return ARRIVAL_CONTACT * load + 4.0 * noise


def _clean_arrivals(
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    load: float,
    noise: float,
    win: list[tuple[int, int]],
    kept: list[float],
) -> tuple[list[tuple[int, int]], list[float]]:
    """The windows whose wheel arrives rolling in contact, if there is one such.

    A template is the wheel rolling steadily onto the flat. On a lightly damped foundation
    the wheel can still be bouncing from the last turn's impact when the flat comes round
    again (the wide set's W06 loses contact 76 % of the time, with impacts of 4-14 P in the
    40 ms before the flat): its state at the flat is the chaotic outcome of a turn of
    impacts (MODEL.md §7), which neither the template nor a simulation of the earlier turn
    can have, and that window only misleads the fit. A window counts as an arrival from
    rolling when the record stays above ``ARRIVAL_CONTACT``·P + 4σ over the
    ``ARRIVAL_LOOK`` s before it; if at least one window does, only those are compared.
    """
    floor = contact_floor(load, noise)
    look = round(ARRIVAL_LOOK * (t.size - 1) / float(t[-1] - t[0]))
    clean = [
        k
        for k, (i0, _) in enumerate(win)
        if i0 == 0 or float(np.min(f[max(0, i0 - look) : i0])) > floor
    ]
    if not clean or len(clean) == len(win):
        return win, kept
    return [win[k] for k in clean], [kept[k] for k in clean]


EXPLAINED_RATIO = 8.0
"""The fit explains the measurement when its rms residual over the windows is at most this
many times the record's own noise σ. Above the noise, a right fit still leaves what the twin
does not model: up to 10 µm of unknown rail roughness and the chaotic timing of the bounces
(MODEL.md §7). On the project's own generator over the wide space (docs/diagnosis.md) the
fits within tolerance have a median of 2.2x and most stay below 8; most wrong fits lie above."""


def residual_ratio(rms: float, noise: float) -> float:
    """A fit's rms residual over the record's noise σ (infinite for a record without noise)."""
    return rms / noise if noise > 0 else math.inf


def explains(rms: float, noise: float) -> bool:
    """Whether a fit with this rms residual explains a record with this noise σ.

    >>> explains(3e3, 1e3), explains(9e3, 1e3), explains(1.0, 0.0)
    (True, False, False)
    """
    return residual_ratio(rms, noise) <= EXPLAINED_RATIO


def bound_factor(windows: int, options: FitOptions = DEFAULT_OPTIONS) -> float:
    """J_max / J_best of the length interval's χ² bound over ``windows`` windows (the
    residuals are model error, correlated over a window: ``dof_per_window`` degrees of
    freedom each).

    >>> round(bound_factor(2), 2)
    2.28
    """
    return 1.0 + 3.84 / (options.dof_per_window * windows)


DEPTH_FACTORS = (0.7, 1.3)
"""A worn flat's depth is fitted within these multiples of l²/16R (the spread of worn
flats' depths in the literature the wide validation space follows)."""


def _refine_depth(prob: _Problem, cand: Candidate, options: FitOptions) -> Candidate:
    """Fit a worn flat's depth: golden sections on the depth factor, then on the length at
    that depth (depth and length trade off: a deeper flat looks like a longer one), twice."""
    z, ln, df = cand.zeta, cand.length, 1.0
    for _ in range(2):
        _golden(
            lambda dd, ln=ln: prob.evaluate("rounded_flat", ln, z, dd).cost,
            DEPTH_FACTORS[0],
            DEPTH_FACTORS[1],
            options.refine_evaluations - 1,
        )
        df = _best(prob, "rounded_flat", length=ln, zeta=z, depth_factor=None).depth_factor
        _golden(
            lambda ll, df=df: prob.evaluate("rounded_flat", ll, z, df).cost,
            0.9 * ln,
            1.1 * ln,
            options.refine_evaluations - 2,
        )
        ln = _best(prob, "rounded_flat", zeta=z, depth_factor=df).length
    return _best(prob, "rounded_flat", zeta=z, depth_factor=None)


SCREEN_NOISE_SIGMAS = 4.0
"""The record's largest deviation from P, less this many noise σ, is what the screen
compares (4σ: the largest of a few thousand samples of white noise)."""


def _dismissed(
    wheel: WheelOnSite,
    speed: float,
    sensor: SensorModel,
    rate: float,
    f: NDArray[np.float64],
    noise: float,
    zeta_max: float,
    options: FitOptions,
) -> bool:
    """A round wheel dismissed without a fit: the record's largest deviation from a round
    wheel's (``f`` comes here as record - round wheel on the site's rail + P), less
    ``SCREEN_NOISE_SIGMAS`` noise σ, is below the smallest deviation the shortest
    flat the fit would report makes, by both kinds (its template at the detection floor, the
    most damped foundation searched, through the site's chain). A flat below the floor is
    then dismissed too: the fit reports one only when it stands out of its record."""
    P = wheel.load
    deviation = float(np.max(np.abs(f - P))) - SCREEN_NOISE_SIGMAS * noise
    if deviation <= 0.0:
        return True
    prob = _Problem(
        wheel,
        speed,
        sensor,
        sensor.fine_rate(rate),
        np.zeros(0),
        np.zeros(0),
        [],
        np.zeros(0),
        RailTables(RailProfile.flat()),
    )
    floor = detection_floor(speed, options)
    try:
        smallest = min(
            float(
                np.max(np.abs(prob.template(make_flat(wheel.radius, kind, floor), zeta_max)[1] - P))
            )
            for kind in options.kinds
        )
    except IntegrationError:
        return False  # no floor to compare with: the fit decides
    return deviation < smallest


NOISE_DIFFERENCE_ORDER = 3
"""The record's noise is estimated from its third differences: the measuring chain's
low-pass leaves little of the force's own content there, white noise keeps var·20."""


def record_noise(f: NDArray[np.float64]) -> float:
    """σ (N) of the record's white noise: the median absolute third difference / 0.6745,
    over sqrt(20) (the variance of a third difference of white noise). Robust to the
    impacts, which fill a small part of the record; an upper bound when the force itself
    has content near the Nyquist rate."""
    if f.size <= NOISE_DIFFERENCE_ORDER + 1:
        return 0.0
    d = np.diff(f, NOISE_DIFFERENCE_ORDER)
    return float(np.median(np.abs(d)) / 0.6745 / math.sqrt(20.0))


def estimate_flat(
    wheel: WheelOnSite,
    speed: float,
    t: NDArray[np.float64],
    force: NDArray[np.float64],
    sensor: SensorModel,
    options: FitOptions = DEFAULT_OPTIONS,
    baseline: NDArray[np.float64] | None = None,
    compare: Sequence[tuple[FlatKind, float, float]] = (),
) -> FlatEstimate:
    """Fit a flat to the measured ``force`` at times ``t`` (s; t = 0 at the site's start).

    ``speed`` is the best speed known (measured or reported); the turn spacing refines it.
    ``baseline``: a round wheel's force on the site's own rail as the site would measure it
    at ``t`` (the screen compares the record with it; default: the static load).
    ``compare``: (kind, length, depth factor) of flats whose cost on the fit's own windows
    is returned in ``compared`` (the lowest over the best damping ratio and those searched),
    to set against ``cost_best``: validation asks it of the truth. Nothing else changes.
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
    noise = record_noise(f)
    f_site = wheel.foundation
    zetas: tuple[float, ...] = (0.0,)
    zeta_site = 0.0
    if f_site.is_compliant:
        zeta_site = damping_ratio_of(f_site)
        if zeta_site > 0.0 and options.site_damping_band > 1.0:
            # the site states its damper: trust it within a factor (a track's damping is
            # never zero, so a zero damper means "not known" and the whole range is searched)
            b = options.site_damping_band
            zetas = (round(zeta_site / b, 6), round(zeta_site, 6), round(zeta_site * b, 6))
        else:
            zetas = tuple(sorted({round(zeta_site, 6), *options.damping_ratios}))
    if baseline is not None and baseline.shape != f.shape:
        raise ValueError("diagnosis: baseline must have one value per measured sample")
    base = baseline if baseline is not None else np.full_like(f, P)
    if options.screen and _dismissed(
        wheel, speed, sensor, rate, f - base + P, noise, zetas[-1], options
    ):
        cost = float(np.sum((_clip(f, P) - _clip(base, P)) ** 2))
        return FlatEstimate(
            None,
            None,
            0.0,
            0.0,
            0.0,
            cost,
            cost,
            int(f.size),
            0.0,
            0.0,
            speed,
            zetas[-1],
            (),
            (),
            time.perf_counter() - start,
            noise_level=noise,
            screened=True,
        )
    floor = contact_floor(P, noise) if options.rolling_anchors else None
    anchors = find_anchors(t, f, P, R, speed, contact_floor=floor)
    v = speed
    if anchors.times.size >= 2:
        v = min(max(TWO_PI * R / anchors.period, 0.97 * speed), 1.03 * speed)
    lead = anchors.lead if options.first_impact_lead else 0.0
    before = WINDOW_BEFORE / v + 2e-3 + lead
    after = WINDOW_AFTER + (
        2.0 * sensor.order / (TWO_PI * sensor.cutoff_hz) if sensor.cutoff_hz else 0.0
    )
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
    if options.clean_arrivals and len(win) > 1:
        win, kept = _clean_arrivals(t, f, P, noise, win, kept)
    n = sum(i1 - i0 for i0, i1 in win)
    if options.ringing and win:
        f = remove_ringing(wheel, zeta_site, sensor, t, f, win)
    f = _clip(f, P)
    cost_round = float(sum(np.sum((f[i0:i1] - P) ** 2) for i0, i1 in win))
    windows = tuple((float(t[i0]), float(t[i1 - 1])) for i0, i1 in win)
    if not win:
        return FlatEstimate(
            None,
            None,
            0.0,
            0.0,
            0.0,
            cost_round,
            cost_round,
            0,
            0.0,
            0.0,
            v,
            0.0,
            windows,
            (),
            time.perf_counter() - start,
            noise_level=noise,
        )
    kept_a = np.array(kept)
    t_speed = TWO_PI * R / speed
    turns = np.rint((kept_a - kept_a[0]) / t_speed).astype(np.int64)
    band = (
        t_speed / (1.0 + options.speed_uncertainty_fit),
        t_speed / (1.0 - options.speed_uncertainty_fit),
    )
    prob = _Problem(
        wheel,
        v,
        sensor,
        sensor.fine_rate(rate),
        t,
        f,
        win,
        kept_a,
        RailTables(RailProfile.flat()),
        turns=turns,
        period_band=band,
        max_earlier_turns=options.max_earlier_turns,
        lead=lead,
    )
    if options.arrival_lifts and win:
        period_est = TWO_PI * R / v
        sigma = slowest_decay(wheel, zeta_site) if zeta_site > 0.0 else math.inf
        if math.isfinite(sigma) and math.exp(-sigma * period_est) > RING_LEFT:
            d0 = (P / wheel.contact.coefficient) ** (2.0 / 3.0)
            prob.arrivals = (None, *(InitialState(y_c=h * d0) for h in options.arrival_lifts))
    grid = tuple(sorted(options.lengths))
    # per kind: a coarse grid of lengths and damping ratios, then the length and the ratio by
    # alternating golden sections (they trade off: more damping looks like a shorter flat),
    # then a worn flat's depth; the kinds are independent, a forked child may take one
    best_of_kind: dict[FlatKind, Candidate] = {}
    kinds = options.kinds
    if options.cores > 1 and len(kinds) > 1:
        first = kinds[0]

        def child() -> tuple[Candidate, list[Candidate]]:
            got = _search_kind(prob, first, zetas, grid, options)
            # the interval's walk around it, ahead of knowing how far it goes (the child
            # has time while the other kind's depth is fitted; the walk then finds these;
            # those it does not need stay in the profile only, never in the Diagnosis)
            for side in _walk(got.length, grid[-1]):
                for ln in side:
                    _profile_cost(prob, got, ln, options)
            return got, [c for c in prob.evaluated.values() if c.kind == first]

        with Forked(child) as forked:
            for kind in kinds[1:]:
                best_of_kind[kind] = _search_kind(prob, kind, zetas, grid, options)
            best_of_kind[first], seen = forked.value()  # (here, if no child could)
        for c in seen:
            prob.evaluated.setdefault(_key(c.kind, c.length, c.zeta, c.depth_factor), c)
        best_of_kind = {k: best_of_kind[k] for k in kinds}
    else:
        for kind in kinds:
            best_of_kind[kind] = _search_kind(prob, kind, zetas, grid, options)
    best = min(best_of_kind.values(), key=lambda c: c.cost)
    n_eff = n * (min(1.0, 2.0 * sensor.cutoff_hz / rate) if sensor.cutoff_hz else 1.0)
    n_eff = max(n_eff, 1.0)
    significance = (cost_round - best.cost) / (best.cost / n_eff) if best.cost > 0 else math.inf
    j_max = best.cost * bound_factor(len(win), options)
    # the interval: every kind whose best is within j_max contributes its own (a fresh flat
    # and a worn one ~25 % longer can make the same windows), each walked out from its best
    # length at its damping until the cost passes j_max
    lo, hi = best.length, best.length
    interval_kinds: list[FlatKind] = []
    for cand in best_of_kind.values():
        if cand.cost > j_max and cand is not best:
            continue
        for side in _walk(cand.length, grid[-1]):
            for ln in side:
                if _profile_cost(prob, cand, ln, options) > j_max:
                    break
        k_lo, k_hi = _interval(_profile_points(prob, cand, options), j_max, cand.length)
        lo, hi = min(lo, k_lo), max(hi, k_hi)
        interval_kinds.append(cand.kind)
    at_zeta = [c for c in prob.evaluated.values() if c.zeta == best.zeta and c.depth_factor == 1.0]
    lo *= 1.0 - options.speed_uncertainty
    hi *= 1.0 + options.speed_uncertainty
    # the detection floor: above ~75 km/h a few µm of unknown roughness excite as much dynamic
    # force as a 10-15 mm flat (tuning set: round wheels fitted up to 14.7 mm there)
    contrast = _contrast(prob, best, before, after, significance, rate, sensor)
    floor = detection_floor(v, options)
    # below the floor, a flat is reported only if it stands out of its own record: its
    # once-per-turn windows fit it far better than windows a fraction of a turn away
    standout = contrast >= options.contrast and best.length >= options.min_length_contrast
    # a small flat on an unknown rough rail: where the whole interval lies below
    # ``small_flat_floors`` x the floor and reaches below the shortest flat searched, the
    # record does not tell it from a round wheel (the significance alone does not: every
    # candidate's windows are aligned in time, a round wheel's are not)
    like_round = hi < options.small_flat_floors * floor and lo < options.min_length
    # a fit that explains its record makes the χ² bound a confidence region: where the round
    # wheel lies inside it, the record does not exclude "no flat" (with two or three windows
    # the bound is wide). A fit that does not explain its record leaves a bound set by what
    # the twin does not model, not by the flat: there the significance alone decides
    round_in_bound = explains(math.sqrt(best.cost / max(n, 1)), noise) and cost_round <= j_max
    found = (
        significance >= options.detection
        and not round_in_bound
        and (standout or (best.length >= floor and not like_round))
    )
    flat: Flat | None = None
    if found:
        phases = np.exp(1j * (-(v * best.centres) / R))
        phase = float(np.angle(np.mean(phases))) % TWO_PI
        flat = make_flat(R, best.kind, best.length, best.depth_factor).with_phase(phase)
    profile = tuple(
        (c.kind, c.length, c.cost) for c in sorted(at_zeta, key=lambda c: (c.kind, c.length))
    )
    compared = tuple(
        min(prob.evaluate(kind, ln, z, df).cost for z in {best.zeta, *zetas})
        for kind, ln, df in compare
    )
    return FlatEstimate(
        flat,
        best.kind,
        best.length,
        lo,
        hi,
        cost_round,
        best.cost,
        n,
        float(significance),
        float(contrast),
        v,
        best.zeta,
        windows,
        profile,
        time.perf_counter() - start,
        best.depth_factor,
        tuple(interval_kinds),
        noise,
        compared=compared,
    )
