"""The compiled stepper of a wheel on the modal track: exact modes, an implicit contact, located events.

Between two step ends t and t + τ the contact force F is taken linear in time.
Then every step is exact but for that one assumption (second order in τ):

- each track mode: ζ(t + τ) = e^{λτ}·ζ + τ·φ₁(λτ)·u_a + τ·φ₂(λτ)·(u_b − u_a), with u = g(x)·F
  the mode's load and φ₁(z) = (eᶻ − 1)/z, φ₂(z) = (eᶻ − 1 − z)/z²;
- the wheel: y(t + τ) = y + τ·v − P·τ²/2m + τ²·(F_a/6 + F_b/3)/m;
- the contact: δ_b = δ* − κ·F_b, linear in the unknown end force F_b, so
  F_b = F(δ* − κ·F_b) is one monotone scalar equation, solved by safeguarded
  Newton (the force of any law of MODEL.md §3 on its loading branch).

Every mode is advanced exactly, whatever its frequency, so the step is set by
the contact and the rail's features, not by the stiffest mode. Losses and
returns of contact (δ through 0) and the plastic range's entry and exit
(δ through δ_Y ± the switch width) are located inside the step by a root finder
on the step length (Illinois false position), each a restart point; the step
grid also stops on every sample and every kink of the constraint.

Worked example: ``sim_core.track.passage.simulate_on_track`` is the only caller.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import linear_at, table_eval
from sim_core.contact_laws import HERTZ, contact_force, mode_stiffness

# sample columns
C_T, C_X, C_YC, C_VC, C_YCK, C_W, C_DELTA, C_FORCE, C_CONTACT, C_VW = range(10)
N_COLS = 10
# extrema
E_PEAK_FORCE, E_MIN_FORCE, E_PEAK_DELTA, E_T_FLIGHT, E_STEPS, E_EVENTS = range(6)

EV_LOSS, EV_CONTACT, EV_YIELD, EV_UNYIELD = 0, 1, 2, 3
SERIES_LIMIT = 1e-3


@numba.njit(cache=True)
def _coefficients(
    lam: NDArray[np.complex128],
    tau: float,
    e: NDArray[np.complex128],
    p1m2: NDArray[np.complex128],
    p2: NDArray[np.complex128],
) -> None:
    """e^{λτ}, τ(φ₁ − φ₂) and τ·φ₂ of every mode, by series where λτ is small."""
    for j in range(lam.size):
        z = lam[j] * tau
        ez = np.exp(z)
        if abs(z) < SERIES_LIMIT:
            f1 = 1.0 + z * (0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z / 120.0)))
            f2 = 0.5 + z * (1.0 / 6.0 + z * (1.0 / 24.0 + z * (1.0 / 120.0 + z / 720.0)))
        else:
            f1 = (ez - 1.0) / z
            f2 = (ez - 1.0 - z) / (z * z)
        e[j] = ez
        p1m2[j] = tau * (f1 - f2)
        p2[j] = tau * f2


@numba.njit(cache=True, inline="always")
def _element(x: float, ex: NDArray[np.float64], hint: int) -> int:
    n = ex.size
    i = min(max(hint, 0), n - 1)
    while i > 0 and x < ex[i]:
        i -= 1
    while i < n - 1 and x >= ex[i + 1]:
        i += 1
    return i


@numba.njit(cache=True)
def _shapes(
    x: float,
    e: int,
    ex: NDArray[np.float64],
    el: NDArray[np.float64],
    ephi: NDArray[np.float64],
    n: NDArray[np.float64],
) -> float:
    """The element's deflection shape functions at x into ``n``; returns ξ."""
    L = el[e]
    xi = (x - ex[e]) / L
    if xi < 0.0:
        xi = 0.0
    elif xi > 1.0:
        xi = 1.0
    phi = ephi[e]
    c = 1.0 / (1.0 + phi)
    x2 = xi * xi
    x3 = x2 * xi
    n[0] = c * (1.0 - 3.0 * x2 + 2.0 * x3 + phi * (1.0 - xi))
    n[1] = c * L * (xi - 2.0 * x2 + x3 + 0.5 * phi * (xi - x2))
    n[2] = c * (3.0 * x2 - 2.0 * x3 + phi * xi)
    n[3] = c * L * (-x2 + x3 + 0.5 * phi * (x2 - xi))
    return xi


