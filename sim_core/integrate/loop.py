"""The loop of the compiled adaptive integrator: step-size control, breakpoints, events.

The state is (y_C, v_C, y_M, v_M); on a rigid foundation y_M ≡ v_M ≡ 0. The
right-hand side is smooth inside each *mode* — flight (F = 0), elastic contact
(Hertz), plastic contact (Johnson or the plateau F_Y) — and every switch
between modes is an *event* located to ~1e-14 s on the step's interpolant and
then reached by a fresh Runge–Kutta step that ends exactly on it, so no step
ever straddles a change of law (MODEL.md §4, §7):

- loss of contact: δ falls through 0 (elastic mode);
- return of contact: δ rises through 0 (flight);
- yield / unyield: δ crosses δ_Y (± ``ContactModel.switch_width``, MODEL.md §5).

Kinks of the constraint y_C^k (contact-point jumps) are known in advance
(``ConstraintTable.kinks``): steps in contact stop exactly on them, and restart
the jerk there. So are its *curvature jumps* (``ConstraintTable.
curvature_jumps_between``: C¹ nodes where G'' jumps, e.g. by 1/R where a rail
segment's offset line meets the arc about a vertex): a step in contact stops on
the first one it may not straddle (``stop_on_jump``: its error 0.0016·ω·V²·|ΔG''|·h³
in velocity within ``JUMP_SHARE`` of the tolerance), with no restart (the jerk is
continuous there). On a rough sampled rail that is ~3 stops per mm; the steps they
cut far below DOP853's proposal (h·ω ~ 0.01) are taken by the Dormand–Prince 5(4)
pair (the same step driven by DOPRI5's tableau: 6 new right-hand sides against 12) under its own error
estimate, falling back to DOP853 if it rejects; DOP853's proposal is kept for
when the intervals are long again.

The concerns live in small compiled functions around one short loop
(``_run``, compiled without reference counting: it allocates nothing, and
``integrate`` hands it larger buffers when it stops for room), in the manner
of diffrax:

| concern | where |
|---|---|
| inputs, outputs, codes (``Table``, ``Params``, ``Event``, ``Result``) | ``sim_core.integrate.types`` |
| the vector field, F, jerks, δ and dδ/dt on a step | ``sim_core.integrate.model`` |
| the tableaus as data (``DOP853``, ``DOPRI5``) | ``sim_core.integrate.tableau`` |
| the one step any tableau drives (``rk_step``) | ``sim_core.integrate.step`` |
| the step's size control (``attempt_step``), when DOPRI5 is taken (``short_reach``) | here |
| breakpoints: kinks and the curvature jumps a step may not straddle (``stop_on_jump``) | here, ``constraint.table`` |
| dense output: the septic Hermite interpolant | ``sim_core.integrate.dense`` |
| event detection and location (one root finder) | ``sim_core.integrate.events`` |
| samples, extrema, dents, transitions | ``sim_core.integrate.records`` |

Dense output is the septic Hermite polynomial through the positions,
velocities, accelerations and jerks at both step ends (exact for flight,
O(h⁸) in contact), whichever pair took the step. Extrema (peak and least δ
and force in contact) are taken from that continuous solution.

Worked example: ``sim_core.passage.simulate_passage`` wraps this; see there.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.integrate.dense import fill_dense
from sim_core.integrate.events import detect_in_contact, detect_in_flight
from sim_core.integrate.model import (
    constraint_at,
    delta_rate,
    jerks,
    jerks_and_delta,
    loading_force,
    mode_of,
    rhs,
    value_at_x,
)
from sim_core.integrate.records import (
    dent_rows,
    grown,
    push_row,
    record_dents,
    step_extrema,
    write_initial_samples,
    write_samples,
)
from sim_core.integrate.step import DOP853_STAGES, dop853_step, dopri5_step
from sim_core.integrate.types import (
    ELASTIC,
    EV_CONTACT,
    EV_LOSS,
    EV_YIELD,
    FLIGHT,
    LOOP_DONE,
    LOOP_NEED_DENTS,
    LOOP_NEED_TRANSITIONS,
    N_COLS,
    N_EXTREMA,
    NO_EVENT,
    OK,
    PLASTIC,
    STEP_TOO_SMALL,
    TOO_MANY_STEPS,
    X_MIN_DELTA,
    X_MIN_FORCE,
    X_PEAK_DELTA,
    X_PEAK_FORCE,
    X_T_FLIGHT,
    LoopState,
    Params,
    Result,
    Table,
    Work,
    as_int,
    kernel,
)

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
H_MIN = 1e-15
"""Shortest step (s): below it the solution is not resolvable (``STEP_TOO_SMALL``)."""
H_FIRST = 1e-6
"""First step guess (s): a fraction of the contact period."""
EVENT_OFFSET = 1e-15
"""How far (m) past a switching surface the state is put after an event."""

LOSS_AIM = 1.02
"""Aim the last step of a contact this far past the predicted loss (then redone onto it)."""

LOSS_APPROACH = 0.45
"""Before a predicted loss, a step covers at most this fraction of the time left.

