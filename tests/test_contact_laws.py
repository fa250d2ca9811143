"""MODEL.md §1/§3 in numbers: derived constants, the three loading laws, unloading, ∫F dδ.

The reference values are the page's; ``tests.reference_solver`` re-derives the
closed forms independently of ``sim_core`` so both are checked against the page
and against each other.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from sim_core import contact_laws as cl
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.materials import Material, derive
from tests import reference_solver as rs

E, NU, R, P, M = 2.14e11, 0.3, 0.475, 39240.0, 400.0
THETA = 1.1
LAWS = (cl.HERTZ, cl.JOHNSON, cl.HERTZ_PLASTIC)
LAW_NAMES = {cl.HERTZ: "hertz", cl.JOHNSON: "johnson", cl.HERTZ_PLASTIC: "hertz_plastic"}


def _derived(y: float | None = 6e8):  # type: ignore[no-untyped-def]
    return derive(Material(E, NU, y), radius=R, load=P, mass=M)


def _rounds_to(value: float, reference: float, digits: int) -> bool:
    """``value`` shown with the page's ``digits`` significant digits equals ``reference``."""
    return float(f"{value:.{digits}g}") == reference


# --------------------------------------------------------------------------- §1 numbers
def test_reference_constants_match_the_page() -> None:
    d = _derived()
    k = rs.paper_constants(E, NU, R, P, M, 6e8, THETA)
    for ours, theirs in ((d.effective_modulus, k.e_star), (d.contact_coefficient, k.c)):
        assert ours == pytest.approx(theirs, rel=1e-14)
    assert _rounds_to(d.effective_modulus, 1.1758e11, 5)
    assert _rounds_to(d.contact_coefficient, 1.0805e11, 5)
    assert _rounds_to(d.static_indentation * 1e6, 50.9, 3)
    assert _rounds_to(d.contact_frequency, 270.6, 4)
    assert d.static_indentation == pytest.approx(k.delta0, rel=1e-14)
    assert d.contact_frequency == pytest.approx(k.f0, rel=1e-14)
    assert d.contact_stiffness / 5 == pytest.approx(2.31e8, rel=2e-3)  # Fig. 9's k


@pytest.mark.parametrize(("y", "f_y_kn"), [(6e8, 81.8), (7e8, 129.9), (8e8, 194.0)])
def test_yield_force_matches_the_page(y: float, f_y_kn: float) -> None:
    d = _derived(y)
    k = rs.paper_constants(E, NU, R, P, M, y, THETA)
    assert d.yield_force is not None and d.yield_indentation is not None
    assert d.yield_force == pytest.approx(k.f_y, rel=1e-14)
    assert d.yield_indentation == pytest.approx(k.d_y, rel=1e-14)
    assert round(d.yield_force / 1e3, 1) == f_y_kn
    assert d.yield_force > P  # the paper's requirement at the reference load


def test_yield_indentation_600() -> None:
    d = _derived(6e8)
    assert d.yield_indentation is not None
    assert round(d.yield_indentation * 1e6, 1) == 83.1


def test_no_yield_stress_gives_none() -> None:
    d = _derived(None)
    assert d.yield_force is None and d.yield_indentation is None


# --------------------------------------------------------------------------- §3 laws
@pytest.fixture(scope="module")
def k600() -> rs.Constants:
    return rs.paper_constants(E, NU, R, P, M, 6e8, THETA)


def _force(delta: float, law: int, k: rs.Constants) -> float:
    return float(cl.contact_force(delta, law, k.c, k.f_y, k.d_y, THETA))


def test_hertz_carries_the_load_at_delta0(k600: rs.Constants) -> None:
    assert _force(k600.delta0, cl.HERTZ, k600) == pytest.approx(P, rel=1e-13)


def test_johnson_at_twice_yield_is_four_yield_forces(k600: rs.Constants) -> None:
    f = _force(2 * k600.d_y, cl.JOHNSON, k600)
    assert round(f / k600.f_y, 2) == 4.00
    # closed form: s = 3, F = 3·F_Y·(1 + ln 3/(3ϑ))
    assert f == pytest.approx(3 * k600.f_y * (1 + math.log(3) / (3 * THETA)), rel=1e-14)


