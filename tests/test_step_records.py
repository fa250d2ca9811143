"""The certified bounds that let the integrator skip per-step searches hold on brute force.

``sim_core.integrate.records.step_extrema`` locates an interior extremum of δ only when
``interior_reach`` (|δ''|max·h²/8 from ``curvature_of_delta``, plus a margin) says it
could beat a record. Here random contact steps on the issue's rough sampled rail
(0.5 mm samples, 10 µm rms, a round wheel at 160 km/h) are built as the integrator
builds them (septic Hermite from positions, velocities, accelerations and jerks at
both ends; the ends' δ from ``jerks_and_delta``) and δ is sampled densely inside:
it never leaves [min(δ_a, δ_b) - reach, max(δ_a, δ_b) + reach]. Steps do not
straddle a kink of the constraint, as the integrator's contact steps never do.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core import paper
from sim_core.constraint import tabulate_constraint
from sim_core.contact_laws import HERTZ, ContactLaw
from sim_core.integrate.dense import fill_dense
from sim_core.integrate.model import curvature_bound, delta_rate, jerks_and_delta, slope_at
from sim_core.integrate.records import curvature_of_delta, interior_reach
from sim_core.integrate.types import ELASTIC, Params, Table, table_of
from sim_core.wheel import WheelOutline
from tests.stored_rails import site_rail_0p3

SPEED = 160 / 3.6
N_STEPS = 400
N_SAMPLES = 4001


@numba.njit(cache=True)
def _delta_range(
    t: float, h: float, coef: NDArray[np.float64], par: Params, tab: Table, n: int
) -> tuple[float, float]:
    """(min, max) of the dense δ at n equal fractions of the step, ends included."""
    lo = math.inf
    hi = -math.inf
    hint = 0
    for i in range(n):
        d, _, hint = delta_rate(i / (n - 1), t, h, coef, par, tab, hint)
        lo = min(lo, d)
        hi = max(hi, d)
    return lo, hi


def _site_params(tab: Table) -> Params:
    contact = paper.contact_model(ContactLaw.HERTZ)
    return Params.build(
        law=HERTZ,
        c=contact.coefficient,
        f_y=contact.yield_force,
        d_y=contact.yield_indentation,
        theta=contact.johnson_coefficient,
        hyst=contact.switch_width,
        mass=paper.MASS,
        load=paper.LOAD,
        speed=SPEED,
        compliant=False,
        f_mass=1.0,
        f_stiff=0.0,
        f_damp=0.0,
        rtol=1e-9,
        atol_y=1e-13,
        atol_v=1e-10,
        hmax_contact=1e-4,
        c2max=curvature_bound(tab),
        track_dents=False,
        dent_dx=1e-4,
    )


def _wheel_motion(
    rng: np.random.Generator, ck_a: float, v_track: float, rate_a: float
) -> Callable[[float], tuple[float, float, float, float]]:
    """A smooth wheel-centre motion (position, velocity, acceleration, jerk) in contact.

    It starts at δ = 0.02–0.1 mm, following the constraint (vertical velocity ``v_track``)
    to within ±``rate_a`` in dδ/dt: δ turns inside many steps.
    """
    d0 = rng.uniform(2e-5, 1e-4)
    g = paper.LOAD / paper.MASS
    amp = rng.uniform(0.0, 2e-5)
    om = 2 * math.pi * rng.uniform(100.0, 3000.0)
    ph = rng.uniform(0.0, 2 * math.pi)
    v0 = v_track + rng.uniform(-rate_a, rate_a) - amp * om * math.cos(ph)

    def at(tau: float) -> tuple[float, float, float, float]:
        s, c = math.sin(om * tau + ph), math.cos(om * tau + ph)
        return (
            ck_a - d0 + v0 * tau - 0.5 * g * tau * tau + amp * s,
            v0 - g * tau + amp * om * c,
            -g - amp * om * om * s,
            -amp * om**3 * c,
        )

    return at


def test_interior_reach_bounds_delta_inside_contact_steps(
    record_property: Callable[[str, object], None],
) -> None:
    table = tabulate_constraint(WheelOutline.round(0.46), site_rail_0p3(), 0.0, 0.3)
    tab = table_of(table)
    par = _site_params(tab)
    kinks = np.asarray(table.kinks)
    rng = np.random.default_rng(20261123)
    coef = np.zeros((2, 8))
    n_interior = 0
    n_tested = 0
    tightest = 0.0
    while n_tested < N_STEPS:
        x_a = rng.uniform(0.02, 0.25)
        h = math.exp(rng.uniform(math.log(1e-6), math.log(4e-5)))
        x_b = x_a + SPEED * h
        if np.any((kinks > x_a) & (kinks < x_b)):
            continue
        t = x_a / SPEED
        ck_a, dck_a, _ = slope_at(tab, x_a, 0)
        # the wheel's velocity: the constraint's, within what ~1 000 m/s² turns in the step
        motion = _wheel_motion(rng, ck_a, SPEED * dck_a, 500.0 * h)
        p0, v0, a0, j0 = motion(0.0)
        p1, v1, a1, j1 = motion(h)
        y0 = np.array([p0, v0, 0.0, 0.0])
        y1 = np.array([p1, v1, 0.0, 0.0])
        fill_dense(
            coef, h, y0, np.array([v0, a0, 0.0, 0.0]), j0, 0.0, y1, np.array([v1, a1, 0.0, 0.0]),
            j1, 0.0,
        )  # fmt: skip
        _, _, d_a, _, _ = jerks_and_delta(t, y0, 0.0, ELASTIC, par, tab, 0, False)
        _, _, d_b, _, _ = jerks_and_delta(t + h, y1, 0.0, ELASTIC, par, tab, 0, True)
        m = curvature_of_delta(h, coef, par)
        reach = interior_reach(d_a, d_b, h, m, x_b)
        lo, hi = _delta_range(t, h, coef, par, tab, N_SAMPLES)
        assert hi <= max(d_a, d_b) + reach, (x_a, h, hi - max(d_a, d_b), reach)
        assert lo >= min(d_a, d_b) - reach, (x_a, h, min(d_a, d_b) - lo, reach)
        excess = max(hi - max(d_a, d_b), min(d_a, d_b) - lo)
        if excess > 1e-15:
            n_interior += 1
            tightest = max(tightest, excess / (m * h * h / 8.0))
        n_tested += 1
    record_property("steps_with_interior_extremum", n_interior)
    record_property("largest_excess_over_curvature_term", tightest)
    # the test is not vacuous: δ goes beyond its end values inside many steps, and by a
    # good fraction of the curvature term somewhere (a bound several times smaller fails)
    assert n_interior > N_STEPS // 4
    assert tightest > 0.2


def test_interior_reach_is_attained_by_a_parabola() -> None:
    """The worst case: δ(τ) = δ_e + m·τ·(h - τ)/2 (δ'' = -m, equal ends) peaks m·h²/8 above them."""
    h, m, d_e = 1e-5, 3e3, 1e-4
    excess = m * h * h / 8.0
    reach = interior_reach(d_e, d_e, h, m, 1.0)
    assert excess <= reach < 1.001 * excess
