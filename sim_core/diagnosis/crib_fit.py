"""The fit from crib channels: which flat makes the twin's channels look like the measured ones.

The twin simulates the wheel on the site's track with the site's cribs and chain
(``crib_forward``); a candidate is a flat's kind, length and phase. A forward run simulates
only the windows compared (``CribSite.run_spans``, 0.01-0.07 s; 16-21 a flat wheel), so
the search is short and driven by the record:

1. **Screen** (``crib_screen``, no simulation): a record within the round wheel's allowance
   of the round template is dismissed.
2. **Where the flat's event begins** (``anchor``): the record's excess over the round
   template (summed over the cribs) at its largest, traced back to where it first reached
   half of that (the unloading dip or the first impact: a long flat's largest peak may be a
   later bounce). Windows around it and every 2πR/V from it (one per turn in the record)
   are compared, every crib; all turns at once (the phase is one unknown). Each window is
   simulated on its own from static equilibrium ``RUN_IN`` before it: the previous turn's
   impact is not carried into the next window. Its wake may ring for a turn on a lightly
   damped track, and how long it rings is what a nominal track gets wrong: on the
   handed-over slab site (pads 27 % stiffer than the truth) the twin's contact force still
   swung ±20 % of P just before the next window where the truth's had settled to ±10 %,
   and drew the fit of 104-119 mm flats 10-20 % short.
3. **Kind and length.** Each kind is run at the lengths of ``LENGTH_GRID``. A candidate's
   phase puts its event on the measured one: the impact trails the flat's centre by l/2 of
   travel plus an offset, which each run measures (the cross-correlation of its excess with
   the measured one over the windows) and which the next run of the kind interpolates
   linearly in the length (``_Search.offset``; a kind's first run takes the other kind's).
   The cost, the sum of squared channel differences over the windows, is taken on the run
   whose excess over the round template is shifted by the measured delay (the gauges' steps
   stay put), so that it does not jump with a phase a fraction of a millisecond off.
4. **Refinement and interval.** Successive parabolic steps in log length from each kind's
   best grid run (``REFINE_RUNS`` each; the other kind only if its best is within
   ``KIND_REFINE_RATIO`` of the best), ``END_STEP`` (half a grid step) outwards where the
   best is the longest or shortest run so far; the best run and its near neighbours are
   run again at their aligned phase first if they were more than ``PHASE_TOLERANCE`` off
   (``_realign``). The cheaper kind wins. The length interval is where
   the cost's parabola through the best run and its neighbours stays within the χ² bound
   J <= J_min·(1 + 3.84/(``DOF_PER_WINDOW``·windows)) (the residual is model error,
   correlated over a window). A flat that explains the windows no better than the round
   template is not reported.

A worn flat's depth is taken as l²/16R (depth factor 1): fitting it as well (three more runs)
was measured on the handed-over detector sites and helped on calibrated site files as much as
it hurt on nominal ones. docs/service.md ("Wheel-flat diagnosis") has the method, the README
the validation on an independent solver's records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sim_core.diagnosis.crib_forward import CribRun, CribSite, CribWheel
from sim_core.diagnosis.crib_screen import Screen, round_template, screen
from sim_core.diagnosis.forward import Flat, FlatKind, ideal_flat_depth, typical_rounded_depth
from sim_core.passage import IntegrationError
from sim_core.wheel import TWO_PI

__all__ = ["DOF_PER_WINDOW", "LENGTH_GRID", "CribEstimate", "fit_channels", "flat_of"]

KINDS: tuple[FlatKind, ...] = ("flat", "rounded_flat")

LENGTH_GRID = (0.015, 0.025, 0.04, 0.065, 0.105)
"""m: the lengths tried for each kind (about 1.6 apart), before the refinement."""

GRID_STEP = math.log(1.6)
"""The grid's step in log length."""

END_STEP = 0.5 * GRID_STEP
"""The refinement's step in log length outwards from an end of the runs so far: half the
grid's, so that a flat just beyond the grid's longest (105-130 mm) is bracketed by a run near
it (a whole step, to 168 mm, cost 5-30x the best and drew the parabola's vertex short)."""

MAX_REALIGN = 2
"""Rounds of ``_realign`` a kind's refinement may take (each 1-3 runs, besides ``runs``)."""

PHASE_TOLERANCE = 0.003
"""m: a run whose phase was further than this off the aligned one is run again before the
refinement steps from it or its neighbours (``_realign``)."""

MIN_STEP = 0.01
"""Smallest step in log length the refinement takes (1 %: below what the data resolve)."""

