"""The compiled stepper of a wheel on the modal track: exact modes, an implicit contact, located events.

Between two step ends t and t + τ the contact force F is taken linear in time.
Then every step is exact but for that one assumption (second order in τ):

- each track mode: ζ(t + τ) = e^{λτ}·ζ + τ·(φ₁ − φ₂)(λτ)·u_a + τ·φ₂(λτ)·u_b, with u = R(x)·F
  the mode's load, φ₁(z) = (eᶻ − 1)/z and φ₂(z) = (eᶻ − 1 − z)/z²;
- the wheel: y(t + τ) = y + τ·v − P·τ²/2m + τ²·(F_a/3 + F_b/6)/m (exact for F linear in t);
- the contact: δ_b = δ* − κ·F_b is linear in the unknown end force F_b, so
  F_b = F(δ* − κ·F_b) is one monotone scalar equation, solved by safeguarded
  Newton (the loading branch of any law of MODEL.md §3).

Every mode is advanced exactly whatever its frequency, so the step is set by the
contact and the rail's features, not by the stiffest mode. A loss of contact
(δ* falling through 0 with the force released) and a return (the free δ rising
through 0) are located inside the step by Illinois false position on the step
length; the step grid also stops on every sample and every kink of the
constraint. The plastic range's entry and exit are reported where δ crosses
δ_Y ± the switch width, interpolated on the step (the force law is one monotone
function, so the step needs no restart there).

Complex numbers are kept as separate real and imaginary arrays, and the
weights (2 for a conjugate pair) are folded into the rows, so that the loops over
the modes are plain float arithmetic the compiler vectorises. The modes are
scaled so that one row R(x) is both a mode's deflection and its load
(``sim_core.track.modal``), and a step is one pass over the modes: the end force's
part of a step, τφ₂·R_b·F_b, is not added when the step is taken but when the
next one reads the state (ζ = p + b·R·F, kept as p, R, b and F). The row R at the step's
end is kept for the next step's start, and a step of the nominal length after one of the
same length folds the pending part into its coefficients:
p' = e^{λτ}·p + (e^{λτ}·b + τ(φ₁ − φ₂))·R·F (rows 6-7 of the nominal coefficients).

Worked example: ``sim_core.track.passage.simulate_on_track`` is the only caller.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import linear_at, table_eval
from sim_core.contact_laws import HERTZ, contact_force, mode_stiffness
from sim_core.integrate.types import Table

# sample columns
C_T, C_X, C_YC, C_VC, C_YCK, C_W, C_DELTA, C_FORCE, C_CONTACT, C_VW = range(10)
N_COLS = 10
# extrema
E_PEAK_FORCE, E_MIN_FORCE, E_PEAK_DELTA, E_T_FLIGHT, E_STEPS = range(5)
N_EXTREMA = 5
CO_ROWS = 8
"""Rows ``coefficients`` fills when given room for them: with 8, the merged pair too."""
WORK_ROWS = 24
"""Rows of ``run``'s work array (one column a mode): the nominal step's coefficients (8: the
six of ``coefficients`` and the merged e^{λτ}·τφ₂ + τ(φ₁ − φ₂)), a trial step's (6), the
pending τφ₂ (2), and four pairs of state (``Slots``: the modes at t and a trial's
prediction, R at t and at a trial's end)."""

RATE_BLOCK = 16
"""Samples whose ζ̇ ``run`` keeps before it adds their cribs' inertia (rows of ``rates``: two a
sample). A crib's row is then read once a block: read at every sample, the cribs' rows (27 kB
on the site case's 8 cribs) pushed the step's own rows out of the first-level cache."""

CRIB_GROUP = 4
"""Cribs a pass over the modes adds the inertia of (``Modes.crib_r`` is padded with zero rows
to a multiple of this). ``_crib_inertia``'s loop is written out for four: change both
together."""

EV_LOSS, EV_CONTACT, EV_YIELD, EV_UNYIELD = 0, 1, 2, 3
OK, TOO_MANY_STEPS, TOO_MANY_TRANSITIONS = 0, 1, 2
MODE_DTYPE = np.float32
"""The modes' state, rows and step coefficients are kept and advanced in single precision; the
wheel, the contact, the constraint and the residual stay in double. The loop over the modes is
the stepper's whole cost and is bound by its arithmetic: in single precision it runs ~2.2x faster
(twice the lanes a vector instruction).

What it costs: a mode's state is rounded to 6e-8 of itself every step, and a slow mode whose
change in one step, |λτ| of its distance from equilibrium, falls below that rounding stops
short of its equilibrium by ~6e-8/|λτ| of its amplitude. The error therefore grows as the step
shortens (measured on the site case, Hertz, against a double-precision run, force and
channels, of P): 2-4e-6 at the usual 20 µs, 1-2e-5 at 2 µs (a plastic law's dent spacing at
45 m/s), 0.4-1e-4 at 0.5 µs, 3-7e-4 at 0.1 µs, which no passage takes (the step is bounded
below by the rail table's resolution and the dent spacing over the speed). It depends on the
case too: a plastic wheel leaving dents, at 3.3 µs steps, measured ~1e-4 of P (a reviewer's
float64 build). ``tests/test_track_precision.py`` holds 20 and 0.5 µs; the track's validation
allows 2 % of P."""

EVENT_TOLERANCE = 1e-7
"""An event is located to this fraction of the longest step (2e-12 s at 20 µs). Finer is noise:
the single-precision deflection's rounding (~4e-11 m) makes the event function flat below
~1e-10 s, and a finer bracket only costs iterations (one exponential per mode each)."""

SERIES_LIMIT = 1e-3
"""Below this |λτ| the φ functions are summed as series (their closed forms cancel)."""

_NO_REFCOUNTS: dict[str, Any] = {"_nrt": False}
"""``run`` is compiled without numba's runtime: it allocates nothing (the caller passes its work
arrays), and the reference counts numba would otherwise keep on every array it reads from
the ``Modes`` and ``Table`` tuples (atomic increments and decrements, ~60 a step)
cost more than the stepping itself on a small model (measured: 8.7 -> 2.3 ms on the site
case with 4 modes; the private numba option of the pinned numba)."""

_LOOP_MATH = {"reassoc", "contract"}
"""The stepper's floating-point flags: sums over the modes may be reordered (vectorised) and
multiplies fused with adds; no assumption that values are finite (the loop compares with ±inf)."""

_kernel = numba.njit(cache=True, fastmath=_LOOP_MATH, **_NO_REFCOUNTS)
"""``run`` and the loops it calls per step or sample (``predict``, ``coefficients``,
``_rail_at``): arrays pass between them without reference counts, and as few as possible (an
array is seven or nine words of arguments: the state lives in one work array, addressed by
``Slots``). ``trial`` is inlined into ``run``; inlining the loops as well compiles 3x slower."""


class Modes(NamedTuple):
    """The modal track as the compiled stepper reads it (``ModalTrack.arrays``)."""

    lam_r: NDArray[np.floating[Any]]
    lam_i: NDArray[np.floating[Any]]
    row_r: NDArray[np.floating[Any]]
    """(rail dofs of the kept elements, modes): R, each mode's deflection and load per unit
    downward force at a dof (weights folded in). The modes' arrays are padded with inert modes
    to whole cache lines (``sim_core.track.lanes``)."""
    row_i: NDArray[np.floating[Any]]
    ex: NDArray[np.float64]
    el: NDArray[np.float64]
    ephi: NDArray[np.float64]
    resid: NDArray[np.float64]
    bubble: NDArray[np.float64]
    crib_lo: NDArray[np.float64]
    crib_hi: NDArray[np.float64]
    crib_r: NDArray[np.floating[Any]]
    """(cribs, modes): the rail's inertia between the gauges per ζ̇, weights folded in."""
    crib_i: NDArray[np.floating[Any]]


class Wheel(NamedTuple):
    """The wheel, its contact law and its speed."""

    law: int
    c: float
    f_y: float
    d_y: float
    theta: float
    hyst: float
    mass: float
    load: float
    speed: float


class Slots(NamedTuple):
    """Where the modes' state lies in the work array (row indices, each the real part's row,
    the imaginary part's the next): the modes at the last step's end t, and a trial's end.

    ζ(t) = p + b·R(x(t))·F: the last step's prediction p (``z``) without its end force, that
    step's τφ₂ b (``b``: the nominal coefficients' row 4, or ``PENDING``, a copy), R at x(t)
    (``ha``) and the force F at t. A trial writes its prediction into ``p`` and R at its end
    into ``hb``; taking the step swaps them with ``z`` and ``ha``. Rows, not arrays: the
    compiled calls per step then pass one array and a few integers (a tuple of ten arrays
    cost ~0.3 µs a step in argument copies alone)."""

    z: int
    p: int
    ha: int
    hb: int
    b: int


CO_NOMINAL = 0
"""Work rows 0-7: the nominal step's coefficients (``CO_ROWS``)."""
CO_TRIAL = CO_ROWS
"""Work rows 8-13: a trial step's coefficients (6)."""
PENDING = CO_TRIAL + 6
"""Work rows 14-15: the pending τφ₂, copied when the nominal coefficients change under it."""
FIRST_STATE = PENDING + 2
"""Work rows 16-23: the four state pairs of ``Slots`` (z, p, ha, hb)."""


EXP_RANGE = 0.5
"""|Re λτ| up to which ``coefficients`` takes e^{Re λτ} from its Taylor polynomial."""

TRIG_RANGE = 2.0
"""|Im λτ| up to which ``coefficients`` takes cos and sin from their Taylor polynomials."""

_EXP_TERMS = 17
"""Terms of e^a's polynomial on |a| ≤ ``EXP_RANGE``: the first left out, 0.5¹⁷/17!, is 2e-20."""

_TRIG_TERMS = 14
"""Terms of cos b's and sin b's polynomials in b² on |b| ≤ ``TRIG_RANGE``: the first left out,
2²⁹/29!, is 6e-23."""

_INV_EXP = tuple(1.0 / k for k in range(1, _EXP_TERMS + 1))
_INV_COS = tuple(1.0 / ((2 * k - 1) * (2 * k)) for k in range(1, _TRIG_TERMS + 1))
_INV_SIN = tuple(1.0 / ((2 * k) * (2 * k + 1)) for k in range(1, _TRIG_TERMS + 1))


@numba.njit(cache=True, inline="always")
def _exp_cos_sin(a: float, b: float) -> tuple[float, float, float]:
    """(e^a, cos b, sin b) for |a| ≤ ``EXP_RANGE``, |b| ≤ ``TRIG_RANGE``, by nested Taylor
    polynomials (1 + a/k·(…), 1 − b²/((2k−1)·2k)·(…), 1 − b²/(2k·(2k+1))·(…)): plain
    arithmetic the loop over the modes vectorises, where libm's exp, cos and sin are calls
    one mode at a time. Within 4.4e-16 (relative where above 1) of libm over the ranges
    (``tests/test_track_step_coefficients.py``); the coefficients are kept in single precision."""
    # the polynomials written out: the tuples indexed by constants are constants to the compiler
    e = 1.0 + a * _INV_EXP[16]
    e = 1.0 + a * e * _INV_EXP[15]
    e = 1.0 + a * e * _INV_EXP[14]
    e = 1.0 + a * e * _INV_EXP[13]
    e = 1.0 + a * e * _INV_EXP[12]
    e = 1.0 + a * e * _INV_EXP[11]
    e = 1.0 + a * e * _INV_EXP[10]
    e = 1.0 + a * e * _INV_EXP[9]
    e = 1.0 + a * e * _INV_EXP[8]
    e = 1.0 + a * e * _INV_EXP[7]
    e = 1.0 + a * e * _INV_EXP[6]
    e = 1.0 + a * e * _INV_EXP[5]
    e = 1.0 + a * e * _INV_EXP[4]
    e = 1.0 + a * e * _INV_EXP[3]
    e = 1.0 + a * e * _INV_EXP[2]
    e = 1.0 + a * e * _INV_EXP[1]
    e = 1.0 + a * e * _INV_EXP[0]
    b2 = b * b
    c = 1.0 - b2 * _INV_COS[13]
    sn = 1.0 - b2 * _INV_SIN[13]
    c = 1.0 - b2 * c * _INV_COS[12]
    sn = 1.0 - b2 * sn * _INV_SIN[12]
    c = 1.0 - b2 * c * _INV_COS[11]
    sn = 1.0 - b2 * sn * _INV_SIN[11]
    c = 1.0 - b2 * c * _INV_COS[10]
    sn = 1.0 - b2 * sn * _INV_SIN[10]
    c = 1.0 - b2 * c * _INV_COS[9]
    sn = 1.0 - b2 * sn * _INV_SIN[9]
    c = 1.0 - b2 * c * _INV_COS[8]
    sn = 1.0 - b2 * sn * _INV_SIN[8]
    c = 1.0 - b2 * c * _INV_COS[7]
    sn = 1.0 - b2 * sn * _INV_SIN[7]
    c = 1.0 - b2 * c * _INV_COS[6]
    sn = 1.0 - b2 * sn * _INV_SIN[6]
    c = 1.0 - b2 * c * _INV_COS[5]
    sn = 1.0 - b2 * sn * _INV_SIN[5]
    c = 1.0 - b2 * c * _INV_COS[4]
    sn = 1.0 - b2 * sn * _INV_SIN[4]
    c = 1.0 - b2 * c * _INV_COS[3]
    sn = 1.0 - b2 * sn * _INV_SIN[3]
    c = 1.0 - b2 * c * _INV_COS[2]
    sn = 1.0 - b2 * sn * _INV_SIN[2]
    c = 1.0 - b2 * c * _INV_COS[1]
    sn = 1.0 - b2 * sn * _INV_SIN[1]
    c = 1.0 - b2 * c * _INV_COS[0]
    sn = 1.0 - b2 * sn * _INV_SIN[0]
    return e, c, b * sn


@numba.njit(cache=True, inline="always")
def _write_coefficients(
    co: NDArray[Any], j: int, tau: float, a: float, b: float, er: float, ei: float, merged: bool
) -> None:
    """Column j of ``co`` (see ``coefficients``) from z = a + ib = λτ and e^z = er + i·ei."""
    r2 = a * a + b * b
    if r2 < SERIES_LIMIT * SERIES_LIMIT:
        z = complex(a, b)
        f1 = 1.0 + z * (0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z / 120.0)))
        f2 = 0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z * (1.0 / 120.0 + z / 720.0)))
        f1r, f1i, f2r, f2i = f1.real, f1.imag, f2.real, f2.imag
    else:
        inv = 1.0 / r2
        f1r = ((er - 1.0) * a + ei * b) * inv
        f1i = (ei * a - (er - 1.0) * b) * inv
        f2r = ((f1r - 1.0) * a + f1i * b) * inv
        f2i = (f1i * a - (f1r - 1.0) * b) * inv
    co[0, j] = er
    co[1, j] = ei
    co[2, j] = tau * (f1r - f2r)
    co[3, j] = tau * (f1i - f2i)
    co[4, j] = tau * f2r
    co[5, j] = tau * f2i
    if merged:
        co[6, j] = tau * (er * f2r - ei * f2i + f1r - f2r)
        co[7, j] = tau * (er * f2i + ei * f2r + f1i - f2i)