F ~ δ^(3/2) is singular at δ = 0, so near a loss the error estimate allows steps
about as long as the time left, as after a landing it allows steps about as long
as the time since (the steps after a landing grow as 6, 6, 16, 27, 44, 69 µs in
Fig. 4). A step that would run past the loss is rejected, often twice; capping
it at this fraction of the predicted time left keeps every step of the approach
accepted, and the last one, within reach of a singular step, ends on the loss.
"""

SINGULAR_STEP = 0.004
"""A step touching δ = 0 (the first after a landing, the last before a loss), as a
fraction of the Hertz impact duration, at rtol = 1e-9."""

JUMP_STRADDLE = 0.0016
"""The velocity error of a step of length h over a jump J of the acceleration's second
derivative, as a multiple of J·h³: the largest over the jump's place in the step of
|Σ b_i·(c_i - s)₊²/2 - (1 - s)³/6|, 0.00160 for DOP853's weights, 0.00114 for DOPRI5's."""

JUMP_SHARE = 0.1
"""A curvature jump may be stepped over if its error is at most this share of the
tolerance: the error estimate does not see it, and several add up over a passage."""

SHORT_REACH = 0.1
"""The short pair (DOPRI5) takes only steps with h·ω below this (ω: the contact's
linearised frequency, with the foundation's mass if compliant): its local error is then
~(h·ω)⁶ ≈ 1e-6 of the motion before its constant, and far inside its stability region
(|h·λ| up to ~3), where its embedded estimate is to be trusted. The site's steps between
breakpoints (5 µs at ω = 1700 /s) have h·ω ≈ 0.01."""


_C = DOP853_STAGES.c
"""DOP853's stage times, with the end point at 1 (where a loss may be aimed short of)."""


@numba.njit(cache=True, inline="always")
def jump_allowance(par: Params) -> float:
    """The largest |ΔG''|·h³ (m²) a contact step may straddle (``JUMP_STRADDLE``, ``JUMP_SHARE``).

    A jump ΔG'' of the constraint's curvature makes δ'' jump by V²·ΔG'' and the
    acceleration's second derivative by ω²·V²·ΔG'' (ω² = F'(δ)/m); a step of length h
    over it errs in velocity by ``JUMP_STRADDLE``·ω²·V²·ΔG''·h³, which the tolerance
    (atol_v = ω·atol_y) must hold ``JUMP_SHARE`` times over. The paper's wheel at
    160 km/h, rtol 1e-8 (atol_y = 5.1e-13 m, ω = 1700 /s): 9.5e-18 s³/m, so an arc's
    end (ΔG'' = 2.17 /m) stops every step longer than 1.6 µs, a Hermite join on a
    smooth cosine (ΔG'' ~ 1e-4 /m) none shorter than 46 µs.
    """
    omega = par.atol_v / par.atol_y
    return JUMP_SHARE * par.atol_y / (JUMP_STRADDLE * omega * par.speed * par.speed)


@numba.njit(cache=True, inline="always")
def short_reach(par: Params) -> float:
    """The longest step the short pair may take (s): ``SHORT_REACH``/ω.

    ω² = F'(δ0)/m, times (1 + m/M) on a compliant foundation (the wheel and the
    foundation beat against each other across the contact). The paper's wheel on a
    rigid foundation: ω = 1700 /s, 59 µs.
    """
    omega = par.atol_v / par.atol_y
    if par.compliant:
        omega *= math.sqrt(1.0 + par.mass / par.f_mass)
    return SHORT_REACH / omega


@numba.njit(cache=True, inline="always")
def stop_on_jump(
    jumps: NDArray[np.float64],
    sizes: NDArray[np.float64],
    jp: int,
    t: float,
    h: float,
    v: float,
    allowance: float,
) -> tuple[float, int]:
    """(h, index of the jump the step now ends on, or -1): the first curvature jump in
    (t, t + h] that a step of length h may not straddle (``jump_allowance``) cuts it.

    Shortening the step only lowers the error of the jumps before the cut, so one
    pass in order is enough.
    """
    q = jp
    while q < jumps.size:
        dt = jumps[q] / v - t
        if dt > h:
            break
        if sizes[q] * h * h * h > allowance:
            return dt, q
        q += 1
    return h, -1


@kernel
def _aim_short_of_loss(factor: float, dstage: NDArray[np.float64]) -> float:
    """The shrink factor after an elastic attempt that ran past a loss of contact.

    A stage or the end with δ < 0 means the attempt crossed δ = 0, where F ~ δ^(3/2)
    stops being smooth and the error estimate explodes: aim the next attempt just
    short of the first crossing the stage values bracket, instead of shrinking blindly.
    """
    c_neg = 2.0
    for q in range(1, 13):
        if dstage[q] < 0.0 and _C[q] < c_neg:
            c_neg = _C[q]
    if c_neg > 1.0:
        return factor
    c_pos = 0.0
    d_pos = max(dstage[0], 0.0)
    d_neg = 0.0
    for q in range(1, 13):
        if _C[q] < c_neg and _C[q] > c_pos and dstage[q] > 0.0:
            c_pos = _C[q]
            d_pos = dstage[q]
        if _C[q] == c_neg:
            d_neg = dstage[q]
    c_cross = c_pos + (c_neg - c_pos) * d_pos / (d_pos - d_neg)
    return max(factor, min(0.98 * c_cross, 0.9))


@numba.njit(cache=True, inline="always")
def attempt_step(
    t: float,
    y: NDArray[np.float64],
    h: float,
    mode: int,
    w: Work,
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[int, float, float, int, int]:
    """Steps from (t, y), shrinking h until the error is accepted.

    Returns (status, h taken, its error norm, rejected attempts, hint).
    """
    n_rej = 0
    while True:
        err, hint = dop853_step(t, y, h, mode, w, par, tab, hint)
        if err <= 1.0:
            return OK, h, err, n_rej, hint
        n_rej += 1
        factor = max(MIN_FACTOR, SAFETY * err ** (-1.0 / 8.0))
        if mode == ELASTIC:
            factor = _aim_short_of_loss(factor, w.dstage)
        h *= factor
        if h < H_MIN:
            return STEP_TOO_SMALL, h, err, n_rej, hint


@kernel
def land_on_event(
    kind: int, t: float, y: NDArray[np.float64], par: Params, tab: Table, hint: int
) -> tuple[int, int]:
    """Put the state exactly on the new side of the switching surface; (new mode, hint).

    The step that reached the event carries an error of ~rtol·|y| (1e-14 m), enough
    to leave δ on the old side and fool the next scan at its very first instant.
    """
    ck, hint = value_at_x(tab, par.speed * t, hint)
    if kind == EV_LOSS:
        target = -EVENT_OFFSET
        mode = FLIGHT
    elif kind == EV_CONTACT:
        target = EVENT_OFFSET
        mode = ELASTIC
    elif kind == EV_YIELD:
        target = par.d_y + par.hyst + EVENT_OFFSET
        mode = PLASTIC
    else:
        target = par.d_y - par.hyst - EVENT_OFFSET
        mode = ELASTIC
    y[0] = ck + y[2] - target
    return mode, hint


@numba.njit(cache=True, inline="always")
def singular_step(rate: float, par: Params) -> float:
    """A step with δ = 0 at one end and |dδ/dt| = ``rate`` there, short enough for rtol.

    The Hertz impact lasts ~2.87·(m²/(C²·v))^(1/5) (Johnson, Contact Mechanics
    §11.4); ``SINGULAR_STEP`` of it at rtol = 1e-9. Near δ = 0 the force grows as
    t^(3/2), so a step's error grows as h^(7/2): h scales with rtol^(2/7). For the
    paper's wheel landing at 0.3 m/s: τ = 2.87·(400²/(1.08e11²·0.3))^(1/5) = 1.55 ms,
    a first step of 6.2 µs (Fig. 4's first steps after a landing are 6.1 and 6.2 µs).
    """
    rate = max(abs(rate), 1e-6)
    tau = 2.87 * (par.mass**2 / (par.c**2 * rate)) ** 0.2
    return SINGULAR_STEP * tau * (par.rtol / 1e-9) ** (2.0 / 7.0)


@numba.njit(cache=True, inline="always")
def time_to_loss(d: float, r: float, a: float) -> float:
    """The first τ > 0 with d + r·τ + a·τ²/2 = 0 (δ from its value, rate and curvature), or inf.

    Written as τ = 2d/(-r + √(r² - 2ad)), which has no cancellation.

        >>> round(time_to_loss(1e-6, -0.1, 0.0) * 1e6, 6), time_to_loss(1e-6, 0.1, 10.0)
        (10.0, inf)
    """
    disc = r * r - 2.0 * a * d
    if d <= 0.0:
        return 0.0
    if disc < 0.0:
        return math.inf
    den = -r + math.sqrt(disc)
    if den <= 0.0:
        return math.inf
    return 2.0 * d / den


@numba.njit(cache=True, inline="always")
def step_toward_loss(h: float, d: float, r: float, a: float, par: Params) -> float:
    """The next elastic step from the end of the last (δ = d, rate r, mean curvature a).

    At most ``LOSS_APPROACH`` of the predicted time to a loss, and once one singular
    step reaches it, a step ``LOSS_AIM`` times that time: it holds the loss, which is
    then located and the step redone onto it.
    """
    tau = time_to_loss(d, r, a)
    if tau == math.inf:
        return h
    if tau <= 1.5 * singular_step(r, par):
        return min(h, LOSS_AIM * tau)
    return min(h, LOSS_APPROACH * tau)


@kernel
def step_after_event(
    kind: int,
    h: float,
    t: float,
    t1: float,
    hstep: float,
    coef: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, int]:
    """The first step after an event (the step [t - hstep, t] ended on it); (h, hint)."""
    if kind == EV_CONTACT:
        _, rate, hint = delta_rate(1.0, t - hstep, hstep, coef, par, tab, hint)
        return min(h, singular_step(rate, par)), hint
    if kind == EV_LOSS and not par.compliant:
        # ballistic flight: the parabola is exact, the scan finds the landing
        return t1 - t, hint
    return max(h, 1e-9), hint


@kernel
def _start_derivatives(
    t: float,
    y: NDArray[np.float64],
    mode: int,
    K: NDArray[np.float64],
    par: Params,
    tab: Table,
    hint: int,
) -> tuple[float, float, int]:
    """K[0] = f(t, y) in ``mode``; returns the jerks there and the hint."""
    ac, am, _, hint = rhs(t, y[0], y[1], y[2], y[3], mode, par, tab, hint)
    K[0, 0] = y[1]
    K[0, 1] = ac
    K[0, 2] = y[3]
    K[0, 3] = am
    return jerks(t, y, am, mode, par, tab, hint, False)


@kernel
def _run(
    tab: Table,
    kinks: NDArray[np.float64],
    jumps: NDArray[np.float64],
    jump_sizes: NDArray[np.float64],
    par: Params,
    t1: float,
    y: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    max_steps: int,
    samples: NDArray[np.float64],
    trans: NDArray[np.float64],
    dents: NDArray[np.float64],
    ext: NDArray[np.float64],
    w: Work,
    st: LoopState,
) -> tuple[int, LoopState]:
    """The step loop from ``st`` to t1, or until ``trans`` or ``dents`` is full: (why, state).

    Compiled without reference counting (it allocates nothing): a call costs no atomic
    operations on the ~20 arrays it is handed, nor does each use of them in the loop.
    """
    v = par.speed
    K = w.K
    ynew = w.ynew
    coef = w.coef
    t = st.t
    h = st.h
    h_control = st.h_control
    mode = st.mode
    kp = st.kp
    jp = st.jp
    h_short = st.h_short
    allowance = jump_allowance(par)
    reach = short_reach(par)
    si = st.si
    hint = st.hint
    shint = st.sample_hint
    j0c = st.j0c
    j0m = st.j0m
    nsteps = st.steps
    nrej = st.rejected
    nrhs = st.rhs_evaluations
    n_tr = st.n_tr
    n_dent = st.n_dent
    status = st.status
    why = LOOP_DONE
    while t < t1:
        if nsteps + nrej >= max_steps:
            status = TOO_MANY_STEPS
            break
        # --- the step's size: to the end, the longest contact step, the next kink or
        # the first curvature jump it may not straddle
        hmax = t1 - t
        if mode != FLIGHT:
            hmax = min(hmax, par.hmax_contact)
        hit_kink = False
        if mode != FLIGHT and kp < kinks.size:
            tk = kinks[kp] / v
            if tk - t <= hmax:
                hmax = tk - t
                hit_kink = True
        if h >= hmax:
            h = hmax
        else:
            hit_kink = False
        jq = -1
        if mode != FLIGHT and jp < jumps.size:
            h, jq = stop_on_jump(jumps, jump_sizes, jp, t, h, v, allowance)
            if jq >= 0:
                hit_kink = False
        if h < H_MIN:
            if hit_kink:
                # already on the kink (to round-off): pass it
                kp += 1
                h = max(h, 1e-9)
                continue
            if jq >= 0:
                jp = jq + 1
                h = max(h_control, 1e-9)
                continue
            status = STEP_TOO_SMALL
            break
        # --- room for what this step may record (the step taken is at most h)
        if n_tr >= trans.shape[0]:
            why = LOOP_NEED_TRANSITIONS
            break
        if mode == PLASTIC and par.track_dents and n_dent + dent_rows(h, par) > dents.shape[0]:
            why = LOOP_NEED_DENTS
            break
        # --- the step: the short pair if a breakpoint cut DOP853's proposal to a step
        # within the short pair's reach; else DOP853 (so a passage without breakpoints
        # steps exactly as before)
        short = False
        if mode != FLIGHT:  # δ at the start, for the event scan and the loss aim
            ck, hint = value_at_x(tab, v * t, hint)
            w.dstage[0] = -y[0] + ck + y[2]
        cut = (hit_kink or jq >= 0) and h < h_control
        if mode != FLIGHT and cut and h <= h_short and h <= reach:
            err, hint = dopri5_step(t, y, h, mode, w, par, tab, hint)
            nrhs += 6
            # its own proposal, not capped in growth: the breakpoints set the steps, and
            # a step cut to a sliver between two of them must not bar the next one
            h_short = h * max(MIN_FACTOR, SAFETY * err ** (-1.0 / 5.0)) if err > 0.0 else math.inf
            if err <= 1.0:
                short = True
            else:
                nrej += 1
        if not short:
            status, h, err, n_rej, hint = attempt_step(t, y, h, mode, w, par, tab, hint)
            nrhs += 12 * (n_rej + 1)
            nrej += n_rej
            if status != OK:
                break
            factor = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / 8.0))
            if n_rej > 0:
                hit_kink = False
                jq = -1
                factor = min(1.0, factor)
            h_control = h * factor
        nsteps += 1
        j1c, j1m, d_1, r_1, hint = jerks_and_delta(
            t + h, ynew, K[12, 3], mode, par, tab, hint, True
        )
        fill_dense(coef, h, y, K[0], j0c, j0m, ynew, K[12], j1c, j1m)
        # --- events: detect, locate, and redo the step so that it ends on the first
        if mode == FLIGHT:
            ev_s, ev_kind, hint = detect_in_flight(t, h, w, par, tab, kinks, hint)
        else:
            ev_s, ev_kind, hint = detect_in_contact(mode, t, h, w, par, tab, hint)
        hstep = h
        if ev_kind != NO_EVENT:
            hit_kink = False
            jq = -1
            hstep = ev_s * h
            if hstep > H_MIN:
                # K[0] is the same start: the redone stages overwrite the rest
                _, hint = dop853_step(t, y, hstep, mode, w, par, tab, hint)
                nrhs += 12
                j1c, j1m, d_1, r_1, hint = jerks_and_delta(
                    t + hstep, ynew, K[12, 3], mode, par, tab, hint, True
                )
                fill_dense(coef, hstep, y, K[0], j0c, j0m, ynew, K[12], j1c, j1m)
            else:
                hstep = 0.0
                for j in range(4):
                    ynew[j] = y[j]
                    K[12, j] = K[0, j]
                fill_dense(coef, 1.0, y, K[0], j0c, j0m, ynew, K[12], j0c, j0m)
        tn = t + hstep
        if hit_kink:
            tn = kinks[kp] / v
        elif jq >= 0:
            tn = jumps[jq] / v
        if tn < t1 and t1 - tn < H_MIN:
            # a sliver of round-off left before the end (a step ending on a kink or an
            # event a few ulps short of t1): no step could take it, and it is nothing
            # (1e-15 s); the samples at t1 come from this step's dense output
            tn = t1
        # --- records: samples, extrema, dents
        si, shint = write_samples(samples, si, sample_t, tn, t, hstep, coef, mode, par, tab, shint)
        d_b = 0.0
        r_b = 0.0
        c_b = 0.0
        if mode == FLIGHT:
            ext[X_T_FLIGHT] += hstep
        elif hstep > 0.0:
            d_b, r_b, c_b, hint = step_extrema(
                ext, mode, t, hstep, y, d_1, r_1, coef, par, tab, hint
            )
            if mode == PLASTIC and par.track_dents:
                n_dent, hint = record_dents(dents, n_dent, t, hstep, coef, par, tab, hint)
        # --- advance
        t = tn
        for j in range(4):
            y[j] = ynew[j]
        if hit_kink:
            kp += 1
        while kp < kinks.size and kinks[kp] <= v * t + 1e-15:
            kp += 1
        if jq >= 0:
            jp = jq + 1
        while jp < jumps.size and jumps[jp] <= v * t + 1e-15:
            jp += 1
        if ev_kind != NO_EVENT:
            n_tr = push_row(trans, n_tr, t, float(ev_kind))
            mode, hint = land_on_event(ev_kind, t, y, par, tab, hint)
            if ev_kind == EV_LOSS:
                ext[X_MIN_DELTA] = min(ext[X_MIN_DELTA], 0.0)
            j0c, j0m, hint = _start_derivatives(t, y, mode, K, par, tab, hint)
            nrhs += 1
            h, hint = step_after_event(ev_kind, h, t, t1, hstep, coef, par, tab, hint)
            h_control = h
            continue
        for j in range(4):
            K[0, j] = K[12, j]
        if hit_kink:
            # the constraint's slope jumps here: the jerk does too
            j0c, j0m, hint = jerks(t, y, K[0, 3], mode, par, tab, hint, False)
        else:
            # (at a curvature jump the jerk is continuous: no restart)
            j0c = j1c
            j0m = j1m
        h = h_control
        if mode == ELASTIC and d_b > 0.0:
            h = step_toward_loss(h, d_b, r_b, c_b, par)
    out = LoopState(
        t,
        h,
        h_control,
        h_short,
        mode,
        kp,
        jp,
        si,
        hint,
        shint,
        j0c,
        j0m,
        nsteps,
        nrej,
        nrhs,
        n_tr,
        n_dent,
        status,
    )
    return why, out


