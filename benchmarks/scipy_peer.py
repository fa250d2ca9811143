"""The benchmark's peer: SciPy ``solve_ivp`` on exactly the case railtwin's integrator solves.

Two ways of running SciPy on a passage (MODEL.md §4), both on the same
tabulated constraint y_C^k as ``sim_core`` (so the comparison measures the
integrators, not the geometry):

- :func:`solve_events` — the honest peer: one mode at a time (flight, elastic
  contact, plastic contact), terminal events with a direction (δ = 0, δ = δ_Y),
  a restart with the other law after every event and at every kink of the
  constraint. This is the classic way to get the loss/return of contact right
  with a general-purpose solver.
- :func:`solve_plain` — for scale only: one call, no event location, the
  force law evaluated with max(δ, 0) (the solver steps over the switches and
  its error control copes as it can). Fast, but neither the transition list
  nor the peak force is located.

The constraint is read from the table's nodes with a scalar Python Hermite
look-up (values, left/right slopes, periodic wrap): the same piecewise cubic
``sim_core.constraint.table`` evaluates, written independently here.

Tolerances are matched to railtwin's (``PassageSpec.rtol``; absolute
tolerances rtol·δ0 on positions and rtol·δ0·ω0 on velocities). ``max_step`` is
the table's resolution over the speed, the cap railtwin uses in contact, also
applied in flight so that the sign test of the events does not step over a
short contact (DOP853's error estimate is zero on the flight parabola).
"""

from __future__ import annotations

import bisect
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

from sim_core.constraint.table import ConstraintTable
from sim_core.contact_laws import ContactLaw
from sim_core.passage import PassageSpec, static_indentation

FLIGHT, ELASTIC, PLASTIC = 0, 1, 2
_NEXT = {"contact": ELASTIC, "loss": FLIGHT, "yield": PLASTIC, "unyield": ELASTIC}


def hermite_lookup(table: ConstraintTable) -> Callable[[float], float]:
    """y_C^k(x) as a scalar Python function of the table's nodes (periodic wrap, flat ends)."""
    xs = table.x.tolist()
    ys = table.y.tolist()
    sr = table.slope_right.tolist()
    sl = table.slope_left.tolist()
    period = float(table.period)
    x0, xn = xs[0], xs[-1]
    n = len(xs)

    def f(x: float) -> float:
        if period > 0.0:
            x -= period * math.floor((x - x0) / period)
        elif x <= x0:
            return float(ys[0])
        elif x >= xn:
            return float(ys[-1])
        i = min(max(bisect.bisect_right(xs, x) - 1, 0), n - 2)
        h = xs[i + 1] - xs[i]
        s = (x - xs[i]) / h
        s2 = s * s
        s3 = s2 * s
        return float(
            (2 * s3 - 3 * s2 + 1) * ys[i]
            + (s3 - 2 * s2 + s) * h * sr[i]
            + (-2 * s3 + 3 * s2) * ys[i + 1]
            + (s3 - s2) * h * sl[i + 1]
        )

    return f


@dataclass
class PeerResult:
    """What the benchmark compares: wall time of the solve, transitions, extrema, work."""

    wall: float
    transitions: list[tuple[float, str]]
    peak_delta: float
    peak_force: float
    nfev: int
    segments: int
    steps: int
    extra: dict[str, Any] = field(default_factory=dict)