@_kernel
def coefficients(md: Modes, tau: float, co: NDArray[np.float64]) -> None:
    """Rows of ``co``: Re, Im of e^{λτ}, τ(φ₁ − φ₂)(λτ) and τ·φ₂(λτ), by series where λτ is small;
    with ``CO_ROWS`` rows, also Re, Im of e^{λτ}·τφ₂ + τ(φ₁ − φ₂) (a nominal step after one of
    the same length: its pending τφ₂ folded in).

    In real arithmetic: e^{λτ} from e^{Re λτ}, cos and sin of Im λτ; φ₁ = (e^z − 1)/z and
    φ₂ = (φ₁ − 1)/z as products with conj(z)/|z|². When every mode's λτ lies within
    ``EXP_RANGE`` and ``TRIG_RANGE`` (a 12 kHz track at 20 µs steps: |Re λτ| ≤ 0.05,
    |Im λτ| ≤ 1.51), the three come from Taylor polynomials and the loop vectorises: 18 → ~7 µs
    for the site case's 416 modes, which it calls ~50 times a passage (its events and
    stops); otherwise from libm, mode by mode."""
    merged = co.shape[0] >= CO_ROWS
    n = md.lam_r.size
    amax = 0.0
    bmax = 0.0
    for j in range(n):
        amax = max(amax, abs(md.lam_r[j] * tau))
        bmax = max(bmax, abs(md.lam_i[j] * tau))
    if amax <= EXP_RANGE and bmax <= TRIG_RANGE:
        for j in range(n):
            a = md.lam_r[j] * tau
            b = md.lam_i[j] * tau
            ea, c, sn = _exp_cos_sin(a, b)
            _write_coefficients(co, j, tau, a, b, ea * c, ea * sn, merged)
        return
    for j in range(n):
        a = md.lam_r[j] * tau
        b = md.lam_i[j] * tau
        ea = math.exp(a)
        _write_coefficients(co, j, tau, a, b, ea * math.cos(b), ea * math.sin(b), merged)