REFINE_RUNS = 3
"""Runs refining each kind's length."""

KIND_REFINE_RATIO = 10.0
"""The other kind is refined too when its best grid cost is within this factor of the best:
a wide factor, since a fresh flat's cost is sharp in the length and its grid points may all
miss its minimum (a 30 mm fresh flat at 40 km/h cost 4x a worn 42 mm one at the grid's 25 and
40 mm, and 0.5x at 30 mm)."""

LENGTH_RANGE = (0.006, 0.2)
"""m: the lengths the search may try."""

DOF_PER_WINDOW = 1.0
"""Degrees of freedom of the model error per compared window (χ² bound of the interval)."""

WINDOW_BEFORE = 0.15
"""m of travel before a measured impact that its window covers (the longest flat's dip)."""

WINDOW_AFTER = 0.008
"""s after a measured impact that its window covers (the impact and the first rebound)."""

ANCHOR_REACH = 0.4
"""m before the largest excess searched for the event's beginning (``anchor``)."""

ANCHOR_LEVEL = 0.5
"""Fraction of the largest |excess| that marks the event's beginning (``anchor``)."""

SPAN_MARGIN = 0.003
"""s simulated either side of a window (``CribSite.run_spans``): the alignment's time shift
(a millisecond or two) reads the run that far beyond the window."""

MAX_SHIFT = 80
"""Samples either way over which a candidate's excess is aligned with the measured one."""


def flat_of(
    radius: float, kind: FlatKind, length: float, phase: float, depth_factor: float = 1.0
) -> Flat:
    """The candidate flat: a fresh chord, or a worn flat of depth ``depth_factor``·l²/16R."""
    if kind == "flat":
        return Flat("flat", length, ideal_flat_depth(radius, length), phase % TWO_PI)
    depth = depth_factor * typical_rounded_depth(radius, length)
    return Flat("rounded_flat", length, depth, phase % TWO_PI)


@dataclass(frozen=True)
class Trial:
    """One forward run of the search: the candidate (phase as aligned) and its cost."""

    kind: FlatKind
    length: float
    phase: float
    cost: float
    peak_force: float
    run: CribRun = field(repr=False)
    misaligned: float = 0.0
    """m by which the run's phase was off the aligned one (its cost is taken on the run
    shifted in time, which holds to a few mm: ``PHASE_TOLERANCE``)."""


@dataclass(frozen=True)
class CribEstimate:
    """What the fit found (``flat`` None: a round wheel, dismissed by the screen or because
    no flat explains the record better than the round template).

    ``cost_*`` are sums of squared channel differences over the ``n_samples`` compared
    (N²); ``fitted`` the best candidate's channels at the record's instants (rows per crib);
    ``peak_force_fit`` its contact peak over the windows simulated; ``runs`` the forward runs."""

    flat: Flat | None
    best_kind: FlatKind | None
    length_low: float
    length_high: float
    cost_round: float
    cost_best: float
    n_samples: int
    windows: int
    noise: float
    screen: Screen
    runs: int
    fitted: NDArray[np.float64] = field(repr=False)
    peak_force_fit: float
    trials: tuple[tuple[str, float, float], ...] = ()
    speed: float = 0.0

    @property
    def screened(self) -> bool:
        return not self.screen.flat_suspected

    @property
    def fit_rms(self) -> float:
        cost = self.cost_best if self.flat is not None else self.cost_round
        return math.sqrt(cost / max(self.n_samples, 1))