class _Problem:
    def __init__(self, table: ConstraintTable, spec: PassageSpec) -> None:
        self.spec = spec
        self.ck = hermite_lookup(table)
        c = spec.contact
        self.law = c.law
        self.c = c.coefficient
        self.f_y = c.yield_force
        self.d_y = c.yield_indentation if c.law.is_plastic else math.inf
        # the same switch as railtwin's: yield at δ_Y + w, unyield at δ_Y - w
        self.switch = c.switch_width if c.law.is_plastic else 0.0
        self.theta = c.johnson_coefficient
        self.m = spec.mass
        self.p = spec.load
        self.v = spec.speed
        fd = spec.foundation
        self.compliant = fd.is_compliant
        self.fm = fd.mass if self.compliant else 1.0
        self.fk = fd.stiffness if self.compliant else 0.0
        self.fc = fd.damping if self.compliant else 0.0
        self.d0 = static_indentation(c, spec.load)
        self.omega0 = math.sqrt(1.5 * self.c * math.sqrt(self.d0) / self.m)
        self.resolution = table.resolution
        self.kinks = table.kinks_between(
            spec.speed * spec.t0 - 1e-12, spec.speed * (spec.t0 + spec.duration)
        )

    def delta(self, t: float, y: NDArray[np.float64]) -> float:
        return -float(y[0]) + self.ck(self.v * t) + float(y[2])

    def force(self, d: float, mode: int) -> float:
        if mode == FLIGHT:
            return 0.0
        if mode == ELASTIC:  # odd continuation below 0: smooth up to the located loss
            return self.c * d * math.sqrt(abs(d))
        if self.law == ContactLaw.JOHNSON:
            s = max(2.0 * d / self.d_y - 1.0, 1e-300)
            return float(self.f_y * s * (1.0 + math.log(s) / (3.0 * self.theta)))
        return float(self.f_y)

    def loading_force(self, d: float) -> float:
        if d <= 0.0:
            return 0.0
        if d <= self.d_y:
            return float(self.c * d**1.5)
        return self.force(d, PLASTIC)

    def initial_state(self) -> NDArray[np.float64]:
        s = self.spec
        init = s.initial
        ym = -self.p / self.fk if self.compliant else 0.0
        y = np.array([self.ck(self.v * s.t0) + ym - self.d0, 0.0, ym, 0.0])
        if init is not None:
            y += np.array([init.y_c, init.v_c, init.y_m, init.v_m])
        return y

    def atol(self) -> NDArray[np.float64]:
        a = self.spec.rtol * self.d0
        return np.array([a, a * self.omega0, a, a * self.omega0])

    def rhs(self, mode: int) -> Callable[[float, NDArray[np.float64]], NDArray[np.float64]]:
        v, m, p, fm, fk, fc, comp = (
            self.v,
            self.m,
            self.p,
            self.fm,
            self.fk,
            self.fc,
            self.compliant,
        )
        ck = self.ck
        force = self.force

        def f(t: float, s: NDArray[np.float64]) -> NDArray[np.float64]:
            y0, y1, y2, y3 = s
            d = -y0 + ck(v * t) + y2
            fo = force(d, mode)
            am = (-fo - fk * y2 - fc * y3) / fm if comp else 0.0
            return np.array([y1, (fo - p) / m, y3, am])

        return f


def _peak_in(prob: _Problem, sol: Any, ts: NDArray[np.float64]) -> float:
    """Largest δ of one contact segment: its step ends, refined by Brent around the best."""
    ds = [prob.delta(float(t), sol(float(t))) for t in ts]
    i = int(np.argmax(ds))
    best = float(ds[i])
    lo, hi = float(ts[max(i - 1, 0)]), float(ts[min(i + 1, len(ts) - 1)])
    if hi > lo:
        r = minimize_scalar(
            lambda tt: -prob.delta(tt, sol(tt)),
            bounds=(lo, hi),
            method="bounded",
            options={"xatol": 1e-14},
        )
        best = max(best, -float(r.fun))
    return best


