"""Event detection and location on a step's dense output, with one root finder.

An event (``types.Event``) is a sign change of its event function g
from <= 0 to > 0 (``event_value``). A step is first *accepted*, then its dense
output is searched for the first event in it:

- in contact the 12 stages of the step already evaluated δ; only if one of
  them, or the step's end, comes within reach of a threshold (the stage gaps
  times a bound on δ'') is the interpolant scanned (``detect_in_contact``);
- in flight on a rigid foundation the wheel centre is a parabola (steps grow
  to the end of the window, the error estimate being zero), so δ(t) is scanned
  by interval bisection with a rigorous bound on δ'' (P/m + V²·max|y_C^k''|,
  plus the foundation's acceleration): an interval is discarded only if its
  end values and the bound prove δ < 0 inside it (``detect_in_flight``).

``find_root`` locates every zero the integrator needs: the events, and the sign
changes of dδ/dt and dF/dt that are the extrema. It runs railtwin's one Illinois
loop (``sim_core.constraint.roots.illinois_bracket``, which the constraint's
``illinois`` runs too) on the step's dense output.

Worked example: see ``sim_core.integrate.loop``; ``tests/test_integrator.py``
checks the located transitions against an independent solver to 1e-7 s.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.roots import illinois_bracket
from sim_core.contact_laws import HERTZ
from sim_core.integrate.dense import end_acceleration
from sim_core.integrate.model import delta_rate, force_rate
from sim_core.integrate.types import (
    ELASTIC,
    EV_CONTACT,
    EV_LOSS,
    EV_UNYIELD,
    EV_YIELD,
    F_FORCE_RATE,
    F_RATE,
    NO_EVENT,
    Params,
    Table,
    Work,
    as_bool,
    as_int,
    kernel,
)

EVENT_TOL = 1e-14
"""Width in time (s) to which an event is bracketed."""

SCAN_POINTS = 16
"""Equal fractions of a contact step at which a threshold's event function is sampled."""


@numba.njit(cache=True, inline="always")
def event_value(kind: int, d: float, par: Params) -> float:
    """g of event ``kind`` at indentation δ = ``d``: the event is g rising through 0."""
    if kind == EV_CONTACT:
        return d
    if kind == EV_LOSS:
        return -d
    if kind == EV_YIELD:
        return d - par.d_y - par.hyst
    return par.d_y - par.hyst - d


