"""The one-dimensional solvers every tabulator shares: bisection, Illinois false position,
safeguarded Newton for a maximum.

Each takes the function as a compiled (numba) function and its extra arguments as one tuple
``args``, so one solver serves the ψ-search, the round wheel's closed form, the piece sweep and the
polyline sweep. They are inlined into their callers (numba cannot cache a separately
compiled solver specialised on a function argument, and then neither its callers).

Worked example: √2 as the root of x² - 2 in [1, 2], by Illinois false position and by
bisection on the sign, and the maximum of -(x - 0.3)² by Newton:

    >>> import numba
    >>> f = numba.njit(lambda x, a: x * x - a[0])
    >>> round(illinois(f, 1.0, 2.0, (2.0,)), 15)
    1.414213562373095
    >>> below = numba.njit(lambda x, a: x * x < a[0])
    >>> round(bisect(below, 1.0, 2.0, (2.0,), 0.0), 15)
    1.414213562373095
    >>> g = numba.njit(lambda x, a: (-(x - a[0]) ** 2, -2.0 * (x - a[0]), -2.0))
    >>> newton_max(g, 0.0, 1.0, (0.3,), 1e-12, 0.0, True)[0]
    0.3
"""

from __future__ import annotations

import math
from typing import Any

import numba

__all__ = ["bisect", "illinois", "illinois_bracket", "newton_max", "newton_max_from"]


@numba.njit(cache=True, inline="always")
def bisect(below: Any, lo: float, hi: float, args: Any, rtol: float) -> float:
    """The change point of the predicate ``below(x, args)`` (True left of it) in [lo, hi].

    Halves until ``hi - lo <= rtol·max(1, |lo|)`` or the midpoint no longer moves (``rtol``
    0: to the last bit), at most 200 times; returns the midpoint.
    """
    for _ in range(200):
        if hi - lo <= rtol * max(1.0, abs(lo)):
            break
        m = 0.5 * (lo + hi)
        if m <= lo or m >= hi:
            break
        if below(m, args):
            lo = m
        else:
            hi = m
    return 0.5 * (lo + hi)


@numba.njit(cache=True, inline="always")
def illinois(f: Any, xa: float, xb: float, args: Any) -> float:
    """Root of ``f(x, args)`` in [xa, xb] by Illinois false position (to ~2e-16 relative);
    nan if f has the same sign at both ends."""
    fa = f(xa, args)
    fb = f(xb, args)
    if fa == 0.0:
        return xa
    if fb == 0.0:
        return xb
    if (fa > 0.0) == (fb > 0.0):
        return math.nan
    sign = 1.0 if fb > 0.0 else -1.0
    a, b, _ = illinois_bracket(f, args, sign, xa, sign * fa, xb, sign * fb, 2e-16, 0.0, 200, True)
    return 0.5 * (a + b)


@numba.njit(cache=True, inline="always")
def illinois_bracket(
    f: Any,
    args: Any,
    sign: float,
    a: float,
    ga: float,
    b: float,
    gb: float,
    x_tol: float,
    g_tol: float,
    max_iter: int,
    stop_at_zero: bool,
) -> tuple[float, float, float]:
    """Illinois false position on g = sign·f(x, args), given g(a) = ``ga`` <= 0 < g(b) = ``gb``.

    Narrows [a, b], keeping g(a) <= 0 < g(b), until ``b - a <= x_tol·max(1, |a|)``, |g| <
    ``g_tol`` at the last point, g = 0 there exactly (if ``stop_at_zero``: then a = b = that
    point) or after ``max_iter`` evaluations. Returns (a, b, the last point evaluated, or the
    midpoint if none): b is the first point known to have g > 0 (where an event of the
    integrator is), the last point the best estimate of the zero. The one Illinois loop of
    railtwin: ``illinois`` above and the integrator's events and extrema
    (``sim_core.integrate.events.find_root``) run it.
    """
    side = 0
    m = 0.5 * (a + b)
    for _ in range(max_iter):
        if b - a <= x_tol * max(1.0, abs(a)):
            break
        m = (a * gb - b * ga) / (gb - ga) if gb != ga else 0.5 * (a + b)
        if not (a < m < b):
            m = 0.5 * (a + b)
        gm = sign * f(m, args)
        if gm > 0.0:
            b = m
            gb = gm
            if side == -1:
                ga *= 0.5
            side = -1
        elif stop_at_zero and gm == 0.0:
            return m, m, m
        else:
            a = m
            ga = gm
            if side == 1:
                gb *= 0.5
            side = 1
        if abs(gm) < g_tol:
            break
    return a, b, m


@numba.njit(cache=True, inline="always")
def newton_max(
    g: Any, lo: float, hi: float, args: Any, atol: float, rtol: float, strict: bool
) -> tuple[float, Any]:
    """(ψ, g(ψ, args)) at the maximum of a unimodal function on (lo, hi) with g' (lo) > 0 > g'(hi).

    ``g`` returns a tuple (G, G', G'', ...). Newton on G' kept inside the bracket (bisection
    where a step leaves it or G'' >= 0), at most 60 steps; it stops after the step that
    moved ψ by at most ``atol + rtol·|ψ|`` (only a Newton step, G'' < 0, if ``strict``),
    when the bracket is 4e-16 wide, or on G' = 0 exactly.
    """
    return newton_max_from(g, lo, hi, 0.5 * (lo + hi), args, atol, rtol, strict)


@numba.njit(cache=True, inline="always")
def newton_max_from(
    g: Any, lo: float, hi: float, start: float, args: Any, atol: float, rtol: float, strict: bool
) -> tuple[float, Any]:
    """:func:`newton_max` from the first iterate ``start`` (the midpoint if it is not inside (lo, hi)).

    A good start saves the steps a midpoint start spends: on a cell 1e-3 rad wide the secant of
    G' between the ends is within ~1e-7 rad of the maximum, two Newton steps from it.
    """
    a, b = lo, hi
    psi = start if lo < start < hi else 0.5 * (lo + hi)
    out = g(psi, args)
    for _ in range(60):
        gp, gpp = out[1], out[2]
        if gp > 0.0:
            a = psi
        else:
            b = psi
        nxt = psi - gp / gpp if gpp < 0.0 else 0.5 * (a + b)
        if not (a < nxt < b):
            nxt = 0.5 * (a + b)
        small = abs(nxt - psi) <= atol + rtol * abs(psi)
        done = (small and (gpp < 0.0 or not strict)) or b - a <= 4e-16
        psi = nxt
        out = g(psi, args)
        if done or out[1] == 0.0:
            break
    return psi, out
