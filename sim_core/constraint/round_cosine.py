"""A round wheel on a gentle cosine rail: the offset curve in closed form, one period.

A round wheel of radius R on a rail y_r(p) = a·cos(kp) (k = 2π/λ) whose curvature never
reaches the wheel's, |a|k²R < 1, touches it at exactly one point p: the circle tangent to the
rail at p has G'' > 0 against it everywhere on its lower half (its curvature 1/R exceeds the
rail's), so it lies above the rail but at p. The wheel centre is then the rail's offset curve,
in closed form in the contact point p (s = y_r'(p), q = sqrt(1 + s²)):

    x_C(p) = p - R·s/q,    y_C^k(p) = y_r(p) + R/q - R = y_r(p) - R·s²/(q·(1 + q)),

with dx_C/dp = 1 - R·y_r''(p)/q³ > 0 (so x_C(p) is invertible) and dy_C^k/dx_C = s (the
wheel centre moves along the rail's tangent). The table is periodic (period λ, MODEL.md §2:
the round wheel turns without changing the constraint) and made on one period: nodes at
x_C(p) for p on a grid, refined where the cubic Hermite misses the closed form at an
interval's middle (value, or slope times h/8, by more than ``HERMITE_TOL``, as the
ψ-search checks at its midpoint; here at the node of the contact point halfway, where
x_C is within ~1 % of the midpoint on an interval short enough to check). No search over
ψ and no root: a sine, a cosine and a square root per node, against the ψ-search's many
evaluations of G.

Worked example (the paper's Fig. 3 geometry, |a|k²R = 0.75): a 0.475 m wheel on a = 0.1 mm,
λ = 5 cm rides the crest at +a and the trough at -a:

    >>> from sim_core.wheel import WheelOutline
    >>> from sim_core.rail import RailProfile
    >>> t = tabulate_round_cosine(WheelOutline.round(0.475), RailProfile.cosine(1e-4, 0.05), 0.0, 1e-3)
    >>> t.period, round(float(t.y.max()) / 1e-4, 12), round(float(t.y.min()) / 1e-4, 12)
    (0.05, 1.0, -1.0)
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.nodes import (
    HERMITE_TOL,
    MAX_STEPS,
    NCOL,
    SL,
    SR,
    XD,
    V,
    X,
    grow,
    interval_stack,
    next_interval,
    split,
    stretch,
    table_from_nodes,
)
from sim_core.constraint.table import ConstraintTable
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["CURVATURE_LIMIT", "supports_round_cosine", "tabulate_round_cosine"]

CURVATURE_LIMIT = 0.95
"""The closed form is taken where the rail's largest curvature |a|k² is at most this fraction
of the wheel's 1/R (beyond, the offset curve nears a cusp at the trough, and at 1 the wheel
starts to bridge the trough: the ψ-search then). The paper's cosine is at 0.75."""


def supports_round_cosine(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True for a round wheel on a cosine whose curvature stays below the wheel's (``CURVATURE_LIMIT``)."""
    if wheel.kind != "round" or rail.kind != "cosine":
        return False
    k = TWO_PI / rail.wavelength
    return abs(rail.amplitude) * k * k * wheel.nominal_radius <= CURVATURE_LIMIT


@numba.njit(cache=True, inline="always")
def _offset(a: float, k: float, R: float, p: float) -> tuple[float, float, float, float]:
    """(x_C, y_C^k, slope, dx_C/dp) of the wheel touching the rail a·cos(kp) at p."""
    c = math.cos(k * p)
    s = -a * k * math.sin(k * p)
    q = math.sqrt(1.0 + s * s)
    curv = -a * k * k * c
    return p - R * s / q, a * c - R * s * s / (q * (1.0 + q)), s, 1.0 - R * curv / (q * q * q)


@numba.njit(cache=True)
def _contact_at(a: float, k: float, R: float, x: float, pa: float, pb: float) -> float:
    """The contact point p in [pa, pb] with x_C(p) = x (x_C(pa) <= x <= x_C(pb)): Newton
    from the secant, bisection where a step leaves the bracket."""
    xa = _offset(a, k, R, pa)[0]
    xb = _offset(a, k, R, pb)[0]
    p = pa + (pb - pa) * (x - xa) / (xb - xa) if xb > xa else 0.5 * (pa + pb)
    lo, hi = pa, pb
    for _ in range(60):
        xc, _, _, d = _offset(a, k, R, p)
        f = xc - x
        if f == 0.0:
            return p
        if f > 0.0:
            hi = p
        else:
            lo = p
        nxt = p - f / d
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - p) <= 1e-15 * max(1.0, abs(p)) or hi - lo <= 4e-16 * max(1.0, abs(p)):
            return nxt
        p = nxt
    return p