@numba.njit(cache=True, inline="always")
def element_at(x: float, ex: NDArray[np.float64], hint: int) -> int:
    n = ex.size
    i = min(max(hint, 0), n - 1)
    while i > 0 and x < ex[i]:
        i -= 1
    while i < n - 1 and x >= ex[i + 1]:
        i += 1
    return i


@numba.njit(cache=True, inline="always")
def shapes(x: float, e: int, md: Modes, n: NDArray[np.float64]) -> float:
    """The element's deflection shape functions at x into ``n``; returns ξ."""
    L = md.el[e]
    xi = min(max((x - md.ex[e]) / L, 0.0), 1.0)
    phi = md.ephi[e]
    c = 1.0 / (1.0 + phi)
    x2 = xi * xi
    x3 = x2 * xi
    n[0] = c * (1.0 - 3.0 * x2 + 2.0 * x3 + phi * (1.0 - xi))
    n[1] = c * L * (xi - 2.0 * x2 + x3 + 0.5 * phi * (xi - x2))
    n[2] = c * (3.0 * x2 - 2.0 * x3 + phi * xi)
    n[3] = c * L * (-x2 + x3 + 0.5 * phi * (x2 - xi))
    return xi


@numba.njit(cache=True, inline="always")
def residual(e: int, xi: float, n: NDArray[np.float64], md: Modes) -> float:
    """The static compliance the modes leave out at the load point (truncation and bubble)."""
    r = 0.0
    for a in range(4):
        s = 0.0
        for b in range(4):
            s += md.resid[e, a, b] * n[b]
        r += n[a] * s
    nb = md.bubble.shape[1]
    p = xi * (nb - 1)
    k = min(int(p), nb - 2)
    f = p - k
    return r + (1.0 - f) * md.bubble[e, k] + f * md.bubble[e, k + 1]