def solve_events(
    table: ConstraintTable,
    spec: PassageSpec,
    *,
    rtol: float | None = None,
    max_segments: int = 200_000,
    wall_limit: float = 120.0,
) -> PeerResult:
    """DOP853 with event location and a restart at every transition and kink (see module doc).

    The wall time covers the integration only; the peak indentation is refined
    afterwards from the dense output of each contact segment (not timed).
    Raises RuntimeError after ``max_segments`` restarts or ``wall_limit`` seconds.
    """
    prob = _Problem(table, spec)
    rt = spec.rtol if rtol is None else rtol
    atol = prob.atol()
    max_step = prob.resolution / prob.v
    t0, t1 = spec.t0, spec.t0 + spec.duration
    stops = [float(k) / prob.v for k in prob.kinks if t0 < float(k) / prob.v < t1] + [t1]
    y = prob.initial_state()
    d = prob.delta(t0, y)
    mode = FLIGHT if d <= 0 else (PLASTIC if d > prob.d_y else ELASTIC)
    rhs = {md: prob.rhs(md) for md in (FLIGHT, ELASTIC, PLASTIC)}

    def g_zero(t: float, s: NDArray[np.float64]) -> float:
        return prob.delta(t, s)

    def g_yield(t: float, s: NDArray[np.float64]) -> float:
        return prob.delta(t, s) - prob.d_y - prob.switch

    def g_unyield(t: float, s: NDArray[np.float64]) -> float:
        return prob.delta(t, s) - prob.d_y + prob.switch

    def events(md: int) -> list[tuple[Any, str]]:
        out: list[tuple[Any, str]] = []
        if md == FLIGHT:
            e0 = _event(g_zero, +1)
            out.append((e0, "contact"))
        elif md == ELASTIC:
            out.append((_event(g_zero, -1), "loss"))
            if prob.law.is_plastic:
                out.append((_event(g_yield, +1), "yield"))
        else:
            out.append((_event(g_unyield, -1), "unyield"))
        return out

    evs = {md: events(md) for md in (FLIGHT, ELASTIC, PLASTIC)}
    transitions: list[tuple[float, str]] = []
    segs: list[tuple[int, Any, NDArray[np.float64]]] = []
    nfev = steps = 0
    t = t0
    si = 0
    start = time.perf_counter()
    while t < t1:
        if len(segs) >= max_segments:
            raise RuntimeError(f"scipy peer: more than {max_segments} segments (chatter?)")
        if time.perf_counter() - start > wall_limit:
            raise RuntimeError(f"scipy peer: over {wall_limit:g} s wall at t = {t:.6g} s of {t1:g}")
        while stops[si] <= t:
            si += 1
        ev = evs[mode]
        sol = solve_ivp(
            rhs[mode],
            (t, stops[si]),
            y,
            method="DOP853",
            rtol=rt,
            atol=atol,
            events=[g for g, _ in ev],
            dense_output=True,
            max_step=max_step,
        )
        nfev += sol.nfev
        steps += max(len(sol.t) - 1, 0)
        if sol.status < 0:
            raise RuntimeError(f"scipy peer failed at t = {t}: {sol.message}")
        if sol.status == 1:
            hits = [(float(te[0]), j) for j, te in enumerate(sol.t_events) if te.size]
            te, j = min(hits)
            segs.append((mode, sol.sol, np.append(sol.t[sol.t < te], te)))
            y = np.asarray(sol.y_events[j][0], dtype=np.float64).copy()
            kind = ev[j][1]
            transitions.append((te, kind))
            mode = _NEXT[kind]
            t = te
        else:
            segs.append((mode, sol.sol, sol.t))
            y = sol.y[:, -1].copy()
            t = float(stops[si])
    wall = time.perf_counter() - start
    peak = 0.0
    for md, sl, ts in segs:
        if md != FLIGHT and ts.size >= 2:
            peak = max(peak, _peak_in(prob, sl, ts))
    return PeerResult(
        wall=wall,
        transitions=transitions,
        peak_delta=peak,
        peak_force=prob.loading_force(peak),
        nfev=nfev,
        segments=len(segs),
        steps=steps,
        extra={"rtol": rt, "max_step": max_step},
    )


def _event(g: Callable[[float, NDArray[np.float64]], float], direction: int) -> Any:
    def e(t: float, s: NDArray[np.float64]) -> float:
        return g(t, s)

    e.terminal = True  # type: ignore[attr-defined]
    e.direction = direction  # type: ignore[attr-defined]
    return e


def solve_plain(
    table: ConstraintTable, spec: PassageSpec, *, rtol: float | None = None
) -> PeerResult:
    """One ``solve_ivp`` call over the whole window, no events, F(max(δ, 0)) (for scale only).

    Peak force is the largest of the accepted steps' end values (not located).
    """
    prob = _Problem(table, spec)
    rt = spec.rtol if rtol is None else rtol
    v, m, p, fm, fk, fc, comp = prob.v, prob.m, prob.p, prob.fm, prob.fk, prob.fc, prob.compliant
    ck = prob.ck
    lf = prob.loading_force

    def f(t: float, s: NDArray[np.float64]) -> NDArray[np.float64]:
        y0, y1, y2, y3 = s
        fo = lf(-y0 + ck(v * t) + y2)
        am = (-fo - fk * y2 - fc * y3) / fm if comp else 0.0
        return np.array([y1, (fo - p) / m, y3, am])

    y = prob.initial_state()
    t0, t1 = spec.t0, spec.t0 + spec.duration
    start = time.perf_counter()
    sol = solve_ivp(f, (t0, t1), y, method="DOP853", rtol=rt, atol=prob.atol())
    wall = time.perf_counter() - start
    if sol.status < 0:
        raise RuntimeError(f"scipy plain solve failed: {sol.message}")
    ds = np.array([prob.delta(float(tt), sol.y[:, i]) for i, tt in enumerate(sol.t)])
    peak = float(ds.max()) if ds.size else 0.0
    return PeerResult(
        wall=wall,
        transitions=[],
        peak_delta=peak,
        peak_force=prob.loading_force(peak),
        nfev=int(sol.nfev),
        segments=1,
        steps=max(len(sol.t) - 1, 0),
        extra={"rtol": rt},
    )