def test_johnson_unloading_from_twice_yield(k600: rs.Constants) -> None:
    dc = 2 * k600.d_y
    grid = np.linspace(0.0, dc, 2001)
    f, d_r, d_f = cl.johnson_unloading(grid, dc, k600.f_y, k600.d_y, k600.c, THETA)
    assert round(d_f / k600.d_y, 3) == 0.268
    assert d_r == pytest.approx(k600.d_y * math.sqrt(3.0), rel=1e-14)
    assert d_f + d_r == pytest.approx(dc, rel=1e-14)
    assert f[-1] == pytest.approx(_force(dc, cl.JOHNSON, k600), rel=1e-13)  # starts on loading
    assert np.all(f[grid <= d_f] == 0.0)
    assert np.all(np.diff(f) >= 0.0)
    # the paper's remark (MODEL §6, Fig. 5): unloading lies above loading for 0.86 < δ/δ_Y < 1.36
    load = np.array([_force(x, cl.JOHNSON, k600) for x in grid])
    above = grid[(f > load) & (grid > 0.5 * k600.d_y)] / k600.d_y
    assert above.min() == pytest.approx(0.86, abs=0.01)
    assert above.max() == pytest.approx(1.36, abs=0.01)


def test_hpp_plateau_and_recovery(k600: rs.Constants) -> None:
    for x in (1.0000001, 1.5, 2.0, 10.0):
        assert _force(x * k600.d_y, cl.HERTZ_PLASTIC, k600) == k600.f_y
    dc = 2 * k600.d_y
    grid = np.linspace(0.0, dc, 1001)
    f, d_r, d_f = cl.hertz_plastic_unloading(grid, dc, k600.f_y, k600.d_y)
    assert d_r == k600.d_y
    assert d_f == pytest.approx(dc - k600.d_y, rel=1e-14)
    assert f[-1] == pytest.approx(k600.f_y, rel=1e-14)
    assert np.all(f[grid <= d_f] == 0.0)


@pytest.mark.parametrize("fn", [cl.johnson_unloading, cl.hertz_plastic_unloading])
def test_unloading_needs_plastic_start(fn, k600: rs.Constants) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ValueError, match="plastic"):
        if fn is cl.johnson_unloading:
            fn(np.zeros(3), 0.5 * k600.d_y, k600.f_y, k600.d_y, k600.c, THETA)
        else:
            fn(np.zeros(3), 0.5 * k600.d_y, k600.f_y, k600.d_y)


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("x", [0.3, 1.0, 1.2, 2.0, 3.5])
def test_contact_potential_against_quad(law: int, x: float, k600: rs.Constants) -> None:
    delta = x * k600.d_y
    pts = [k600.d_y] if x > 1 else None
    num, _ = quad(lambda d: _force(d, law, k600), 0.0, delta, points=pts, epsabs=0, epsrel=1e-13)
    got = float(cl.contact_potential(delta, law, k600.c, k600.f_y, k600.d_y, THETA))
    assert got == pytest.approx(num, rel=1e-11)
    assert got == pytest.approx(rs.loading_potential(delta, LAW_NAMES[law], k600), rel=1e-12)


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("delta", [-0.0, 0.0, -1e-300, -5e-324, -1e-6, -1e-3, -1.0, -math.inf])
def test_no_nan_for_negative_indentation(law: int, delta: float, k600: rs.Constants) -> None:
    args = (law, k600.c, k600.f_y, k600.d_y, THETA)
    assert cl.contact_force(delta, *args) == 0.0
    assert cl.contact_potential(delta, *args) == 0.0
    for plastic in (False, True):
        assert cl.mode_force(delta, plastic, *args) == 0.0
    arr = cl.force_array(np.array([delta, delta]), *args)
    assert np.all(arr == 0.0)
    model = ContactModel(ContactLaw(law), k600.c, k600.f_y, k600.d_y)
    assert np.all(model.force(delta) == 0.0)