@_kernel
def predict(
    e: int,
    n: NDArray[np.float64],
    row_r: NDArray[Any],
    row_i: NDArray[Any],
    wk: NDArray[Any],
    co: int,
    sl: Slots,
    fa: float,
    merged: bool,
) -> tuple[float, float]:
    """A step's modes at its end without its end force, into the work rows ``sl.p``, and R
    there into ``sl.hb``; returns (their deflection there, its compliance Σ Re(τφ₂·R²)).

    The step starts at the state's x (R there: rows ``sl.ha``) with τφ₂ (rows ``sl.b``)
    pending and its coefficients in rows ``co``..; it ends in element ``e`` (shape functions
    ``n``). With ``merged`` (a nominal step after one of the same length: the pending τφ₂ is
    the coefficients' own row 4) the pending part comes folded into rows 6-7, a third fewer
    operations a mode."""
    d = 2 * e
    r0, r1, r2, r3 = row_r[d], row_r[d + 1], row_r[d + 2], row_r[d + 3]
    i0, i1, i2, i3 = row_i[d], row_i[d + 1], row_i[d + 2], row_i[d + 3]
    ft = wk.dtype.type
    f = ft(fa)
    n0, n1, n2, n3 = ft(n[0]), ft(n[1]), ft(n[2]), ft(n[3])
    er, ei, ar, ai, br, bi = wk[co], wk[co + 1], wk[co + 2], wk[co + 3], wk[co + 4], wk[co + 5]
    zr, zi, pr, pi = wk[sl.z], wk[sl.z + 1], wk[sl.p], wk[sl.p + 1]
    har, hai, hbr, hbi = wk[sl.ha], wk[sl.ha + 1], wk[sl.hb], wk[sl.hb + 1]
    w = ft(0.0)
    b = ft(0.0)
    two = ft(2.0)
    if merged:
        cr, ci = wk[co + 6], wk[co + 7]
        for j in range(zr.size):
            u_r = har[j] * f
            u_i = hai[j] * f
            p_r = er[j] * zr[j] - ei[j] * zi[j] + cr[j] * u_r - ci[j] * u_i
            p_i = er[j] * zi[j] + ei[j] * zr[j] + cr[j] * u_i + ci[j] * u_r
            pr[j] = p_r
            pi[j] = p_i
            h_r = n0 * r0[j] + n1 * r1[j] + n2 * r2[j] + n3 * r3[j]
            h_i = n0 * i0[j] + n1 * i1[j] + n2 * i2[j] + n3 * i3[j]
            hbr[j] = h_r
            hbi[j] = h_i
            w += h_r * p_r - h_i * p_i
            b += br[j] * (h_r * h_r - h_i * h_i) - two * bi[j] * (h_r * h_i)
        return float(w), float(b)
    lr, li = wk[sl.b], wk[sl.b + 1]
    for j in range(zr.size):
        u_r = har[j] * f
        u_i = hai[j] * f
        z_r = zr[j] + lr[j] * u_r - li[j] * u_i
        z_i = zi[j] + lr[j] * u_i + li[j] * u_r
        p_r = er[j] * z_r - ei[j] * z_i + ar[j] * u_r - ai[j] * u_i
        p_i = er[j] * z_i + ei[j] * z_r + ar[j] * u_i + ai[j] * u_r
        pr[j] = p_r
        pi[j] = p_i
        h_r = n0 * r0[j] + n1 * r1[j] + n2 * r2[j] + n3 * r3[j]
        h_i = n0 * i0[j] + n1 * i1[j] + n2 * i2[j] + n3 * i3[j]
        hbr[j] = h_r
        hbi[j] = h_i
        w += h_r * p_r - h_i * p_i
        b += br[j] * (h_r * h_r - h_i * h_i) - two * bi[j] * (h_r * h_i)
    return float(w), float(b)


