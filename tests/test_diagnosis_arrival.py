"""The measured (and not kept) ways of giving a template the state a lightly damped wheel
arrives with (docs/diagnosis.md, "Tried and not kept"): each does what it says."""

from __future__ import annotations

import math

import numpy as np

from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.diagnosis.estimate import _clean_arrivals, remove_ringing, ringing_modes
from sim_core.diagnosis.forward import WheelOnSite
from sim_core.diagnosis.sensor import SensorModel
from sim_core.diagnosis.turns import disturbance, first_impact_lead
from sim_core.materials import Material, derive
from sim_core.passage import Foundation

R, P, M = 0.46, 80e3, 600.0
RATE = 1e4


def _wheel(zeta: float) -> WheelOnSite:
    d = derive(Material(2.14e11, 0.3), radius=R, load=P, mass=M)
    c = 2 * zeta * math.sqrt(2e8 * 150.0)
    return WheelOnSite(
        M,
        P,
        R,
        ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
        Foundation.compliant(150.0, 2e8, c),
    )


def test_lead_reaches_back_to_an_earlier_impact_than_the_largest() -> None:
    t = np.arange(0.0, 0.3, 1.0 / RATE)
    f = np.full(t.size, P)
    for first, bounce in ((0.05, 0.065), (0.15, 0.158)):  # first impact, then a harder bounce
        f[np.searchsorted(t, first)] += 6 * P
        f[np.searchsorted(t, bounce)] += 10 * P
    g = disturbance(t, f, P)
    times = np.array([t[np.searchsorted(t, 0.065)], t[np.searchsorted(t, 0.158)]])
    assert abs(first_impact_lead(t, g, times, 0.1) - 0.015) <= 1e-3  # the smoothing's width
    f2 = np.full(t.size, P)
    f2[np.searchsorted(t, times)] += 10 * P
    assert first_impact_lead(t, disturbance(t, f2, P), times, 0.1) == 0.0


def test_only_the_windows_entered_in_contact_are_kept_if_there_is_one() -> None:
    t = np.arange(0.0, 0.3, 1.0 / RATE)
    f = np.full(t.size, P)
    win = [(500, 700), (1500, 1700), (2500, 2700)]
    f[1400:1450] = 0.0  # the wheel off the rail 10 ms before the second window
    kept_win, kept = _clean_arrivals(t, f, P, 1e3, win, [0.07, 0.17, 0.27])
    assert kept_win == [(500, 700), (2500, 2700)] and kept == [0.07, 0.27]
    f[400:450] = 0.0
    f[2400:2450] = 0.0  # every window entered bouncing: all are kept
    assert _clean_arrivals(t, f, P, 1e3, win, [0.07, 0.17, 0.27])[0] == win


def test_a_linear_ringing_is_fitted_before_the_window_and_removed_in_it() -> None:
    zeta = 0.02
    w = _wheel(zeta)
    sensor = SensorModel(2000.0, 4)
    lam = ringing_modes(w, zeta)
    slow = lam[(lam.imag > 0)][np.argmax(lam[lam.imag > 0].real)]  # the foundation's mode
    fine = sensor.fine_rate(RATE)
    tf = np.arange(0.0, 0.3, 1.0 / fine)
    ring = 0.3 * P * np.exp(slow.real * tf) * np.cos(slow.imag * tf + 0.7)
    t = np.arange(0.0, 0.29, 1.0 / RATE)
    f = P + np.interp(t, tf, sensor.filter(ring, fine))
    win = [(1000, 1200), (2200, 2400)]
    out = remove_ringing(w, zeta, sensor, t, f, win)
    for i0, i1 in win:
        before = np.max(np.abs(f[i0:i1] - P))
        assert before > 0.01 * P
        assert np.max(np.abs(out[i0:i1] - P)) < 0.01 * before
    assert np.array_equal(out[:1000], f[:1000])  # the record outside the windows unchanged


def test_a_lifted_arrival_template_starts_in_flight() -> None:
    """``FitOptions.arrival_lifts``: a window may be matched by a template whose wheel
    arrives lifted (in flight) instead of rolling; that template starts out of contact and
    lands before the flat."""
    from sim_core.diagnosis.estimate import _Problem, make_flat
    from sim_core.diagnosis.forward import RailTables
    from sim_core.passage import InitialState
    from sim_core.rail import RailProfile

    w = _wheel(0.05)
    d0 = (P / w.contact.coefficient) ** (2.0 / 3.0)
    prob = _Problem(
        w,
        25.0,
        SensorModel(3000.0, 2),
        75_000.0,
        np.zeros(0),
        np.zeros(0),
        [],
        np.zeros(0),
        RailTables(RailProfile.flat()),
        arrivals=(None, InitialState(y_c=5.0 * d0)),
    )
    flat = make_flat(R, "flat", 0.05)
    _, rolling = prob.template(flat, 0.05, 0)
    tau, lifted = prob.template(flat, 0.05, 1)
    start = tau < tau[0] + 5e-4  # the first half millisecond, after the chain's settling
    assert abs(float(np.median(rolling[start])) - P) < 0.01 * P
    assert float(np.min(lifted[start])) < 0.2 * P  # airborne at first
    assert float(np.max(lifted)) > P  # and lands again
