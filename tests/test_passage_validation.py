"""The passage API rejects nonsense early, with messages that name the field."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest

from sim_core.constraint import flat_constraint
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.materials import Material, derive
from sim_core.passage import (
    Foundation,
    InitialState,
    PassageSpec,
    simulate_passage,
    static_indentation,
)
from tests import reference_solver as rs

NAN = math.nan
INF = math.inf
K600 = rs.paper_constants(yield_stress=6e8)
HERTZ = ContactModel(ContactLaw.HERTZ, K600.c)


def _spec(**kw: Any) -> PassageSpec:
    base: dict[str, Any] = dict(
        mass=400.0, load=39240.0, speed=20.0, duration=0.01, sample_rate=1e4, contact=HERTZ
    )
    base.update(kw)
    return PassageSpec(**base)


@pytest.mark.parametrize("field", ["mass", "load", "speed", "duration", "sample_rate", "rtol"])
@pytest.mark.parametrize("value", [-1.0, 0.0, NAN, INF, -INF])
def test_spec_rejects_non_positive_or_non_finite(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=rf"passage: {field} must be a positive finite number"):
        _spec(**{field: value})


def test_spec_rejects_non_finite_t0_and_tiny_rtol() -> None:
    with pytest.raises(ValueError, match="t0 must be finite"):
        _spec(t0=NAN)
    with pytest.raises(ValueError, match="rtol"):
        _spec(rtol=1e-16)


def test_spec_accepts_the_reference_case() -> None:
    spec = _spec()
    assert spec.rtol == 1e-9 and spec.foundation.kind == "rigid"


@pytest.mark.parametrize("field", ["mass", "stiffness"])
@pytest.mark.parametrize("value", [-1.0, 0.0, NAN, INF])
def test_compliant_foundation_rejects(field: str, value: float) -> None:
    kw = {"mass": 400.0, "stiffness": 2.3e8, field: value}
    with pytest.raises(ValueError, match=rf"compliant foundation: {field} must be positive"):
        Foundation.compliant(kw["mass"], kw["stiffness"])


@pytest.mark.parametrize("value", [-1.0, NAN, INF])
def test_compliant_foundation_rejects_damping(value: float) -> None:
    with pytest.raises(ValueError, match="damping must be >= 0"):
        Foundation.compliant(400.0, 2.3e8, value)


def test_foundation_kind() -> None:
    with pytest.raises(ValueError, match="foundation kind must be 'rigid' or 'compliant'"):
        Foundation("elastic")


@pytest.mark.parametrize("field", ["y_c", "v_c", "y_m", "v_m"])
@pytest.mark.parametrize("value", [NAN, INF, -INF])
def test_initial_state_rejects_non_finite(field: str, value: float) -> None:
    with pytest.raises(ValueError, match=rf"initial state: {field} must be finite"):
        InitialState(**{field: value})


def test_initial_foundation_state_on_rigid_foundation() -> None:
    with pytest.raises(ValueError, match="y_m/v_m given for a rigid foundation"):
        simulate_passage(flat_constraint(), _spec(initial=InitialState(v_m=0.1)))


@pytest.mark.parametrize("value", [-1.0, 0.0, NAN, INF])
def test_contact_model_rejects_coefficient(value: float) -> None:
    with pytest.raises(ValueError, match="contact coefficient must be positive"):
        ContactModel(ContactLaw.HERTZ, value)


@pytest.mark.parametrize("law", [ContactLaw.JOHNSON, ContactLaw.HERTZ_PLASTIC])
@pytest.mark.parametrize(
    ("f_y", "d_y"), [(0.0, 0.0), (-1.0, 8e-5), (8e4, -1.0), (NAN, 8e-5), (8e4, NAN)]
)
def test_plastic_law_needs_yield(law: ContactLaw, f_y: float, d_y: float) -> None:
    with pytest.raises(ValueError, match="needs a positive yield force and yield indentation"):
        ContactModel(law, K600.c, f_y, d_y)


def test_contact_model_rejects_nan_johnson_coefficient() -> None:
    with pytest.raises(ValueError, match="johnson"):
        ContactModel(ContactLaw.JOHNSON, K600.c, K600.f_y, K600.d_y, johnson_coefficient=NAN)


def test_contact_model_rejects_infinite_yield_force() -> None:
    with pytest.raises(ValueError, match="yield"):
        ContactModel(ContactLaw.JOHNSON, K600.c, INF, K600.d_y)


@pytest.mark.parametrize("eps", [-1e-6, 2e-3, NAN, INF])
def test_contact_model_rejects_yield_hysteresis(eps: float) -> None:
    with pytest.raises(ValueError, match=r"yield_hysteresis.*0 <= ε <= 1e-3"):
        ContactModel(ContactLaw.HERTZ_PLASTIC, K600.c, K600.f_y, K600.d_y, yield_hysteresis=eps)


def test_contact_model_switch_width() -> None:
    """ε·δ_Y, ε = 3e-5 by default for the Hertzian–perfectly plastic law only, and never
    below the round-off floor (ε = 0, or Hertz without a δ_Y)."""
    hpp = ContactModel(ContactLaw.HERTZ_PLASTIC, K600.c, K600.f_y, K600.d_y)
    assert hpp.switch_width == pytest.approx(3e-5 * K600.d_y, rel=1e-12)
    off = ContactModel(ContactLaw.HERTZ_PLASTIC, K600.c, K600.f_y, K600.d_y, yield_hysteresis=0.0)
    john = ContactModel(ContactLaw.JOHNSON, K600.c, K600.f_y, K600.d_y)
    assert off.switch_width == john.switch_width == HERTZ.switch_width == 1e-14
    wide = ContactModel(ContactLaw.JOHNSON, K600.c, K600.f_y, K600.d_y, yield_hysteresis=1e-4)
    assert wide.switch_width == pytest.approx(1e-4 * K600.d_y, rel=1e-12)


def test_contact_model_rejects_inconsistent_yield_pair() -> None:
    with pytest.raises(ValueError, match="yield"):
        ContactModel(ContactLaw.HERTZ_PLASTIC, K600.c, 2.0 * K600.f_y, K600.d_y)


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        (dict(youngs_modulus=-1.0), "youngs_modulus"),
        (dict(youngs_modulus=NAN), "youngs_modulus"),
        (dict(poisson_ratio=0.5), "poisson_ratio"),
        (dict(poisson_ratio=NAN), "poisson_ratio"),
        (dict(yield_stress=0.0), "yield_stress"),
        (dict(yield_stress=NAN), "yield_stress"),
        (dict(yield_stress=-6e8), "yield_stress"),
        (dict(johnson_coefficient=0.0), "johnson_coefficient"),
        (dict(johnson_coefficient=NAN), "johnson_coefficient"),
    ],
)
def test_material_rejects(kw: dict[str, float], match: str) -> None:
    base: dict[str, Any] = dict(youngs_modulus=2.14e11, poisson_ratio=0.3, yield_stress=6e8)
    base.update(kw)
    with pytest.raises(ValueError, match=match):
        Material(**base)


@pytest.mark.parametrize("field", ["radius", "load", "mass"])
@pytest.mark.parametrize("value", [-1.0, 0.0, NAN])
def test_derive_rejects(field: str, value: float) -> None:
    kw = {"radius": 0.475, "load": 39240.0, "mass": 400.0, field: value}
    with pytest.raises(ValueError, match=rf"{field} must be a positive finite number"):
        derive(Material(2.14e11, 0.3), **kw)


def test_hpp_load_above_yield_force_is_a_clear_error() -> None:
    hpp = ContactModel(ContactLaw.HERTZ_PLASTIC, K600.c, K600.f_y, K600.d_y)
    load = 1.2 * K600.f_y
    with pytest.raises(ValueError, match=r"exceeds the yield force .*no static equilibrium"):
        static_indentation(hpp, load)
    with pytest.raises(ValueError, match="exceeds the yield force"):
        simulate_passage(flat_constraint(), _spec(contact=hpp, load=load))


def test_johnson_load_above_yield_force_has_a_plastic_equilibrium() -> None:
    john = ContactModel(ContactLaw.JOHNSON, K600.c, K600.f_y, K600.d_y)
    load = 2.0 * K600.f_y
    d = static_indentation(john, load)
    assert d > K600.d_y
    assert d == pytest.approx(rs.static_indentation(load, "johnson", K600), rel=1e-12)
    out = simulate_passage(flat_constraint(), _spec(contact=john, load=load, duration=0.005))
    assert out.transitions == ()
    assert out.delta == pytest.approx(d, rel=1e-12)


def test_spec_is_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        _spec().mass = 1.0  # type: ignore[misc]