@_kernel
def _fill_row(
    e: int,
    n: NDArray[np.float64],
    row_r: NDArray[Any],
    row_i: NDArray[Any],
    hr: NDArray[Any],
    hi: NDArray[Any],
) -> None:
    """R at the point of element ``e`` with shape functions ``n``, into (hr, hi)."""
    d = 2 * e
    r0, r1, r2, r3 = row_r[d], row_r[d + 1], row_r[d + 2], row_r[d + 3]
    i0, i1, i2, i3 = row_i[d], row_i[d + 1], row_i[d + 2], row_i[d + 3]
    ft = hr.dtype.type
    n0, n1, n2, n3 = ft(n[0]), ft(n[1]), ft(n[2]), ft(n[3])
    for j in range(hr.size):
        hr[j] = n0 * r0[j] + n1 * r1[j] + n2 * r2[j] + n3 * r3[j]
        hi[j] = n0 * i0[j] + n1 * i1[j] + n2 * i2[j] + n3 * i3[j]


@_kernel
def _rail_at(
    lam_r: NDArray[Any],
    lam_i: NDArray[Any],
    wk: NDArray[Any],
    sl: Slots,
    fa: float,
    out: NDArray[Any],
    row: int,
) -> tuple[float, float]:
    """The rail's deflection and velocity at the state's x (R there: rows ``sl.ha``),
    Σ Re(R·ζ) and Σ Re(R·ζ̇), with ζ = p + b·R·F; ζ̇ = λζ + R·F into the rows ``row``,
    ``row + 1`` of ``out``."""
    ft = wk.dtype.type
    f = ft(fa)
    zr, zi, dr, di = wk[sl.z], wk[sl.z + 1], out[row], out[row + 1]
    hr, hi, lr, li = wk[sl.ha], wk[sl.ha + 1], wk[sl.b], wk[sl.b + 1]
    wv = ft(0.0)
    vw = ft(0.0)
    for j in range(zr.size):
        h_r = hr[j]
        h_i = hi[j]
        u_r = h_r * f
        u_i = h_i * f
        z_r = zr[j] + lr[j] * u_r - li[j] * u_i
        z_i = zi[j] + lr[j] * u_i + li[j] * u_r
        d_r = lam_r[j] * z_r - lam_i[j] * z_i + u_r
        d_i = lam_r[j] * z_i + lam_i[j] * z_r + u_i
        dr[j] = d_r
        di[j] = d_i
        wv += h_r * z_r - h_i * z_i
        vw += h_r * d_r - h_i * d_i
    return float(wv), float(vw)


@_kernel
def _crib_inertia(
    md: Modes, rates: NDArray[Any], channels: NDArray[np.float64], first: int, count: int
) -> None:
    """Add each crib's rail inertia, Σ Re(A_i·ζ̇), to ``count`` samples of ``channels`` from
    ``first`` on, their ζ̇ in the row pairs of ``rates``: four cribs a pass over the modes
    (``Modes.crib_r`` has a multiple of four rows, zeros past the cribs)."""
    nc = md.crib_lo.size
    ar, ai = md.crib_r, md.crib_i
    ft = rates.dtype.type
    for b in range(count):
        dr, di = rates[2 * b], rates[2 * b + 1]
        for i in range(0, nc, CRIB_GROUP):
            a0r, a1r, a2r, a3r = ar[i], ar[i + 1], ar[i + 2], ar[i + 3]
            a0i, a1i, a2i, a3i = ai[i], ai[i + 1], ai[i + 2], ai[i + 3]
            s0 = ft(0.0)
            s1 = ft(0.0)
            s2 = ft(0.0)
            s3 = ft(0.0)
            for j in range(dr.size):
                d_r = dr[j]
                d_i = di[j]
                s0 += a0r[j] * d_r - a0i[j] * d_i
                s1 += a1r[j] * d_r - a1i[j] * d_i
                s2 += a2r[j] * d_r - a2i[j] * d_i
                s3 += a3r[j] * d_r - a3i[j] * d_i
            row = channels[first + b]
            row[i] += float(s0)
            if i + 1 < nc:
                row[i + 1] += float(s1)
            if i + 2 < nc:
                row[i + 2] += float(s2)
            if i + 3 < nc:
                row[i + 3] += float(s3)