class _Search:
    """The record, its windows and the runs made so far."""

    def __init__(
        self,
        site: CribSite,
        wheel: CribWheel,
        speed: float,
        t: NDArray[np.float64],
        channels: NDArray[np.float64],
        template: NDArray[np.float64],
        t_star: float,
    ) -> None:
        self.site, self.wheel, self.speed, self.t = site, wheel, speed, t
        self.channels, self.template, self.t_star = channels, template, t_star
        period = TWO_PI * wheel.radius / speed
        self.period = period
        inside = site.in_fit_stretch(t, speed)
        mask = np.zeros(t.size, dtype=np.bool_)
        k0 = math.floor((t[0] - t_star) / period) - 1
        k1 = math.ceil((t[-1] - t_star) / period) + 1
        windows = 0
        spans: list[tuple[float, float]] = []
        for k in range(k0, k1 + 1):
            tk = t_star + k * period
            w = (t >= tk - WINDOW_BEFORE / speed - 0.002) & (t <= tk + WINDOW_AFTER) & inside
            if np.any(w):
                windows += 1
                mask |= w
                a = speed * (tk - 0.002 - SPAN_MARGIN) - WINDOW_BEFORE
                spans.append((a, speed * (tk + WINDOW_AFTER + SPAN_MARGIN)))
        self.mask = mask
        self.spans = spans
        self.windows = max(windows, 1)
        self.lags: dict[FlatKind, list[tuple[float, float]]] = {}
        self.runs = 0
        self.trials: list[Trial] = []

    def cost(self, chans: NDArray[np.float64]) -> float:
        d = (self.channels - chans)[:, self.mask]
        return float(np.sum(d * d))

    def excess(self, chans: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.asarray(np.sum(chans - self.template, axis=0), dtype=np.float64)

    def delay(self, chans: NDArray[np.float64]) -> float | None:
        """s by which the simulated excess lags the measured one over the windows (the
        cross-correlation's peak, to a fraction of a sample). The product, not the squared
        difference: a candidate whose impact is larger than the measured one would otherwise
        be shifted to put its impact outside the windows (into the round template beyond a
        run's spans, whose excess is zero), locking every later run's phase off. None
        where the peak is at the end of the ``MAX_SHIFT`` searched (no peak: a short flat at
        speed whose excess is lost in the noise), or the windows hold too few samples."""
        m = self.excess(self.channels)
        s = self.excess(chans)
        dt = float(self.t[1] - self.t[0])
        idx = np.flatnonzero(self.mask)
        if idx.size < 3:
            return None
        lags = range(-MAX_SHIFT, MAX_SHIFT + 1)
        a = m[idx]
        scores = []
        for k in lags:
            j = np.clip(idx + k, 0, s.size - 1)
            scores.append(-float(np.dot(a, s[j])))
        i = int(np.argmin(scores))
        if not 0 < i < len(scores) - 1:
            return None
        frac = 0.0
        y0, y1, y2 = scores[i - 1], scores[i], scores[i + 1]
        den = y0 - 2.0 * y1 + y2
        if den > 0.0:
            frac = 0.5 * (y0 - y2) / den
        return (lags[i] + frac) * dt

    def offset(self, kind: FlatKind, length: float) -> float:
        """m by which the impact trails the flat's centre beyond l/2 for this kind and
        length: linear in the length through the two aligned runs nearest to it (the other
        kind's before the kind's first run, the chain's delay before any)."""
        known = sorted(self.lags.get(kind, []), key=lambda p: abs(p[0] - length))
        if not known:  # the other kind's impacts trail alike (within a few mm at one length)
            known = sorted(
                (p for ps in self.lags.values() for p in ps), key=lambda p: abs(p[0] - length)
            )
        if not known:
            return self.speed * self._chain_delay()
        if len(known) == 1 or abs(known[0][0] - known[1][0]) < 1e-6:
            return known[0][1]
        (l1, o1), (l2, o2) = known[0], known[1]
        return o1 + (o2 - o1) * (length - l1) / (l2 - l1)

    def run(self, kind: FlatKind, length: float) -> Trial | None:
        """Simulate the candidate with the phase that puts its excess on the measured one
        (``offset``); None if the integrator cannot
        resolve it."""
        R, V = self.wheel.radius, self.speed
        offset = self.offset(kind, length)
        x_centre = V * self.t_star - 0.5 * length - offset
        phase = -x_centre / R
        try:
            got = self.site.run(
                self.wheel, V, flat_of(R, kind, length, phase), self.t, spans=self.spans
            )
        except IntegrationError:
            return None
        found = self.delay(got.channels)
        shift = 0.0 if found is None else found
        mine = [p for p in self.lags.get(kind, []) if abs(p[0] - length) > 1e-9]
        if found is not None:
            mine.append((length, offset + V * shift))
        self.lags[kind] = mine
        self.trials = [tr for tr in self.trials if tr.kind != kind or tr.length != length]
        self.runs += 1
        # the run as it would be at the aligned phase: its excess over the round template
        # shifted in time (a fraction of a millisecond, over which the cribs hardly move
        # relative to the impact); the gauge steps stay where the wheel crosses the gauges
        aligned = np.empty_like(got.channels)
        for i in range(aligned.shape[0]):
            ex = got.channels[i] - self.template[i]
            aligned[i] = self.template[i] + np.interp(self.t + shift, self.t, ex)
        trial = Trial(
            kind, length, phase + V * shift / R, self.cost(aligned), got.peak_force, got, V * shift
        )
        self.trials.append(trial)
        return trial

    def _chain_delay(self) -> float:
        """s: the chain's group delay at low frequency (Butterworth: sum of 1/(ω·sin θ_k))."""
        s = self.site.sensor
        if s.cutoff_hz is None:
            return 0.0
        w = TWO_PI * s.cutoff_hz
        n = s.order
        return sum(1.0 / (w * math.sin(math.pi * (2 * k + 1) / (2 * n))) for k in range(n)) / 2.0


def _parabola(points: list[tuple[float, float]]) -> tuple[float, float, float] | None:
    """(a, l0, J0) of J = a (l - l0)² + J0 through three (l, J) points, or None."""
    (x1, y1), (x2, y2), (x3, y3) = sorted(points)
    den = (x1 - x2) * (x1 - x3) * (x2 - x3)
    if den == 0.0:
        return None
    a = (x3 * (y2 - y1) + x2 * (y1 - y3) + x1 * (y3 - y2)) / den
    b = (x3 * x3 * (y1 - y2) + x2 * x2 * (y3 - y1) + x1 * x1 * (y2 - y3)) / den
    if a <= 0.0:
        return None
    c = y1 - a * x1 * x1 - b * x1
    l0 = -b / (2.0 * a)
    return a, l0, c - b * b / (4.0 * a)


def anchor(
    excess: NDArray[np.float64], t: NDArray[np.float64], inside: NDArray[np.bool_], speed: float
) -> float:
    """t*: where the flat's event begins in the record. The largest |excess| may be a later
    bounce of a long flat (a 111 mm worn flat at 48 km/h bounced 0.28 m on); the event
    begins at the first sample within ``ANCHOR_REACH`` before it where |excess| reaches
    ``ANCHOR_LEVEL`` of that largest (the unloading dip, or the first impact)."""
    a = np.where(inside, np.abs(excess), -np.inf)
    i = int(np.argmax(a))
    near = inside & (t >= t[i] - ANCHOR_REACH / speed) & (t <= t[i])
    first = np.flatnonzero(near & (a >= ANCHOR_LEVEL * a[i]))
    return float(t[first[0]]) if first.size else float(t[i])


def _of_kind(search: _Search, kind: FlatKind) -> list[Trial]:
    return sorted((tr for tr in search.trials if tr.kind == kind), key=lambda tr: tr.length)


def _realign(search: _Search, kind: FlatKind, around: int) -> None:
    """Run again, at their aligned phase, the kind's runs at ``around`` and either side of
    it (sorted by length) whose phase was more than ``PHASE_TOLERANCE`` off: a kind's first
    run has only the chain's delay to go by, and one far from the lengths run before it only
    an extrapolation, and their costs, taken on a run shifted by a millisecond or more, stand
    too high (a 15 mm run 38 mm off, a 168 mm one 0.3 m: the alignment locked on to another
    feature)."""
    for tr in _misaligned(search, kind, around):
        search.run(kind, tr.length)


def _misaligned(search: _Search, kind: FlatKind, around: int) -> list[Trial]:
    """The runs ``_realign`` would run again: the kind's run at ``around`` and those either
    side of it whose phase was off (a 14 mm misalignment put a 105 mm run at 4x its aligned
    cost)."""
    mine = _of_kind(search, kind)
    return [
        mine[k]
        for k in range(max(around - 1, 0), min(around + 2, len(mine)))
        if abs(mine[k].misaligned) > PHASE_TOLERANCE
    ]


def _refine(search: _Search, kind: FlatKind, runs: int) -> Trial:
    """Successive parabolic steps in log length from the kind's best run (golden steps where
    the parabola is not convex, ``END_STEP`` outwards at the ends of the runs so far); runs
    around the best whose phase was off are run again first (``_realign``, up to
    ``MAX_REALIGN`` rounds besides ``runs``); the best run after."""
    done = realigned = 0
    while done < runs:
        mine = _of_kind(search, kind)
        i = min(range(len(mine)), key=lambda k: mine[k].cost)
        if realigned < MAX_REALIGN and _misaligned(search, kind, i):
            realigned += 1
            _realign(search, kind, i)
            continue
        u = [math.log(tr.length) for tr in mine]
        if i == 0:
            nxt = u[0] - END_STEP
        elif i == len(mine) - 1:
            nxt = u[-1] + END_STEP
        else:
            par = _parabola([(u[k], mine[k].cost) for k in (i - 1, i, i + 1)])
            far = i - 1 if u[i] - u[i - 1] > u[i + 1] - u[i] else i + 1
            golden = u[i] + 0.382 * (u[far] - u[i])
            nxt = golden if par is None else min(max(par[1], u[i - 1]), u[i + 1])
            if min(abs(nxt - x) for x in u) < MIN_STEP:
                nxt = golden
        lo, hi = math.log(LENGTH_RANGE[0]), math.log(LENGTH_RANGE[1])
        if not lo <= nxt <= hi or min(abs(nxt - x) for x in u) < MIN_STEP:
            break
        search.run(kind, math.exp(nxt))
        done += 1
    return min(_of_kind(search, kind), key=lambda tr: tr.cost)


def _interval(search: _Search, kind: FlatKind, best: Trial) -> tuple[float, float]:
    """The lengths where the cost's parabola through the best run and its nearest runs either
    side (log length) stays within the χ² bound; without one, the span of runs within it.
    Either is clipped to the lengths the search may try (``LENGTH_RANGE``): a cost nearly flat
    in the length (a record the flat barely changes) gives a parabola so shallow that its
    bound lay at 1 µm and 104 m, where the data say only "somewhere in the range"."""
    bound = 1.0 + 3.84 / (DOF_PER_WINDOW * search.windows)
    mine = _of_kind(search, kind)
    i = mine.index(best)
    low, high = None, None
    if 0 < i < len(mine) - 1:
        pts = [(math.log(mine[k].length), mine[k].cost) for k in (i - 1, i, i + 1)]
        par = _parabola(pts)
        if par is not None:
            a, u0, j0 = par
            half = math.sqrt(max(best.cost * bound - j0, 0.0) / a)
            low, high = math.exp(u0 - half), math.exp(u0 + half)
    if low is None or high is None:
        ok = [tr.length for tr in mine if tr.cost <= best.cost * bound]
        low, high = min(ok), max(ok)
    # within the search's range, and holding the best run
    return min(max(low, LENGTH_RANGE[0]), best.length), max(min(high, LENGTH_RANGE[1]), best.length)


def fit_channels(
    site: CribSite,
    wheel: CribWheel,
    speed: float,
    t: NDArray[np.float64],
    channels: NDArray[np.float64],
) -> CribEstimate:
    """Fit a flat to the measured ``channels`` (rows in ``site.cribs``' order) at times ``t``."""
    template = round_template(site.cribs, speed, wheel.load, t, site.sensor)
    sc = screen(channels, template, speed, wheel.load)
    inside = site.in_fit_stretch(t, speed)
    d0 = (channels - template)[:, inside]
    n_all = int(d0.size)
    cost_round_all = float(np.sum(d0 * d0))
    if not sc.flat_suspected:
        return CribEstimate(
            None,
            None,
            0.0,
            0.0,
            cost_round_all,
            cost_round_all,
            n_all,
            0,
            sc.noise,
            sc,
            0,
            template,
            wheel.load,
            speed=speed,
        )
    t_star = anchor(np.sum(channels - template, axis=0), t, inside, speed)
    search = _Search(site, wheel, speed, t, channels, template, t_star)
    cost_round = search.cost(template)
    n = int(np.count_nonzero(search.mask)) * len(site.cribs)
    for kind in KINDS:
        for length in LENGTH_GRID:
            search.run(kind, length)
    if not search.trials:
        return CribEstimate(
            None,
            None,
            0.0,
            0.0,
            cost_round,
            cost_round,
            n,
            search.windows,
            sc.noise,
            sc,
            0,
            template,
            wheel.load,
            speed=speed,
        )
    best_of: dict[FlatKind, Trial] = {}
    for tr in search.trials:
        if tr.kind not in best_of or tr.cost < best_of[tr.kind].cost:
            best_of[tr.kind] = tr
    lowest = min(tr.cost for tr in best_of.values())
    refined: dict[FlatKind, Trial] = {}
    for k, tr in best_of.items():
        if tr.cost <= KIND_REFINE_RATIO * lowest:
            runs = REFINE_RUNS
            refined[k] = _refine(search, k, runs)
    kind = min(refined, key=lambda k: refined[k].cost)
    final = refined[kind]
    low, high = _interval(search, kind, final)
    low, high = min(low, final.length), max(high, final.length)
    if final.cost >= cost_round:  # no flat explains the windows better than a round wheel
        return CribEstimate(
            None,
            None,
            low,
            high,
            cost_round,
            final.cost,
            n,
            search.windows,
            sc.noise,
            sc,
            search.runs,
            template,
            wheel.load,
            speed=speed,
        )
    return CribEstimate(
        flat_of(wheel.radius, kind, final.length, final.phase),
        kind,
        low,
        high,
        cost_round,
        final.cost,
        n,
        search.windows,
        sc.noise,
        sc,
        search.runs,
        final.run.channels,
        final.peak_force,
        tuple((tr.kind, tr.length, tr.cost) for tr in search.trials),
        speed,
    )