@numba.njit(cache=True, inline="always")
def value_at(
    kind: int,
    s: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """Function ``kind`` (an event code, ``F_RATE`` or ``F_FORCE_RATE``) at fraction s of the step.

    Inlined into the scans and the root finder, which call it in loops: a call would copy
    ``Params`` and ``Table`` (~65 words) for a dense evaluation and a look-up.
    """
    if kind == F_FORCE_RATE:
        _, q, hint = force_rate(s, t, h, coef, par, tab, as_bool(False), hint)
        return q, hint
    d, r, hint = delta_rate(s, t, h, coef, par, tab, hint)
    if kind == F_RATE:
        return r, hint
    return event_value(kind, d, par), hint


@numba.njit(cache=True, inline="always")
def _value_of(
    s: float, args: tuple[int, float, float, NDArray[np.float64], Params, Table, int]
) -> float:
    """``value_at`` as the root finder's f(x, args); args = (kind, t, h, coef, par, tab, hint)."""
    kind, t, h, coef, par, tab, hint = args
    g, _ = value_at(kind, s, t, h, coef, par, tab, hint)
    return g


@kernel
def find_root(
    kind: int,
    sign: float,
    sa: float,
    ga: float,
    sb: float,
    gb: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    s_tol: float,
    g_tol: float,
    max_iter: int,
    hint: int,
) -> tuple[float, float, int]:
    """Illinois regula falsi for g = sign·f_kind with g(sa) <= 0 < g(sb), on fractions of a step.

    ``sim_core.constraint.roots.illinois_bracket`` on ``value_at``: stops when the bracket
    is at most ``s_tol`` wide, when |g| < ``g_tol`` or after ``max_iter`` evaluations.
    Returns (sb, the last point evaluated, hint): sb is the first point known to have
    g > 0 (an event's location), the last point the best estimate of the zero (an
    extremum's location). Every look-up starts from ``hint`` (the bracket lies in one step).
    """
    args = (kind, t, h, coef, par, tab, hint)
    _, sb, sm = illinois_bracket(
        _value_of, args, sign, sa, ga, sb, gb, s_tol, g_tol, max_iter, False
    )
    return sb, sm, hint


@numba.njit(cache=True, inline="always")
def locate_event(
    kind: int,
    sa: float,
    ga: float,
    sb: float,
    gb: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """The first fraction with g > 0 in (sa, sb], to ``EVENT_TOL`` in time."""
    tol = EVENT_TOL / h if h > 0 else EVENT_TOL
    s, _, hint = find_root(
        as_int(kind), 1.0, sa, ga, sb, gb, t, h, coef, par, tab, tol, 0.0, as_int(200), hint
    )
    return s, hint


@kernel
def first_crossing(
    kind: int,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    n_points: int,
    hint: int,
) -> tuple[float, int]:
    """Scan g at n_points+1 equal fractions; return (the first root or -1, hint)."""
    ga, hint = value_at(kind, 0.0, t, h, coef, par, tab, hint)
    if ga > 0.0:
        # Starting on the wrong side by round-off: treat the start as g = 0.
        ga = 0.0
    sa = 0.0
    for j in range(1, n_points + 1):
        sb = j / n_points
        gb, hint = value_at(kind, sb, t, h, coef, par, tab, hint)
        if gb > 0.0:
            return locate_event(kind, sa, ga, sb, gb, t, h, coef, par, tab, hint)
        sa = sb
        ga = gb
    return -1.0, hint


@kernel
def _flight_crossing(
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    kinks: NDArray[np.float64],
    stack_s: NDArray[np.float64],
    stack_g: NDArray[np.float64],
    s_start: float,
    hint: int,
) -> tuple[float, int]:
    """(First return of contact in the step after fraction ``s_start``, or -1; hint).

    On [sa, sb] with g = δ <= 0 at both ends and |δ''| <= D2, δ <= max(ga, gb) + D2·(Δt)²/8.
    Kinks of the constraint break the bound on δ'' and are inserted as split points.
    """
    v = par.speed
    d2 = par.load / par.mass + v * v * par.c2max
    if par.compliant:
        # the foundation's acceleration at the step's ends, from the dense coefficients
        a0m, a1m = end_acceleration(h, coef, 1)
        d2 += 2.0 * max(abs(a0m), abs(a1m)) + 1e-12
    x0 = v * (t + s_start * h)
    x1 = v * (t + h)
    lo = 0
    hi = 0
    if kinks.size > 0:
        lo = int(np.searchsorted(kinks, x0, side="right"))
        hi = int(np.searchsorted(kinks, x1, side="left"))
    min_ds = 1e-13 / h
    cap = stack_s.size
    sa = s_start
    ga, hint = value_at(EV_CONTACT, sa, t, h, coef, par, tab, hint)
    if ga > 0.0:
        ga = 0.0
    # segments between kinks, left to right; inside each, depth-first halving
    for j in range(lo, hi + 1):
        if j < hi:
            s_end = (kinks[j] / v - t) / h
            if not (sa < s_end < 1.0):
                continue
        else:
            s_end = 1.0
        n = 1
        stack_s[0] = s_end
        stack_g[0], hint = value_at(EV_CONTACT, s_end, t, h, coef, par, tab, hint)
        while n > 0:
            sb = stack_s[n - 1]
            gb = stack_g[n - 1]
            dt = (sb - sa) * h
            if gb > 0.0:
                # A crossing lies in [sa, sb] and none before sa. It is the only one if g
                # is monotone there: g'(sa) > |g''|max·Δt. Otherwise halve and look left first.
                _, rate_a, hint = delta_rate(sa, t, h, coef, par, tab, hint)
                if rate_a > d2 * dt or (sb - sa) < min_ds or n >= cap:
                    return locate_event(EV_CONTACT, sa, ga, sb, gb, t, h, coef, par, tab, hint)
            else:
                bound = max(ga, gb) + d2 * dt * dt / 8.0
                if bound < 0.0 or (sb - sa) < min_ds or n >= cap:
                    # proven free of contact (or unresolvably small): move on
                    sa = sb
                    ga = gb
                    n -= 1
                    continue
            sm = 0.5 * (sa + sb)
            stack_s[n] = sm
            stack_g[n], hint = value_at(EV_CONTACT, sm, t, h, coef, par, tab, hint)
            n += 1
    return -1.0, hint


@kernel
def detect_in_flight(
    t: float, h: float, w: Work, par: Params, tab: Table, kinks: NDArray[np.float64], hint: int
) -> tuple[float, int, int]:
    """(fraction, ``EV_CONTACT`` or ``NO_EVENT``, hint): the first landing in a flight step."""
    coef = w.coef
    s_from = 0.0
    while True:
        ev_s, hint = _flight_crossing(
            t, h, coef, par, tab, kinks, w.stack_s, w.stack_g, s_from, hint
        )
        if ev_s < 0.0:
            return -1.0, NO_EVENT, hint
        _, rate, hint = delta_rate(ev_s, t, h, coef, par, tab, hint)
        if rate > 0.0:
            return ev_s, EV_CONTACT, hint
        # a grazing touch (δ reaches 0 without rising through it): look on after it
        s_from = ev_s + max(1e-12, 1e-14 / h)
        if s_from >= 1.0:
            return -1.0, NO_EVENT, hint


@numba.njit(cache=True, inline="always")
def curvature_of_delta(h: float, coef: NDArray[np.float64], par: Params) -> float:
    """A bound on |d²δ/dt²| over a contact step of length ``h`` with dense coefficients ``coef``.

    δ = y_C^k(V·t) - y_C + y_M: the septic of each body has |p''(s)| <= Σ k(k-1)|c_k| on
    s in [0, 1] (per s², hence the 1/h²), and the constraint's Hermite pieces
    |y_C^k''| <= ``par.c2max`` between kinks (a contact step never straddles one).
    For the paper's wheel in a 5 µs step on the site's rail (V = 44 m/s, c2max ~ 2 /m):
    ~100 m/s² from the wheel and ~4 000 m/s² from the rail.
    """
    a = 0.0
    for k in range(2, 8):
        a += k * (k - 1) * abs(coef[0, k])
    if par.compliant:
        for k in range(2, 8):
            a += k * (k - 1) * abs(coef[1, k])
    v = par.speed
    return a / (h * h) + v * v * par.c2max


@numba.njit(cache=True, inline="always")
def interior_reach(d_a: float, d_b: float, h: float, m: float, x: float) -> float:
    """How far past max(d_a, d_b) (or below the min) δ can reach inside a step, with |δ''| <= m.

    At an interior extremum t* of δ (δ'(t*) = 0), |δ'(t)| <= m·|t - t*|, so δ(t*) is
    within m·t*²/2 of δ(0) and m·(h - t*)²/2 of δ(h): at most m·h²/8 beyond the larger
    end value (below the smaller, for a minimum). Plus a margin for what the end values
    do not see exactly: the step's end is read 1e-13·max(1, |x|) before x (``before``:
    at most 1e-12·max(1, |x|) in δ for a constraint slope up to 10), and round-off of
    the dense sums (1e-9 relative).

    A 5 µs step on the site's rail (|δ''| <= 4 000 m/s², δ = 0.1 mm at both ends):

        >>> round(interior_reach(1e-4, 1e-4, 5e-6, 4e3, 1.0) * 1e9, 4)  # nm: 12.5 of curvature
        12.5011
    """
    return m * h * h / 8.0 + 1e-12 * max(1.0, abs(x)) + 1e-9 * max(abs(d_a), abs(d_b))


@numba.njit(cache=True, inline="always")
def detect_in_contact(
    mode: int, t: float, h: float, w: Work, par: Params, tab: Table, hint: int
) -> tuple[float, int, int]:
    """(fraction, event code or ``NO_EVENT``, hint): the first switch in a contact step.

    Elastic: loss of contact, or yield for a plastic law; plastic: unyield. A
    loss where δ does not fall (a grazing touch of 0) is not an event. Expects
    ``w.dstage[0]`` and ``w.dstage[12]``, δ at the step's start and end, and ``w.coef``,
    the step's dense output.
    """
    coef = w.coef
    dstage = w.dstage
    # δ at the step's ends and how far past them it can reach inside (certified:
    # ``interior_reach`` from a bound on |δ''| over the step): scan only if that
    # reaches a switching surface.
    d_a = dstage[0]
    d_b = dstage[12]
    reach = interior_reach(d_a, d_b, h, curvature_of_delta(h, coef, par), par.speed * (t + h))
    dmin = min(d_a, d_b) - reach
    dmax = max(d_a, d_b) + reach
    ev_s = -1.0
    ev_kind = NO_EVENT
    if mode == ELASTIC:
        if dmin <= 0.0:
            s_l, hint = first_crossing(
                as_int(EV_LOSS), t, h, coef, par, tab, as_int(SCAN_POINTS), hint
            )
            if s_l >= 0.0:
                ev_s = s_l
                ev_kind = EV_LOSS
        if par.law != HERTZ and dmax > par.d_y:
            s_y, hint = first_crossing(
                as_int(EV_YIELD), t, h, coef, par, tab, as_int(SCAN_POINTS), hint
            )
            if s_y >= 0.0 and (ev_s < 0.0 or s_y < ev_s):
                ev_s = s_y
                ev_kind = EV_YIELD
    elif dmin < par.d_y:
        s_u, hint = first_crossing(
            as_int(EV_UNYIELD), t, h, coef, par, tab, as_int(SCAN_POINTS), hint
        )
        if s_u >= 0.0:
            ev_s = s_u
            ev_kind = EV_UNYIELD
    if ev_kind == EV_LOSS:
        # grazing test: δ must be falling at the root
        _, rate, hint = delta_rate(ev_s, t, h, coef, par, tab, hint)
        if rate >= 0.0:
            ev_kind = NO_EVENT
    return ev_s, ev_kind, hint


@numba.njit(cache=True, inline="always")
def extremum_in(
    kind: int,
    fa: float,
    fb: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    g_tol: float,
    hint: int,
) -> tuple[float, int]:
    """Where f_kind (``F_RATE`` or ``F_FORCE_RATE``), of signs fa at s = 0 and fb at s = 1, vanishes.

    To 1e-11 s in time: the extremum is flat there, so its value is exact to far below round-off.
    """
    sign = -1.0 if fa > 0.0 else 1.0
    _, sm, hint = find_root(
        as_int(kind),
        sign,
        0.0,
        sign * fa,
        1.0,
        sign * fb,
        t,
        h,
        coef,
        par,
        tab,
        1e-11 / h,
        g_tol,
        as_int(60),
        hint,
    )
    return sm, hint