@numba.njit(cache=True)
def solve_force(dstar: float, kappa: float, wh: Wheel, guess: float) -> float:
    """F ≥ 0 with F = F_law(δ* − κF): the root of an increasing function on [0, F_law(δ*)].

    Newton starts from ``guess`` (the last step's force: 2-3 iterations, against 6-8 from the
    bracket's end) when it lies inside the bracket, and falls back on bisection when a Newton
    step leaves it; the root, to 1e-13 of F, is the same whatever the start."""
    if dstar <= 0.0:
        return 0.0
    hi = contact_force(dstar, wh.law, wh.c, wh.f_y, wh.d_y, wh.theta)
    lo = 0.0
    f = guess if 0.0 < guess < hi else hi
    for _ in range(200):
        d = dstar - kappa * f
        g = f - contact_force(d, wh.law, wh.c, wh.f_y, wh.d_y, wh.theta)
        if g > 0.0:
            hi = f
        else:
            lo = f
        k = mode_stiffness(
            d, wh.law != HERTZ and d > wh.d_y, wh.law, wh.c, wh.f_y, wh.d_y, wh.theta
        )
        fn = f - g / (1.0 + kappa * k)
        # converged: tested before the bracket, which f itself has just become an end of
        # (a converged Newton step lands on it, and a bisection there would start over)
        if abs(fn - f) <= 1e-13 * max(abs(f), 1.0):
            return fn
        if not (lo < fn < hi):
            fn = 0.5 * (lo + hi)
        if hi - lo <= 1e-13 * max(hi, 1.0):
            return fn
        f = fn
    return f


@numba.njit(cache=True, inline="always")
def _wheel_at(y: float, v: float, fa: float, st: float, wh: Wheel) -> float:
    """The wheel's height after ``st`` without the step's end force."""
    return y + st * v - wh.load * st * st / (2.0 * wh.mass) + st * st * fa / (3.0 * wh.mass)


@numba.njit(cache=True, inline="always")
def trial(
    md: Modes,
    tab: Table,
    wh: Wheel,
    wk: NDArray[Any],
    co: int,
    sl: Slots,
    nsh: NDArray[np.float64],
    t: float,
    st: float,
    y: float,
    v: float,
    fa: float,
    he: int,
    ht: int,
    merged: bool,
) -> tuple[float, float, float, int, int]:
    """A step of length ``st`` (coefficients in the work rows ``co``..; see ``predict``) up to
    its end force: fills the slots ``sl.p`` and ``sl.hb``; returns (δ*, κ, the wheel's height
    without the end force, element, table hints). Inlined into ``run``: called on its own it
    took more in argument copies (~250 words a call) than in its arithmetic."""
    xb = wh.speed * (t + st)
    he = element_at(xb, md.ex, he)
    xi = shapes(xb, he, md, nsh)
    w0, bc = predict(he, nsh, md.row_r, md.row_i, wk, co, sl, fa, merged)
    ypred = _wheel_at(y, v, fa, st, wh)
    ckb, _, ht = table_eval(tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, xb, ht)
    kappa = st * st / (6.0 * wh.mass) - bc + residual(he, xi, nsh, md)
    return -ypred + ckb + w0, kappa, ypred, he, ht


@numba.njit(cache=True, inline="always")
def _end_delta(
    dstar: float, kappa: float, contact: bool, wh: Wheel, guess: float
) -> tuple[float, float]:
    """(F_b, δ_b) at a step's end: the implicit force in contact, none in flight (Newton
    started from ``guess``)."""
    if not contact or dstar <= 0.0:
        return 0.0, dstar
    f = solve_force(dstar, kappa, wh, guess)
    return f, dstar - kappa * f