def test_mode_force_branches(k600: rs.Constants) -> None:
    a = (k600.c, k600.f_y, k600.d_y, THETA)
    x = 1.05 * k600.d_y
    assert cl.mode_force(x, False, cl.JOHNSON, *a) == pytest.approx(k600.c * x**1.5, rel=1e-14)
    assert cl.mode_force(x, True, cl.JOHNSON, *a) == pytest.approx(
        rs.loading_force(x, "johnson", k600), rel=1e-14
    )
    assert cl.mode_force(0.95 * k600.d_y, True, cl.HERTZ_PLASTIC, *a) == k600.f_y


def test_contact_law_names() -> None:
    for name in ("hertz", "johnson", "hertz_plastic"):
        assert ContactLaw.from_name(name).name.lower() == name
    with pytest.raises(ValueError, match="unknown contact law 'plastic'"):
        ContactLaw.from_name("plastic")


# --------------------------------------------------------------------------- properties
yields = st.floats(min_value=3e8, max_value=1.2e9)
laws = st.sampled_from(LAWS)


@settings(max_examples=200, deadline=None)
@given(
    law=laws,
    y=yields,
    a=st.floats(min_value=-2.0, max_value=20.0),
    b=st.floats(min_value=-2.0, max_value=20.0),
)
@example(law=cl.HERTZ_PLASTIC, y=3e8, a=1.0, b=2.0)  # found by hypothesis: δ_Y's last bits
def test_force_monotone_non_decreasing(law: int, y: float, a: float, b: float) -> None:
    k = rs.paper_constants(E, NU, R, P, M, y, THETA)
    lo, hi = sorted((a * k.d_y, b * k.d_y))
    f_lo, f_hi = _force(lo, law, k), _force(hi, law, k)
    assert math.isfinite(f_lo) and math.isfinite(f_hi)
    assert f_lo <= f_hi


@settings(max_examples=200, deadline=None)
@given(law=laws, y=yields, eps=st.floats(min_value=1e-15, max_value=1e-6))
def test_force_continuous_at_yield(law: int, y: float, eps: float) -> None:
    k = rs.paper_constants(E, NU, R, P, M, y, THETA)
    below = _force(k.d_y * (1 - eps), law, k)
    above = _force(k.d_y * (1 + eps), law, k)
    # |F'| <= 2.6·F_Y/δ_Y on either side (Johnson); the jump must be only that slope's worth
    assert abs(above - below) <= 6.0 * k.f_y * eps + 1e-9 * k.f_y


@settings(max_examples=200, deadline=None)
@given(law=laws, y=yields, x=st.floats(min_value=0.0, max_value=20.0))
def test_force_matches_independent_derivation(law: int, y: float, x: float) -> None:
    k = rs.paper_constants(E, NU, R, P, M, y, THETA)
    delta = x * k.d_y
    expected = rs.loading_force(delta, LAW_NAMES[law], k)
    assert _force(delta, law, k) == pytest.approx(expected, rel=1e-13, abs=1e-300)


@pytest.mark.parametrize("law", [cl.JOHNSON, cl.HERTZ_PLASTIC])
@pytest.mark.parametrize("y", [3e8, 4.5e8, 6e8, 1.2e9])
def test_the_law_does_not_dip_where_it_turns_plastic(law: int, y: float) -> None:
    """At δ_Y itself the Hertz branch is capped at F_Y (C·δ_Y^1.5 rounds a few ulp above it at
    Y = 300 MPa): the force at δ_Y is at most the force anywhere beyond (a property found by
    hypothesis with a = 1, b = 2; it must not rest on the last bits of δ_Y)."""
    k = rs.paper_constants(E, NU, R, P, M, y, THETA)
    at = _force(k.d_y, law, k)
    assert at <= k.f_y
    for d in (np.nextafter(k.d_y, np.inf), 1.0000001 * k.d_y, 2.0 * k.d_y):
        assert at <= _force(float(d), law, k)