@numba.njit(cache=True, inline="always")
def _hermite_at(
    ya: float, sa: float, yb: float, sb: float, h: float, t: float
) -> tuple[float, float]:
    """(value, slope) at the fraction t of an interval of length h of the cubic Hermite with
    values ya, yb and slopes sa, sb at its ends."""
    t2 = t * t
    t3 = t2 * t
    v = (2.0 * t3 - 3.0 * t2 + 1.0) * ya + (t3 - 2.0 * t2 + t) * h * sa
    v += (3.0 * t2 - 2.0 * t3) * yb + (t3 - t2) * h * sb
    d = 6.0 * (t2 - t) * (ya - yb) / h + (3.0 * t2 - 4.0 * t + 1.0) * sa + (3.0 * t2 - 2.0 * t) * sb
    return v, d


@numba.njit(cache=True)
def _put(
    nodes: NDArray[np.float64], n: int, a: float, k: float, R: float, p: float, shift: float
) -> NDArray[np.float64]:
    """Row n of ``nodes`` (grown if full): the node of contact point p, moved by ``shift``."""
    nodes = grow(nodes, n)
    xc, yc, s, _ = _offset(a, k, R, p)
    nodes[n] = 0.0
    nodes[n, X] = xc + shift
    nodes[n, V] = yc
    nodes[n, SL] = s
    nodes[n, SR] = s
    nodes[n, XD] = p + shift
    return nodes


@numba.njit(cache=True)
def round_cosine_nodes(
    a: float, lam: float, R: float, x0: float, nint: int, tol: float
) -> NDArray[np.float64]:
    """Node rows over one period [x0, x0 + λ] (sorted by x; the last is the first moved by λ).

    The grid is uniform in the contact point p from p0 (x_C(p0) = x0) over one period: node
    spacings in x_C follow dx_C/dp, finest at the trough where y_C^k is most curved.
    """
    k = TWO_PI / lam
    # p0: the contact point of x0, in the period of p around it (x_C - p is periodic, |.| <= R|s|)
    m = math.floor(x0 / lam)
    pa = m * lam - lam
    pb = m * lam + 2.0 * lam
    p0 = _contact_at(a, k, R, x0, pa, pb)
    nodes = np.empty((4 * nint + 64, NCOL))
    hp = lam / nint
    for i in range(nint):
        nodes = _put(nodes, i, a, k, R, p0 + i * hp, 0.0)
    nodes[0, X] = x0  # x_C(p0) = x0 to round-off: the table starts exactly there
    nodes = _put(nodes, nint, a, k, R, p0, lam)
    nodes[nint, X] = x0 + lam
    nn = nint + 1
    # the contact point of every node, for the bracket of the midpoint's Newton
    pc = np.empty(nodes.shape[0])
    for i in range(nint):
        pc[i] = p0 + i * hp
    pc[nint] = p0 + lam
    stack, ns = interval_stack(nn)
    for _ in range(MAX_STEPS):
        ns, ia, ib, _, xa, xb, h, _ = next_interval(stack, ns, nodes)
        if ia < 0:
            break
        # the node of the contact point halfway (x_C(p) is smooth and monotone: near the
        # interval's middle, where the Hermite's error peaks), checked there
        pm = 0.5 * (pc[ia] + pc[ib])
        xm, ym, sm, _ = _offset(a, k, R, pm)
        if not xa < xm < xb:
            continue
        hm, dm = _hermite_at(
            nodes[ia, V], nodes[ia, SR], nodes[ib, V], nodes[ib, SL], h, (xm - xa) / h
        )
        if abs(ym - hm) <= tol and 0.125 * h * abs(sm - dm) <= tol:
            continue
        nodes = _put(nodes, nn, a, k, R, pm, 0.0)
        nodes[nn, X] = xm
        if pc.size <= nn:
            grown = np.empty(nodes.shape[0])
            grown[: pc.size] = pc
            pc = grown
        pc[nn] = pm
        ic = nn
        nn += 1
        stack, ns = split(stack, ns, ia, ic, ib)
    out = nodes[:nn]
    order = np.argsort(out[:, X], kind="mergesort")
    return out[order]


def tabulate_round_cosine(
    wheel: WheelOutline,
    rail: RailProfile,
    a: float,
    b: float,
    dx: float | None = None,
    resolution: float | None = None,
) -> ConstraintTable:
    """The periodic table (one wavelength from ``a``) of a round wheel on a gentle cosine rail.

    ``dx``: the first grid's spacing in contact point (default: the resolution, λ/16 or
    finer); refinement then keeps the Hermite within ``HERMITE_TOL`` of the closed form.
    ``b`` only completes the signature of the tabulators: the table is periodic.
    """
    if not supports_round_cosine(wheel, rail):
        raise ValueError(
            f"round cosine: needs a round wheel on a cosine whose curvature |a|k² is at most "
            f"{CURVATURE_LIMIT} of 1/R, got a {wheel.kind!r} wheel on a {rail.kind!r} rail"
        )
    lam = rail.wavelength
    res = float(resolution) if resolution is not None else lam / 16.0
    step = float(dx) if dx is not None else res
    x0, _, nint = stretch(a, b, step, lam)
    nodes = round_cosine_nodes(
        rail.amplitude, lam, wheel.nominal_radius, x0, max(nint, 8), HERMITE_TOL
    )
    return table_from_nodes(nodes, lam, res, step)