@_kernel
def run(
    md: Modes,
    tab: Table,
    wh: Wheel,
    t0: float,
    h_max: float,
    stops: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    zr: NDArray[np.floating[Any]],
    zi: NDArray[np.floating[Any]],
    work: NDArray[np.floating[Any]],
    rates: NDArray[np.floating[Any]],
    shp: NDArray[np.float64],
    y0: float,
    v0: float,
    f0: float,
    track_dents: bool,
    max_steps: int,
    samples: NDArray[np.float64],
    channels: NDArray[np.float64],
    transitions: NDArray[np.float64],
    dents: NDArray[np.float64],
    extrema: NDArray[np.float64],
) -> tuple[int, int, int]:
    """Advance from t0 through every sample time; fill the outputs; return (transitions, dents)
    written and a status (OK; TOO_MANY_STEPS past ``max_steps``; TOO_MANY_TRANSITIONS when the
    transition rows are full; the outputs are then incomplete, the last samples' crib inertia
    included). ``rates`` needs two rows a sample of a block (``RATE_BLOCK``) when the model has
    cribs (at least two), ``work`` ``WORK_ROWS``; neither is checked here (compiled without
    bounds checks): ``sim_core.track.passage`` sizes them.

    Each step first tries its whole length; if the contact is lost or regained, or δ enters or
    leaves the plastic range, on the way, the event's instant is located on the step length
    (Illinois false position on the same trial step), the step ends there and the rest of it
    follows as a step of its own.
    """
    m = md.lam_r.size
    nc = md.crib_lo.size
    co_n = work[CO_NOMINAL : CO_NOMINAL + CO_ROWS]
    # the pending τφ₂: zero at t0 (ζ(t0) = p), then the last step's, read from the nominal
    # coefficients' row 4 while the last step was nominal and they have not changed since
    work[PENDING : PENDING + 2] = 0.0
    sl = Slots(FIRST_STATE, FIRST_STATE + 2, FIRST_STATE + 4, FIRST_STATE + 6, PENDING)
    for j in range(m):
        work[sl.z, j] = zr[j]
        work[sl.z + 1, j] = zi[j]
    pending_nominal = False
    nsh = shp
    tau_n = -1.0
    he = 0
    ht = 0
    plastic_law = wh.law != HERTZ
    up = wh.d_y + wh.hyst
    down = wh.d_y - wh.hyst
    v = v0
    y = y0
    fa = f0
    t = t0
    x = wh.speed * t0
    he = element_at(x, md.ex, he)
    xi = shapes(x, he, md, nsh)
    contact = fa > 0.0
    ck, _, ht = table_eval(tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, x, ht)
    _fill_row(he, nsh, md.row_r, md.row_i, work[sl.ha], work[sl.ha + 1])
    w_a, _ = _rail_at(md.lam_r, md.lam_i, work, sl, fa, work, sl.p)
    delta_a = -y + ck + w_a - residual(he, xi, nsh, md) * fa
    plastic = plastic_law and contact and delta_a > wh.d_y
    n_tr = 0
    n_dent = 0
    i_stop = 0
    i_samp = 0
    ns = sample_t.size
    n_steps = 0
    block = rates.shape[0] // 2  # samples whose ζ̇ wait for their cribs' inertia
    first = 0
    f_prev2 = -1.0
    f_prev1 = -1.0
    peak = fa
    least = fa if contact else np.inf
    peak_d = delta_a if contact else 0.0
    t_flight = 0.0
    tol_t = 1e-14 * max(1.0, abs(t0) + abs(sample_t[-1]))
    tol_event = max(tol_t, EVENT_TOLERANCE * h_max)
    while i_samp < ns:
        target = sample_t[i_samp]
        while i_stop < stops.size and stops[i_stop] <= t + tol_t:
            i_stop += 1
        if i_stop < stops.size and stops[i_stop] < target:
            target = stops[i_stop]
        span = target - t
        k_steps = 0
        tau = 0.0
        if span > tol_t:
            k_steps = math.ceil(span / h_max * (1.0 - 1e-12))
            tau = span / k_steps
            if abs(tau - tau_n) > 1e-9 * tau:
                if pending_nominal:  # keep the pending τφ₂ before the nominal row changes
                    for j in range(m):
                        work[PENDING, j] = co_n[4, j]
                        work[PENDING + 1, j] = co_n[5, j]
                    sl = Slots(sl.z, sl.p, sl.ha, sl.hb, PENDING)
                    pending_nominal = False
                coefficients(md, tau, co_n)
                tau_n = tau
        for k in range(k_steps):
            remaining = tau
            if k == k_steps - 1:
                remaining = target - t
            nominal = abs(remaining - tau_n) <= 1e-9 * tau_n
            while remaining > tol_t:
                co = CO_NOMINAL
                used_n = True
                if not nominal:
                    coefficients(md, remaining, work[CO_TRIAL : CO_TRIAL + 6])
                    co = CO_TRIAL
                    used_n = False
                st = remaining
                dstar, kappa, ypred, he, ht = trial(
                    md,
                    tab,
                    wh,
                    work,
                    co,
                    sl,
                    nsh,
                    t,
                    st,
                    y,
                    v,
                    fa,
                    he,
                    ht,
                    used_n and pending_nominal,
                )
                fb, delta_b = _end_delta(dstar, kappa, contact, wh, fa)
                # the first event on the way, as a function g of the step length rising through 0
                event = -1
                level = 0.0
                if contact and plastic_law and not plastic and delta_b > up:
                    event = EV_YIELD
                    level = up
                elif contact and plastic and delta_b < down:
                    event = EV_UNYIELD
                    level = down
                elif contact and dstar <= 0.0:
                    event = EV_LOSS
                elif (not contact) and dstar > 0.0:
                    event = EV_CONTACT
                if event >= 0:
                    # g = ±(δ − level) with the force (yield, unyield) or ±δ* without it (loss, contact)
                    sgn = 1.0 if event in (EV_YIELD, EV_CONTACT) else -1.0
                    with_force = event in (EV_YIELD, EV_UNYIELD)
                    lo = 0.0
                    hi = st
                    g_lo = min(sgn * (delta_a - level), 0.0) - 1e-300
                    g_hi = sgn * ((delta_b if with_force else dstar) - level)
                    side = 0
                    for _it in range(100):
                        s = lo - g_lo * (hi - lo) / (g_hi - g_lo)
                        if not (lo < s < hi):
                            s = 0.5 * (lo + hi)
                        coefficients(md, s, work[CO_TRIAL : CO_TRIAL + 6])
                        ds, ks, _, he, ht = trial(
                            md, tab, wh, work, CO_TRIAL, sl, nsh, t, s, y, v, fa, he, ht, False
                        )
                        if with_force:
                            _, ds = _end_delta(ds, ks, True, wh, fa)
                        gs = sgn * (ds - level)
                        if gs > 0.0:
                            hi = s
                            g_hi = gs
                            if side == 1:
                                g_lo *= 0.5
                            side = 1
                        else:
                            lo = s
                            g_lo = gs
                            if side == -1:
                                g_hi *= 0.5
                            side = -1
                        if hi - lo <= tol_event:
                            break
                    st = hi  # the event's far side: the step ends where it has happened
                    coefficients(md, st, work[CO_TRIAL : CO_TRIAL + 6])
                    dstar, kappa, ypred, he, ht = trial(
                        md, tab, wh, work, CO_TRIAL, sl, nsh, t, st, y, v, fa, he, ht, False
                    )
                    fb, delta_b = _end_delta(dstar, kappa, contact and with_force, wh, fa)
                    if not with_force:
                        delta_b = 0.0
                    co = CO_TRIAL
                    used_n = False
                # take the step: its prediction becomes the state, its τφ₂ the pending one
                sl = Slots(sl.p, sl.z, sl.hb, sl.ha, CO_NOMINAL + 4 if used_n else PENDING)
                pending_nominal = used_n
                if not used_n:
                    for j in range(m):
                        work[PENDING, j] = work[co + 4, j]
                        work[PENDING + 1, j] = work[co + 5, j]
                y = ypred + st * st * fb / (6.0 * wh.mass)
                v = v - wh.load * st / wh.mass + st * (fa + fb) / (2.0 * wh.mass)
                if not contact:
                    t_flight += st
                t_new = t + st
                if event >= 0:
                    if event in (EV_LOSS, EV_CONTACT):
                        contact = event == EV_CONTACT
                    else:
                        plastic = event == EV_YIELD
                    if n_tr >= transitions.shape[0]:
                        return n_tr, n_dent, TOO_MANY_TRANSITIONS
                    transitions[n_tr, 0] = t_new
                    transitions[n_tr, 1] = event
                    n_tr += 1
                if track_dents and contact and delta_b > wh.d_y and n_dent < dents.shape[0]:
                    cx, _, _, _ = linear_at(
                        tab.x, tab.contact_x, tab.period, wh.speed * t_new, ht, False
                    )
                    dents[n_dent, 0] = t_new
                    dents[n_dent, 1] = cx
                    dents[n_dent, 2] = delta_b
                    n_dent += 1
                # extrema: the peak through a parabola of the last three step ends
                if fb > peak:
                    peak = fb
                if 0.0 <= f_prev2 <= f_prev1 and f_prev1 > fb > 0.0:
                    den = f_prev2 - 2.0 * f_prev1 + fb
                    if den < 0.0:
                        top = f_prev1 - 0.125 * (f_prev2 - fb) ** 2 / den
                        if peak < top < 2.0 * f_prev1:
                            peak = top
                if contact and fb < least:
                    least = fb
                if delta_b > peak_d:
                    peak_d = delta_b
                f_prev2 = f_prev1
                f_prev1 = fb
                fa = fb
                delta_a = delta_b
                t = t_new
                remaining -= st
                nominal = False
                n_steps += 1
                if n_steps > max_steps:
                    return n_tr, n_dent, TOO_MANY_STEPS
        t = max(t, target)
        if t >= sample_t[i_samp] - tol_t:
            xs = wh.speed * t
            he = element_at(xs, md.ex, he)
            xi = shapes(xs, he, md, nsh)
            # the state at t (R there is the last step's end row): ζ = p + b·R·F, and the rail's
            # deflection and velocity under the wheel, Σ Re(R·ζ) and Σ Re(R·(λζ + R·F)); ζ̇ into
            # the block of ``rates`` (with cribs) for their inertia, added a block at a time
            slot = i_samp - first
            if nc > 0:
                wv, vw = _rail_at(md.lam_r, md.lam_i, work, sl, fa, rates, 2 * slot)
            else:
                wv, vw = _rail_at(md.lam_r, md.lam_i, work, sl, fa, work, sl.p)
            rr = residual(he, xi, nsh, md)
            ck, _, ht = table_eval(
                tab.x, tab.y, tab.slope_left, tab.slope_right, tab.period, xs, ht
            )
            row = samples[i_samp]
            row[C_T] = t
            row[C_X] = xs
            row[C_YC] = y
            row[C_VC] = v
            row[C_YCK] = ck
            row[C_W] = wv - rr * fa
            row[C_DELTA] = -y + ck + wv - rr * fa
            row[C_FORCE] = fa
            row[C_CONTACT] = 1.0 if contact else 0.0
            row[C_VW] = vw
            for i in range(nc):
                # the wheel's load between the gauges; half of it on a gauge (the step's midpoint:
                # a sample that falls exactly on a gauge crossing is a tie either way)
                s = 0.0
                tie = 1e-9 * (1.0 + abs(xs))
                lo = md.crib_lo[i]
                hi = md.crib_hi[i]
                if lo + tie < xs < hi - tie:
                    s = fa
                elif abs(xs - lo) <= tie or abs(xs - hi) <= tie:
                    s = 0.5 * fa
                channels[i_samp, i] = s
            i_samp += 1
            if nc > 0 and slot == block - 1:
                _crib_inertia(md, rates, channels, first, block)
                first = i_samp
    if nc > 0 and i_samp > first:
        _crib_inertia(md, rates, channels, first, i_samp - first)
    extrema[E_PEAK_FORCE] = peak
    extrema[E_MIN_FORCE] = least
    extrema[E_PEAK_DELTA] = peak_d
    extrema[E_T_FLIGHT] = t_flight
    extrema[E_STEPS] = n_steps
    return n_tr, n_dent, OK
