"""What the integrator records from each accepted step: samples, extrema, dents, transitions.

All of it is read off the step's continuous solution (its dense output), not
off the step ends alone:

- samples at the requested output times (``write_samples``);
- extrema of δ and F in contact (``step_extrema``): at the step ends and where
  dδ/dt — or, with a curvature-dependent C(x), the rate of C(x)·δ^(3/2) —
  changes sign inside the step; an interior extremum of δ is located only when
  a certified bound (``interior_reach``, from |δ''| over the step,
  ``curvature_of_delta``) says it can beat a record;
- the indentation at the contact point every ``dent_dx`` of travel while the
  contact is plastic (``record_dents``), the input of ``sim_core.dents``;
- the located transitions (``push_row``).

Buffers that grow (transitions, dents) are float arrays of rows: the loop, which
allocates nothing, checks their room (``dent_rows``) and returns to be given
larger ones (``grown``).

Worked example: see ``sim_core.passage.simulate_passage``, which reads these
records into a ``PassageOutput``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import linear_at
from sim_core.integrate.dense import dense_state
from sim_core.integrate.events import curvature_of_delta, extremum_in, interior_reach
from sim_core.integrate.model import (
    constraint_at,
    delta_rate,
    force,
    force_rate,
    loading_force,
    slope_at,
)
from sim_core.integrate.types import (
    ELASTIC,
    F_FORCE_RATE,
    F_RATE,
    FLIGHT,
    S_CONTACT,
    S_DELTA,
    S_FORCE,
    S_T,
    S_VC,
    S_VM,
    S_X,
    S_YC,
    S_YCK,
    S_YM,
    X_MIN_DELTA,
    X_MIN_FORCE,
    X_PEAK_DELTA,
    X_PEAK_FORCE,
    Params,
    Table,
    as_bool,
    kernel,
)


@numba.njit(cache=True)
def grown(buf: NDArray[np.float64], n: int, extra: int) -> NDArray[np.float64]:
    """``buf`` (rows) with room for ``extra`` more rows after the first ``n``: doubled when short.

    Called between runs of the loop (``loop``), which itself allocates nothing.
    """
    if n + extra <= buf.shape[0]:
        return buf
    out = np.empty((2 * (n + extra), buf.shape[1]))
    out[:n] = buf[:n]
    return out


@numba.njit(cache=True, inline="always")
def push_row(buf: NDArray[np.float64], n: int, a: float, b: float) -> int:
    """Append the row (a, b) to a two-column buffer with room for it: the new count."""
    buf[n, 0] = a
    buf[n, 1] = b
    return n + 1


@numba.njit(cache=True, inline="always")
def _write_row(
    samples: NDArray[np.float64],
    i: int,
    ts: float,
    x: float,
    yc: float,
    vc: float,
    ym: float,
    vm: float,
    ck: float,
    d: float,
    f: float,
    mode: int,
) -> None:
    samples[i, S_T] = ts
    samples[i, S_X] = x
    samples[i, S_YC] = yc
    samples[i, S_VC] = vc
    samples[i, S_YM] = ym
    samples[i, S_VM] = vm
    samples[i, S_YCK] = ck
    samples[i, S_DELTA] = d
    samples[i, S_FORCE] = f
    samples[i, S_CONTACT] = 1.0 if mode != FLIGHT else 0.0


@kernel
def write_initial_samples(
    samples: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    t0: float,
    y: NDArray[np.float64],
    ck0: float,
    delta0: float,
    mode: int,
    par: Params,
) -> int:
    """Samples at times <= t0 (the initial state); returns how many."""
    si = 0
    while si < sample_t.size and sample_t[si] <= t0:
        si += 1
    f0 = force(delta0, mode, par, 1.0)
    for q in range(si):
        _write_row(
            samples,
            q,
            sample_t[q],
            par.speed * sample_t[q],
            y[0],
            y[1],
            y[2],
            y[3],
            ck0,
            delta0,
            f0,
            mode,
        )
    return si


@numba.njit(cache=True, inline="always")
def write_samples(
    samples: NDArray[np.float64],
    si: int,
    sample_t: NDArray[np.float64],
    tn: float,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    mode: int,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[int, int]:
    """Samples at the output times in (t, tn] from the step [t, t + h]: (next sample, hint)."""
    v = par.speed
    while si < sample_t.size and sample_t[si] <= tn:
        ts = sample_t[si]
        s = (ts - t) / h if h > 0.0 else 0.0
        yc, vc, ym, vm = dense_state(s, h, coef, par.compliant)
        ck, _, sc, hint = constraint_at(tab, v * ts, hint)
        d = -yc + ck + ym
        _write_row(samples, si, ts, v * ts, yc, vc, ym, vm, ck, d, force(d, mode, par, sc), mode)
        si += 1
    return si, hint


@numba.njit(cache=True, inline="always")
def step_extrema(
    ext: NDArray[np.float64],
    mode: int,
    t: float,
    h: float,
    y: NDArray[np.float64],
    d_b: float,
    r_b: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, float, float, int]:
    """Fold the extrema of δ and F over the contact step [t, t + h] into ``ext``.

    ``d_b``, ``r_b``: δ and dδ/dt at the step's end (left-hand slope: the end may be a
    kink), from the end's jerks (``model.jerks_and_delta``). Returns (d_b,
    r_b, the step's mean d²δ/dt², hint): what ``loop.step_toward_loss`` predicts from.

    An interior extremum of δ (dδ/dt changes sign) is located only if it can change a
    record: ``interior_reach`` bounds it from the end values, and when the bound stays
    inside the records (and, where F follows δ, inside the force records) the search
    could only return a value that ``max``/``min`` discard. The records are the same
    bits as with the search done every time.
    """
    v = par.speed
    # δ and dδ/dt at the step's start come from the state itself
    ck_a, dck_a, hint = slope_at(tab, v * t, hint)
    d_a = -y[0] + ck_a + y[2]
    r_a = -y[1] + v * dck_a + y[3]
    ext[X_PEAK_DELTA] = max(ext[X_PEAK_DELTA], d_a, d_b)
    ext[X_MIN_DELTA] = min(ext[X_MIN_DELTA], d_a, d_b)
    by_delta = tab.scale.size == 0 or mode != ELASTIC
    rising = r_a > 0.0 and r_b < 0.0
    if rising or (r_a < 0.0 and r_b > 0.0):
        # a local maximum (rising first) or minimum inside: can it beat the record?
        reach = interior_reach(d_a, d_b, h, curvature_of_delta(h, coef, par), v * (t + h))
        if rising:
            bound = max(d_a, d_b) + reach
            needed = bound > ext[X_PEAK_DELTA] or (
                by_delta and loading_force(bound, par, 1.0) > ext[X_PEAK_FORCE]
            )
        else:
            bound = min(d_a, d_b) - reach
            needed = bound < ext[X_MIN_DELTA] or (
                by_delta and loading_force(bound, par, 1.0) < ext[X_MIN_FORCE]
            )
        if needed:
            # δ is flat at the extremum, so 1e-11 s in time is far below 1e-15 m in δ
            sm, hint = extremum_in(F_RATE, r_a, r_b, t, h, coef, par, tab, 1e-16 / h, hint)
            d_m, _, hint = delta_rate(sm, t, h, coef, par, tab, hint)
            ext[X_PEAK_DELTA] = max(ext[X_PEAK_DELTA], d_m)
            ext[X_MIN_DELTA] = min(ext[X_MIN_DELTA], d_m)
            if by_delta:
                _fold_force(ext, loading_force(d_m, par, 1.0))
    if by_delta:
        # F rises with δ in every mode and σ only scales the elastic branch: the
        # extrema of F are those of δ
        _fold_force(ext, loading_force(d_a, par, 1.0))
        _fold_force(ext, loading_force(d_b, par, 1.0))
    else:
        # F = σ(x)·C·δ^(3/2): its extrema are not those of δ; locate them on q
        f_a, q_a, hint = force_rate(0.0, t, h, coef, par, tab, as_bool(False), hint)
        f_b, q_b, hint = force_rate(1.0, t, h, coef, par, tab, as_bool(True), hint)
        _fold_force(ext, f_a)
        _fold_force(ext, f_b)
        if (q_a > 0.0 and q_b < 0.0) or (q_a < 0.0 and q_b > 0.0):
            sm, hint = extremum_in(F_FORCE_RATE, q_a, q_b, t, h, coef, par, tab, 0.0, hint)
            f_m, _, hint = force_rate(sm, t, h, coef, par, tab, as_bool(False), hint)
            _fold_force(ext, f_m)
    return d_b, r_b, (r_b - r_a) / h, hint


@numba.njit(cache=True, inline="always")
def _fold_force(ext: NDArray[np.float64], f: float) -> None:
    ext[X_PEAK_FORCE] = max(ext[X_PEAK_FORCE], f)
    ext[X_MIN_FORCE] = min(ext[X_MIN_FORCE], f)


@numba.njit(cache=True, inline="always")
def dent_rows(h: float, par: Params) -> int:
    """The most rows ``record_dents`` writes for a plastic step of length ``h`` (or shorter).

    At 100 km/h with a dent every 0.1 mm, a 10 µs step: ceil(27.8·1e-5/1e-4) + 2 = 5 rows.
    """
    return math.ceil(par.speed * h / par.dent_dx) + 2


@kernel
def record_dents(
    dents: NDArray[np.float64],
    n: int,
    t: float,
    h: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[int, int]:
    """Rows (t, x_D, δ) every ``par.dent_dx`` of travel over the plastic step [t, t + h].

    ``dents`` has room for ``dent_rows(h, par)`` rows after the first ``n``; returns (n, hint).
    """
    v = par.speed
    npts = math.ceil(v * h / par.dent_dx) + 1
    for q in range(npts + 1):
        s = q / npts
        d_q, _, hint = delta_rate(s, t, h, coef, par, tab, hint)
        xd, _, shift, hint = linear_at(
            tab.x, tab.contact_x, tab.period, v * (t + s * h), hint, True
        )
        dents[n, 0] = t + s * h
        dents[n, 1] = xd + shift
        dents[n, 2] = d_q
        n += 1
    return n, hint