@numba.njit(cache=True)
def _residual(
    e: int,
    xi: float,
    n: NDArray[np.float64],
    resid: NDArray[np.float64],
    bubble: NDArray[np.float64],
) -> float:
    r = 0.0
    for a in range(4):
        s = 0.0
        for b in range(4):
            s += resid[e, a, b] * n[b]
        r += n[a] * s
    nb = bubble.shape[1]
    p = xi * (nb - 1)
    k = min(int(p), nb - 2)
    f = p - k
    return r + (1.0 - f) * bubble[e, k] + f * bubble[e, k + 1]


@numba.njit(cache=True)
def _interp_modes(
    e: int, n: NDArray[np.float64], coef: NDArray[np.complex128], out: NDArray[np.complex128]
) -> None:
    d = 2 * e
    m = out.size
    for j in range(m):
        out[j] = (
            n[0] * coef[d, j]
            + n[1] * coef[d + 1, j]
            + n[2] * coef[d + 2, j]
            + n[3] * coef[d + 3, j]
        )


@numba.njit(cache=True)
def _solve_force(
    dstar: float, kappa: float, law: int, c: float, f_y: float, d_y: float, theta: float
) -> float:
    """F ≥ 0 with F = F_law(δ* − κF): the root of an increasing function on [0, F_law(δ*)]."""
    if dstar <= 0.0:
        return 0.0
    hi = contact_force(dstar, law, c, f_y, d_y, theta)
    lo = 0.0
    # start from the linearised guess
    f = hi
    for _ in range(100):
        d = dstar - kappa * f
        g = f - contact_force(d, law, c, f_y, d_y, theta)
        if g > 0.0:
            hi = f
        else:
            lo = f
        k = mode_stiffness(d, law != HERTZ and d > d_y, law, c, f_y, d_y, theta)
        dg = 1.0 + kappa * k
        fn = f - g / dg
        if not (lo < fn < hi):
            fn = 0.5 * (lo + hi)
        if abs(fn - f) <= 1e-13 * max(abs(f), 1.0) or hi - lo <= 1e-13 * max(hi, 1.0):
            return fn
        f = fn
    return f


