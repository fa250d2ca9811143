"""An independent, slow reference solver for the equations of motion of MODEL.md §4.

It shares nothing with ``sim_core.integrate.loop``: SciPy's ``solve_ivp`` (DOP853 or
Radau) integrates one *mode* at a time — flight (F = 0), elastic contact (Hertz),
plastic contact (Johnson's cavity model or the Hertzian–perfectly plastic
plateau) — with terminal event functions that have a direction:

- elastic: δ falls through 0 (loss), δ rises through δ_Y (yield, plastic laws);
- flight: δ rises through 0 (return of contact);
- plastic: δ falls through δ_Y (unyield);

and restarts after each event with the other law (the classic approach). Known
non-smooth points of the constraint (kinks, C² breaks) are passed as ``breaks``
(times) and the integration is restarted there too. The constants of the
contact laws are re-derived here from MODEL.md §1/§3 (``paper_constants``,
``loading_force``, ``loading_potential``) so that a bug in
``sim_core.materials`` or ``sim_core.contact_laws`` is caught by the tests that
compare against this module.

Only the loading branch acts (MODEL.md §3: in rolling the contact point moves
on to undeformed material), so the force depends on δ alone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

FLIGHT, ELASTIC, PLASTIC = 0, 1, 2
LAWS = ("hertz", "johnson", "hertz_plastic")

# ------------------------------------------------------------------------------------
# MODEL.md §1/§3 from the page, not from sim_core
# ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Constants:
    """E*, C, δ0, f0 (linearised at P), k_lin, and F_Y, δ_Y (NaN without a yield stress)."""

    e_star: float
    c: float
    delta0: float
    f0: float
    k_lin: float
    f_y: float
    d_y: float
    theta: float


def paper_constants(
    youngs: float = 2.14e11,
    poisson: float = 0.3,
    radius: float = 0.475,
    load: float = 39240.0,
    mass: float = 400.0,
    yield_stress: float | None = None,
    theta: float = 1.1,
) -> Constants:
    """The closed forms of MODEL.md §1/§3 with E1 = E2 = E (the page's convention)."""
    e_star = 1.0 / (2.0 * (1.0 - poisson**2) / youngs)
    c = 4.0 / 3.0 * e_star * math.sqrt(radius)
    delta0 = (load / c) ** (2.0 / 3.0)
    k_lin = 1.5 * c * math.sqrt(delta0)  # dF/dδ of C·δ^1.5 at δ0
    f0 = math.sqrt(k_lin / mass) / (2.0 * math.pi)
    f_y = d_y = math.nan
    if yield_stress is not None:
        f_y = math.pi * (3.0 * math.pi / 4.0) ** 2 * (theta * yield_stress) ** 3 * radius**2
        f_y /= e_star**2
        d_y = (f_y / c) ** (2.0 / 3.0)
    return Constants(e_star, c, delta0, f0, k_lin, f_y, d_y, theta)


def loading_force(delta: float, law: str, k: Constants) -> float:
    """F(δ) of the loading branch (MODEL.md §3); 0 for δ <= 0."""
    if delta <= 0.0:
        return 0.0
    if law == "hertz" or delta <= k.d_y:
        return k.c * delta**1.5
    if law == "johnson":
        s = 2.0 * delta / k.d_y - 1.0
        return k.f_y * s * (1.0 + math.log(s) / (3.0 * k.theta))
    if law == "hertz_plastic":
        return k.f_y
    raise ValueError(f"unknown law {law!r}")


def loading_potential(delta: float, law: str, k: Constants) -> float:
    """∫_0^δ F dδ' of the loading branch, by closed form of each piece."""
    if delta <= 0.0:
        return 0.0
    if law == "hertz" or delta <= k.d_y:
        return 0.4 * k.c * delta**2.5
    e_y = 0.4 * k.c * k.d_y**2.5
    if law == "hertz_plastic":
        return e_y + k.f_y * (delta - k.d_y)
    # Johnson: substitute u = 2δ/δ_Y - 1; ∫ u(1 + ln u/(3ϑ)) du·δ_Y/2 from u = 1
    u = 2.0 * delta / k.d_y - 1.0
    a = (u * u - 1.0) / 2.0
    b = (u * u * math.log(u) / 2.0 - (u * u - 1.0) / 4.0) / (3.0 * k.theta)
    return e_y + k.f_y * k.d_y / 2.0 * (a + b)


def static_indentation(load: float, law: str, k: Constants) -> float:
    """δ with F(δ) = load on the loading branch (bisection beyond δ_Y for Johnson)."""
    d = (load / k.c) ** (2.0 / 3.0)
    if law == "hertz" or not d > k.d_y:
        return d
    if law == "hertz_plastic":
        raise ValueError("HPP cannot carry a load above F_Y")
    lo, hi = k.d_y, 2.0 * k.d_y
    while loading_force(hi, law, k) < load:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if loading_force(mid, law, k) < load else (lo, mid)
    return 0.5 * (lo + hi)


# ------------------------------------------------------------------------------------
# the problem and its solution
# ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Problem:
    """MODEL.md §4: rigid foundation if ``foundation_mass`` is 0, else (M, k, c)."""

    constraint: Callable[[float], float]
    mass: float
    load: float
    speed: float
    law: str
    constants: Constants
    foundation_mass: float = 0.0
    foundation_stiffness: float = 0.0
    foundation_damping: float = 0.0

    @property
    def compliant(self) -> bool:
        return self.foundation_mass > 0.0

    def delta(self, t: float, y: NDArray[np.float64]) -> float:
        return -float(y[0]) + self.constraint(self.speed * t) + float(y[2])

    def mode_force(self, delta: float, mode: int) -> float:
        """The force of the branch of ``mode``, continued smoothly past its switch points.

        The elastic branch is continued as the odd extension C·δ·|δ|^½ below 0 so
        that the right-hand side stays smooth up to the located loss of contact
        (the solution is used only up to that event).
        """
        k = self.constants
        if mode == FLIGHT:
            return 0.0
        if mode == ELASTIC:
            return k.c * delta * math.sqrt(abs(delta))
        if self.law == "johnson":
            s = max(2.0 * delta / k.d_y - 1.0, 1e-300)
            return k.f_y * s * (1.0 + math.log(s) / (3.0 * k.theta))
        return k.f_y

    def initial_mode(self, delta: float) -> int:
        if delta <= 0.0:
            return FLIGHT
        if self.law != "hertz" and delta > self.constants.d_y:
            return PLASTIC
        return ELASTIC

    def static_state(
        self, t0: float = 0.0, v_c: float = 0.0, y_c: float = 0.0
    ) -> NDArray[np.float64]:
        """Static equilibrium at x = V·t0 (y_M = -P/k), plus the given offsets of the wheel."""
        d0 = static_indentation(self.load, self.law, self.constants)
        ym = -self.load / self.foundation_stiffness if self.compliant else 0.0
        return np.array([self.constraint(self.speed * t0) + ym - d0 + y_c, v_c, ym, 0.0])


@dataclass
class Segment:
    t0: float
    t1: float
    mode: int
    sol: Any  # scipy OdeSolution

    def state(self, t: float) -> NDArray[np.float64]:
        out: NDArray[np.float64] = self.sol(t)
        return out


@dataclass
class Result:
    """Transitions [(t, kind)], per-sample series, and the extrema of the continuous solution."""

    transitions: list[tuple[float, str]]
    segments: list[Segment]
    t: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    y_c: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    v_c: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    y_m: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    v_m: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    delta: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    force: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    peak_delta: float = 0.0
    peak_force: float = 0.0
    nfev: int = 0

    def times(self, kind: str | None = None) -> NDArray[np.float64]:
        return np.array([t for t, k in self.transitions if kind is None or k == kind])

    @property
    def kinds(self) -> list[str]:
        return [k for _, k in self.transitions]


def _events(problem: Problem, mode: int) -> list[tuple[Callable[..., float], str]]:
    d_y = problem.constants.d_y

    def g_zero(t: float, y: NDArray[np.float64]) -> float:
        return problem.delta(t, y)

    def g_yield(t: float, y: NDArray[np.float64]) -> float:
        return problem.delta(t, y) - d_y

    out: list[tuple[Callable[..., float], str]] = []
    if mode == FLIGHT:
        g_zero.direction = 1  # type: ignore[attr-defined]
        out.append((g_zero, "contact"))
    elif mode == ELASTIC:
        g_zero.direction = -1  # type: ignore[attr-defined]
        out.append((g_zero, "loss"))
        if problem.law != "hertz":
            g_yield.direction = 1  # type: ignore[attr-defined]
            out.append((g_yield, "yield"))
    else:
        g_yield.direction = -1  # type: ignore[attr-defined]
        out.append((g_yield, "unyield"))
    for g, _ in out:
        g.terminal = True  # type: ignore[attr-defined]
    return out


_NEXT_MODE = {"contact": ELASTIC, "loss": FLIGHT, "yield": PLASTIC, "unyield": ELASTIC}


def solve(
    problem: Problem,
    y0: NDArray[np.float64],
    t0: float,
    t1: float,
    *,
    sample_t: NDArray[np.float64] | None = None,
    breaks: Sequence[float] = (),
    method: str = "DOP853",
    rtol: float = 1e-12,
    atol: float | None = None,
    max_step: float = 2e-5,
    max_segments: int = 100_000,
) -> Result:
    """Integrate from t0 to t1, restarting at every event and every time in ``breaks``.

    ``atol`` defaults to 1e-16 m (and 1e-16 m·ω0 for velocities, ω0 the linearised
    contact frequency): far below every quantity compared. ``max_step`` keeps the
    sign-change test of the events from stepping over a short contact in flight,
    where DOP853's error estimate is zero (the motion is a parabola).
    """
    k = problem.constants
    omega0 = 2.0 * math.pi * k.f0
    a_y = 1e-16 if atol is None else atol
    atol_v = np.array([a_y, a_y * omega0, a_y, a_y * omega0])
    y = np.asarray(y0, dtype=np.float64).copy()
    mode = problem.initial_mode(problem.delta(t0, y))
    stops = [*sorted(b for b in breaks if t0 < b < t1), t1]
    transitions: list[tuple[float, str]] = []
    segments: list[Segment] = []
    t = t0
    nfev = 0
    si = 0
    while t < t1:
        if len(segments) >= max_segments:
            raise RuntimeError(f"reference solver: more than {max_segments} segments (chatter?)")
        while stops[si] <= t:
            si += 1
        t_end = stops[si]
        mode_now = mode

        def rhs(tt: float, s: NDArray[np.float64], mode_now: int = mode_now) -> NDArray[np.float64]:
            d = problem.delta(tt, s)
            f = problem.mode_force(d, mode_now)
            ac = (-problem.load + f) / problem.mass
            am = 0.0
            if problem.compliant:
                am = (
                    -f - problem.foundation_stiffness * s[2] - problem.foundation_damping * s[3]
                ) / problem.foundation_mass
            return np.array([s[1], ac, s[3], am])

        evs = _events(problem, mode)
        sol = solve_ivp(
            rhs,
            (t, t_end),
            y,
            method=method,
            rtol=rtol,
            atol=atol_v,
            events=[g for g, _ in evs],
            dense_output=True,
            max_step=max_step,
        )
        nfev += sol.nfev
        if sol.status < 0:
            raise RuntimeError(f"reference solver failed at t = {t}: {sol.message}")
        if sol.status == 1:
            hits = [(float(te[0]), j) for j, te in enumerate(sol.t_events) if te.size]
            te, j = min(hits)
            segments.append(Segment(t, te, mode, sol.sol))
            y = np.asarray(sol.y_events[j][0], dtype=np.float64).copy()
            kind = evs[j][1]
            transitions.append((te, kind))
            mode = _NEXT_MODE[kind]
            t = te
        else:
            segments.append(Segment(t, t_end, mode, sol.sol))
            y = sol.y[:, -1].copy()
            t = t_end
    res = Result(transitions=transitions, segments=segments, nfev=nfev)
    _extrema(problem, res)
    if sample_t is not None:
        _sample(problem, res, np.asarray(sample_t, dtype=np.float64))
    return res


def segment_at(res: Result, t: float) -> Segment:
    """The segment covering time t (the later one at a shared end)."""
    for seg in reversed(res.segments):
        if seg.t0 <= t <= seg.t1:
            return seg
    raise ValueError(f"t = {t} outside the solution")


def state_at(res: Result, t: float) -> NDArray[np.float64]:
    return segment_at(res, t).state(t)


def _sample(problem: Problem, res: Result, ts: NDArray[np.float64]) -> None:
    n = ts.size
    out = np.empty((6, n))
    for i, tt in enumerate(ts):
        seg = segment_at(res, float(tt))
        s = seg.state(float(tt))
        d = problem.delta(float(tt), s)
        out[:4, i] = s
        out[4, i] = d
        out[5, i] = problem.mode_force(d, seg.mode) if d > 0 else 0.0
    res.t = ts
    res.y_c, res.v_c, res.y_m, res.v_m, res.delta, res.force = out


def _extrema(problem: Problem, res: Result) -> None:
    """Largest δ in contact: a fine scan of each contact segment, refined by Brent."""
    best = -math.inf
    for seg in res.segments:
        if seg.mode == FLIGHT or seg.t1 <= seg.t0:
            continue
        n = max(8, math.ceil((seg.t1 - seg.t0) / 2e-6))
        ts = np.linspace(seg.t0, seg.t1, n + 1)
        ds = np.array([problem.delta(float(tt), seg.state(float(tt))) for tt in ts])
        i = int(np.argmax(ds))
        cand = float(ds[i])
        if 0 < i < n:
            r = minimize_scalar(
                lambda tt, seg=seg: -problem.delta(tt, seg.state(tt)),
                bounds=(float(ts[i - 1]), float(ts[i + 1])),
                method="bounded",
                options={"xatol": 1e-13},
            )
            cand = max(cand, -float(r.fun))
        best = max(best, cand)
    res.peak_delta = best if best > -math.inf else 0.0
    res.peak_force = loading_force(res.peak_delta, problem.law, problem.constants)


# ------------------------------------------------------------------------------------
# analytic constraints (independent of sim_core.constraint)
# ------------------------------------------------------------------------------------


class KinkedTable(Protocol):
    """A constraint tabulated with its non-smooth points listed (``sim_core``'s table)."""

    def evaluate(self, xq: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def kinks_between(self, x0: float, x1: float) -> NDArray[np.float64]: ...

    def curvature_jumps_between(
        self, x0: float, x1: float, least: float = 0.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...


def table_constraint(table: KinkedTable) -> Callable[[float], float]:
    """y_C^k(x) read from ``table``, one point at a time (what ``Problem`` calls)."""
    return lambda x: float(table.evaluate(np.array([x]))[0])


def table_breaks(table: KinkedTable, t0: float, t1: float, speed: float) -> list[float]:
    """Times in (t0, t1] of every kink and every curvature jump of ``table`` rolled at
    ``speed``: where ``solve`` restarts."""
    x0, x1 = speed * t0, speed * t1
    jumps, _ = table.curvature_jumps_between(x0, x1, 1e-9)
    return list(np.sort(np.concatenate([table.kinks_between(x0, x1), jumps])) / speed)


def cosine_profile(amplitude: float, wavelength: float) -> Callable[[float], float]:
    """The option "the profile is the constraint": y_C^k = a·cos(2πx/λ)."""
    kw = 2.0 * math.pi / wavelength
    return lambda x: amplitude * math.cos(kw * x)


def ideal_flat_on_flat(radius: float, length: float, phase: float) -> Callable[[float], float]:
    """Exact y_C^k of an ideal flat on an even rail (MODEL.md §2), derived directly.

    With φ = φ0 + x/R wrapped to [-π, π) and θ0 = asin(l/2R): while a corner of
    the flat is the contact point (|φ| < θ0) the centre sits at R·cos(θ0 - |φ|) - R
    (the corner at angle θ0 - |φ| from the vertical, at distance R); else at 0.
    """
    th0 = math.asin(length / (2.0 * radius))

    def f(x: float) -> float:
        phi = phase + x / radius
        phi -= 2.0 * math.pi * math.floor((phi + math.pi) / (2.0 * math.pi))
        if abs(phi) >= th0:
            return 0.0
        return radius * math.cos(th0 - abs(phi)) - radius

    return f


def ideal_flat_breaks(
    radius: float, length: float, phase: float, speed: float, t0: float, t1: float
) -> list[float]:
    """Times of the kink (φ = 0) and the C² breaks (|φ| = θ0) in [t0, t1]."""
    th0 = math.asin(length / (2.0 * radius))
    out = []
    for c in (-th0, 0.0, th0):
        n0 = math.floor((phase + speed * t0 / radius - c) / (2.0 * math.pi)) - 1
        for n in range(n0, n0 + 3 + math.ceil(speed * (t1 - t0) / (2 * math.pi * radius))):
            t = ((c + 2.0 * math.pi * n) - phase) * radius / speed
            if t0 < t < t1:
                out.append(t)
    return sorted(out)