@numba.njit(cache=True, nogil=True)
def integrate(
    tab: Table,
    kinks: NDArray[np.float64],
    jumps: NDArray[np.float64],
    jump_sizes: NDArray[np.float64],
    par: Params,
    t0: float,
    t1: float,
    y0: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    max_steps: int,
) -> Result:
    """Integrate one passage from t0 to t1.

    Allocates the outputs and scratch arrays, then runs the loop (``_run``), giving it
    larger transition or dent buffers whenever it stops for room.

    Args:
        tab: the constraint table (``types.table_of``).
        kinks: kink positions x (absolute, sorted) over the passage.
        jumps, jump_sizes: positions x (absolute, sorted) of the constraint's curvature
            jumps over the passage and their sizes |ΔG''| (1/m): steps in contact stop on
            those they may not straddle (``jump_allowance``).
        par: the passage's constants.
        y0: initial (y_C, v_C, y_M, v_M).
        sample_t: increasing output times in [t0, t1].
        max_steps: safety limit on accepted + rejected steps.
    """
    v = par.speed
    samples = np.zeros((sample_t.size, N_COLS))
    trans = np.empty((64, 2))
    dents = np.empty((1024, 3))
    w = Work(
        np.zeros((13, 4)),
        np.zeros(13),
        np.zeros(4),
        np.empty(4),
        np.zeros((2, 8)),
        np.empty(128),
        np.empty(128),
    )
    y = y0.copy()
    ck0, _, sc0, hint = constraint_at(tab, v * t0, 0)
    delta0 = -y[0] + ck0 + y[2]
    mode = mode_of(delta0, par)
    j0c, j0m, hint = _start_derivatives(t0, y, mode, w.K, par, tab, hint)
    ext = np.zeros(N_EXTREMA)
    ext[X_PEAK_DELTA] = delta0
    ext[X_MIN_DELTA] = delta0 if mode != FLIGHT else 0.0
    ext[X_PEAK_FORCE] = loading_force(delta0, par, sc0) if mode != FLIGHT else 0.0
    ext[X_MIN_FORCE] = ext[X_PEAK_FORCE]
    si = write_initial_samples(samples, sample_t, t0, y, ck0, delta0, mode, par)
    kp = 0
    while kp < kinks.size and kinks[kp] <= v * t0 + 1e-15:
        kp += 1
    jp = 0
    while jp < jumps.size and jumps[jp] <= v * t0 + 1e-15:
        jp += 1
    st = LoopState(
        t0, H_FIRST, H_FIRST, math.inf, mode, kp, jp, si, hint, hint, j0c, j0m, 0, 0, 1, 0, 0, OK
    )
    while True:
        why, st = _run(
            tab,
            kinks,
            jumps,
            jump_sizes,
            par,
            t1,
            y,
            sample_t,
            max_steps,
            samples,
            trans,
            dents,
            ext,
            w,
            st,
        )
        if why == LOOP_NEED_TRANSITIONS:
            trans = grown(trans, st.n_tr, as_int(1))
        elif why == LOOP_NEED_DENTS:
            dents = grown(dents, st.n_dent, dent_rows(st.h, par))
        else:
            break
    return Result(
        st.status,
        st.t,
        st.mode,
        samples,
        trans[: st.n_tr].copy(),
        ext,
        dents[: st.n_dent].copy(),
        st.steps,
        st.rejected,
        st.rhs_evaluations,
        y,
    )