@numba.njit(cache=True)
def run(
    # the track
    lam: NDArray[np.complex128],
    weight: NDArray[np.float64],
    out_w: NDArray[np.complex128],
    inp: NDArray[np.complex128],
    ex: NDArray[np.float64],
    el: NDArray[np.float64],
    ephi: NDArray[np.float64],
    resid: NDArray[np.float64],
    bubble: NDArray[np.float64],
    crib_lo: NDArray[np.float64],
    crib_hi: NDArray[np.float64],
    crib_rows: NDArray[np.complex128],
    # the constraint table
    tx: NDArray[np.float64],
    ty: NDArray[np.float64],
    tsl: NDArray[np.float64],
    tsr: NDArray[np.float64],
    tcx: NDArray[np.float64],
    tperiod: float,
    # the wheel and contact
    law: int,
    cc: float,
    f_y: float,
    d_y: float,
    theta: float,
    hyst: float,
    mass: float,
    load: float,
    speed: float,
    # time
    t0: float,
    t1: float,
    h_max: float,
    stops: NDArray[np.float64],
    sample_t: NDArray[np.float64],
    # initial state
    zeta: NDArray[np.complex128],
    y0: float,
    v0: float,
    f0: float,
    track_dents: bool,
    # outputs
    samples: NDArray[np.float64],
    channels: NDArray[np.float64],
    transitions: NDArray[np.float64],
    dents: NDArray[np.float64],
    extrema: NDArray[np.float64],
) -> tuple[int, int]:
    """Advance from t0 to t1; fill the outputs; return (transitions, dent records) written."""
    m = lam.size
    nc = crib_lo.size
    e_n = np.empty(m, np.complex128)
    a_n = np.empty(m, np.complex128)
    b_n = np.empty(m, np.complex128)
    e_t = np.empty(m, np.complex128)
    a_t = np.empty(m, np.complex128)
    b_t = np.empty(m, np.complex128)
    hb = np.empty(m, np.complex128)
    gb = np.empty(m, np.complex128)
    ua = np.empty(m, np.complex128)
    zp = np.empty(m, np.complex128)
    nsh = np.empty(4)
    tau_n = -1.0
    hint_e = 0
    hint_t = 0

    y = y0
    v = v0
    fa = f0
    t = t0
    # the load on the modes at the start
    xe = speed * t0
    hint_e = _element(xe, ex, hint_e)
    _shapes(xe, hint_e, ex, el, ephi, nsh)
    _interp_modes(hint_e, nsh, inp, gb)
    for j in range(m):
        ua[j] = gb[j] * fa
    contact = fa > 0.0
    ck0, _, hint_t = table_eval(tx, ty, tsl, tsr, tperiod, xe, hint_t)
    plastic = law != HERTZ and False
    n_tr = 0
    n_dent = 0
    i_stop = 0
    i_samp = 0
    ns = sample_t.size
    n_steps = 0
    f_prev2 = -1.0
    f_prev1 = -1.0
    t_prev1 = t0
    peak = fa
    least = fa if contact else 0.0
    peak_d = 0.0
    t_flight = 0.0
    delta_a = 0.0
    # the indentation at the start
    if contact:
        _shapes(xe, hint_e, ex, el, ephi, nsh)
        _interp_modes(hint_e, nsh, out_w, hb)
        w = 0.0
        for j in range(m):
            w += weight[j] * (hb[j] * zeta[j]).real
        delta_a = (
            -y
            + ck0
            + w
            - _residual(
                hint_e, 0.0 if False else (xe - ex[hint_e]) / el[hint_e], nsh, resid, bubble
            )
            * fa
        )
        plastic = law != HERTZ and delta_a > d_y
        peak_d = delta_a

    while i_samp < ns:
        # the next stop: a sample, a kink, or h_max on
        target = sample_t[i_samp]
        while i_stop < stops.size and stops[i_stop] <= t + 1e-15:
            i_stop += 1
        if i_stop < stops.size and stops[i_stop] < target:
            target = stops[i_stop]
        span = target - t
        if span > 1e-15:
            k = int(math.ceil(span / h_max * (1.0 - 1e-12)))
            tau = span / k
            if abs(tau - tau_n) > 1e-18:
                _coefficients(lam, tau, e_n, a_n, b_n)
                tau_n = tau
            for _step in range(k):
                remaining = tau
                use_nominal = True
                while remaining > 0.0:
                    if use_nominal:
                        ee, aa, bb = e_n, a_n, b_n
                    else:
                        _coefficients(lam, remaining, e_t, a_t, b_t)
                        ee, aa, bb = e_t, a_t, b_t
                    st = remaining
                    # ---- trial step of length st ----
                    xb = speed * (t + st)
                    hint_e = _element(xb, ex, hint_e)
                    xi = _shapes(xb, hint_e, ex, el, ephi, nsh)
                    _interp_modes(hint_e, nsh, out_w, hb)
                    _interp_modes(hint_e, nsh, inp, gb)
                    w0 = 0.0
                    bcoef = 0.0
                    for j in range(m):
                        z = ee[j] * zeta[j] + aa[j] * ua[j]
                        zp[j] = z
                        w0 += weight[j] * (hb[j] * z).real
                        bcoef += weight[j] * (hb[j] * bb[j] * gb[j]).real
                    rb = _residual(hint_e, xi, nsh, resid, bubble)
                    ypred = y + st * v - load * st * st / (2.0 * mass) + st * st * fa / (6.0 * mass)
                    ckb, _, hint_t = table_eval(tx, ty, tsl, tsr, tperiod, xb, hint_t)
                    dstar = -ypred + ckb + w0
                    kappa = st * st / (3.0 * mass) - bcoef + rb
                    event = -1
                    if contact:
                        if dstar <= 0.0:
                            event = EV_LOSS
                    elif dstar > 0.0:
                        event = EV_CONTACT
                    if event >= 0:
                        # locate the root of δ* on the step length (Illinois), then take that step
                        lo = 0.0
                        hi_s = st
                        g_lo = delta_a if contact else delta_a
                        if event == EV_LOSS:
                            g_lo = -delta_a - 1e-300
                        else:
                            g_lo = delta_a - 1e-300
                        g_hi = -dstar if event == EV_LOSS else dstar
                        side = 0
                        s_try = st
                        for _it in range(80):
                            if g_hi - g_lo == 0.0:
                                s_try = 0.5 * (lo + hi_s)
                            else:
                                s_try = lo - g_lo * (hi_s - lo) / (g_hi - g_lo)
                            if not (lo < s_try < hi_s):
                                s_try = 0.5 * (lo + hi_s)
                            _coefficients(lam, s_try, e_t, a_t, b_t)
                            xs_ = speed * (t + s_try)
                            hint_e = _element(xs_, ex, hint_e)
                            _shapes(xs_, hint_e, ex, el, ephi, nsh)
                            _interp_modes(hint_e, nsh, out_w, hb)
                            ws = 0.0
                            for j in range(m):
                                ws += weight[j] * (hb[j] * (e_t[j] * zeta[j] + a_t[j] * ua[j])).real
                            yps = (
                                y
                                + s_try * v
                                - load * s_try * s_try / (2.0 * mass)
                                + s_try * s_try * fa / (6.0 * mass)
                            )
                            cks, _, hint_t = table_eval(tx, ty, tsl, tsr, tperiod, xs_, hint_t)
                            ds = -yps + cks + ws
                            gs = -ds if event == EV_LOSS else ds
                            if gs > 0.0:
                                hi_s = s_try
                                g_hi = gs
                                if side == 1:
                                    g_lo *= 0.5
                                side = 1
                            else:
                                lo = s_try
                                g_lo = gs
                                if side == -1:
                                    g_hi *= 0.5
                                side = -1
                            if hi_s - lo <= 1e-15 * max(1.0, abs(t)) + 1e-14 * st:
                                break
                        st = hi_s
                        _coefficients(lam, st, e_t, a_t, b_t)
                        ee, aa, bb = e_t, a_t, b_t
                        xb = speed * (t + st)
                        hint_e = _element(xb, ex, hint_e)
                        xi = _shapes(xb, hint_e, ex, el, ephi, nsh)
                        _interp_modes(hint_e, nsh, out_w, hb)
                        _interp_modes(hint_e, nsh, inp, gb)
                        w0 = 0.0
                        bcoef = 0.0
                        for j in range(m):
                            z = ee[j] * zeta[j] + aa[j] * ua[j]
                            zp[j] = z
                            w0 += weight[j] * (hb[j] * z).real
                            bcoef += weight[j] * (hb[j] * bb[j] * gb[j]).real
                        rb = _residual(hint_e, xi, nsh, resid, bubble)
                        ypred = (
                            y + st * v - load * st * st / (2.0 * mass) + st * st * fa / (6.0 * mass)
                        )
                        ckb, _, hint_t = table_eval(tx, ty, tsl, tsr, tperiod, xb, hint_t)
                        dstar = -ypred + ckb + w0
                        kappa = st * st / (3.0 * mass) - bcoef + rb
                    # ---- commit ----
                    if event == EV_LOSS or (event < 0 and not contact):
                        fb = 0.0
                    elif event == EV_CONTACT:
                        fb = 0.0
                    else:
                        fb = _solve_force(dstar, kappa, law, cc, f_y, d_y, theta)
                    for j in range(m):
                        zeta[j] = zp[j] + bb[j] * gb[j] * fb
                        ua[j] = gb[j] * fb
                    y = ypred + st * st * fb / (3.0 * mass)
                    v = v - load * st / mass + st * (fa + fb) / (2.0 * mass)
                    delta_b = dstar - kappa * fb if (contact and event != EV_LOSS) else dstar
                    if not contact:
                        t_flight += st
                    t_new = t + st
                    if event == EV_LOSS:
                        contact = False
                        delta_b = 0.0
                    elif event == EV_CONTACT:
                        contact = True
                        delta_b = 0.0
                    if event >= 0 and n_tr < transitions.shape[0]:
                        transitions[n_tr, 0] = t_new
                        transitions[n_tr, 1] = event
                        n_tr += 1
                    # the plastic range: entry and exit (located on the committed step's δ, linearly)
                    if law != HERTZ and contact:
                        up = d_y + hyst
                        down = d_y - hyst
                        if (not plastic) and delta_b > up:
                            fr = (up - delta_a) / (delta_b - delta_a) if delta_b != delta_a else 1.0
                            if n_tr < transitions.shape[0]:
                                transitions[n_tr, 0] = t + fr * st
                                transitions[n_tr, 1] = EV_YIELD
                                n_tr += 1
                            plastic = True
                        elif plastic and delta_b < down:
                            fr = (
                                (delta_a - down) / (delta_a - delta_b)
                                if delta_b != delta_a
                                else 1.0
                            )
                            if n_tr < transitions.shape[0]:
                                transitions[n_tr, 0] = t + fr * st
                                transitions[n_tr, 1] = EV_UNYIELD
                                n_tr += 1
                            plastic = False
                    elif plastic and not contact:
                        if n_tr < transitions.shape[0]:
                            transitions[n_tr, 0] = t_new
                            transitions[n_tr, 1] = EV_UNYIELD
                            n_tr += 1
                        plastic = False
                    if track_dents and contact and delta_b > d_y and n_dent < dents.shape[0]:
                        cx, _, _, _ = linear_at(tx, tcx, tperiod, xb, hint_t, False)
                        dents[n_dent, 0] = t_new
                        dents[n_dent, 1] = cx
                        dents[n_dent, 2] = delta_b
                        n_dent += 1
                    # extrema: the peak through a parabola of the last three step ends
                    if fb > peak:
                        peak = fb
                    if f_prev1 > fb and f_prev1 >= f_prev2 and f_prev2 >= 0.0 and fb > 0.0:
                        den = f_prev2 - 2.0 * f_prev1 + fb
                        if den < 0.0:
                            top = f_prev1 - 0.125 * (f_prev2 - fb) ** 2 / den
                            if top > peak and top < 2.0 * f_prev1:
                                peak = top
                    if contact:
                        if fb < least:
                            least = fb
                    if delta_b > peak_d:
                        peak_d = delta_b
                    f_prev2 = f_prev1
                    f_prev1 = fb
                    t_prev1 = t_new
                    fa = fb
                    delta_a = delta_b
                    t = t_new
                    remaining -= st
                    if remaining <= 1e-15 * max(1.0, abs(t)):
                        remaining = 0.0
                    use_nominal = False
                    n_steps += 1
        else:
            t = target
        # ---- a sample at t? ----
        if abs(t - sample_t[i_samp]) <= 1e-12 * max(1.0, abs(t)) or t >= sample_t[i_samp]:
            xs = speed * t
            hint_e = _element(xs, ex, hint_e)
            xi = _shapes(xs, hint_e, ex, el, ephi, nsh)
            _interp_modes(hint_e, nsh, out_w, hb)
            _interp_modes(hint_e, nsh, inp, gb)
            wv = 0.0
            vw = 0.0
            for j in range(m):
                wv += weight[j] * (hb[j] * zeta[j]).real
                vw += weight[j] * (hb[j] * (lam[j] * zeta[j] + gb[j] * fa)).real
            rr = _residual(hint_e, xi, nsh, resid, bubble)
            ck, _, hint_t = table_eval(tx, ty, tsl, tsr, tperiod, xs, hint_t)
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
                s = 0.0
                for j in range(m):
                    s += weight[j] * (crib_rows[i, j] * (lam[j] * zeta[j] + gb[j] * fa)).real
                if crib_lo[i] < xs < crib_hi[i]:
                    s += fa
                channels[i_samp, i] = s
            i_samp += 1
    extrema[E_PEAK_FORCE] = peak
    extrema[E_MIN_FORCE] = least
    extrema[E_PEAK_DELTA] = peak_d
    extrema[E_T_FLIGHT] = t_flight
    extrema[E_STEPS] = n_steps
    return n_tr, n_dent
