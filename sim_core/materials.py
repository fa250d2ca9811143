"""Material and geometry of the contact, and the quantities derived from them.

Everything here is MODEL.md §1 and §3 in closed form: the effective modulus,
the Hertz coefficient C, the static indentation δ0, the linearised contact
frequency f0, and von Mises' limit of elastic deformation F_Y, δ_Y.

Worked example (the paper's wheel): E = 2.14e11 Pa, ν = 0.3, R = 0.475 m,
P = 39 240 N, m = 400 kg, Y = 600 MPa gives

    >>> d = derive(Material(2.14e11, 0.3, 6.0e8), radius=0.475, load=39240.0, mass=400.0)
    >>> round(d.contact_coefficient / 1e11, 4), round(d.static_indentation * 1e6, 1)
    (1.0805, 50.9)
    >>> round(d.contact_frequency, 1), round(d.yield_force / 1e3, 1), round(d.yield_indentation * 1e6, 1)
    (270.6, 81.8, 83.1)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

JOHNSON_COEFFICIENT_VON_MISES = 1.1
"""ϑ_Y of MODEL.md §1: the mean contact pressure at first yield is 1.1·Y·(3π/4)/π... (von Mises)."""


@dataclass(frozen=True)
class Material:
    """Elastic constants shared by wheel and rail, and the rail's yield stress.

    Both bodies have the same E and ν (MODEL.md §1); ``yield_stress`` may be
    ``None`` for a purely elastic (Hertz) computation.
    """

    youngs_modulus: float
    poisson_ratio: float
    yield_stress: float | None = None
    johnson_coefficient: float = JOHNSON_COEFFICIENT_VON_MISES

    def __post_init__(self) -> None:
        if not (math.isfinite(self.youngs_modulus) and self.youngs_modulus > 0):
            raise ValueError(
                f"youngs_modulus must be a positive finite number, got {self.youngs_modulus!r}"
            )
        if not (math.isfinite(self.poisson_ratio) and -1.0 < self.poisson_ratio < 0.5):
            raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {self.poisson_ratio!r}")
        if self.yield_stress is not None and not (
            math.isfinite(self.yield_stress) and self.yield_stress > 0
        ):
            raise ValueError(
                f"yield_stress must be positive and finite or None, got {self.yield_stress!r}"
            )
        if not (math.isfinite(self.johnson_coefficient) and self.johnson_coefficient > 0):
            raise ValueError(
                f"johnson_coefficient must be positive, got {self.johnson_coefficient!r}"
            )


def effective_modulus(material: Material) -> float:
    """E* with 1/E* = (1-ν1²)/E1 + (1-ν2²)/E2, both bodies of the same material."""
    return material.youngs_modulus / (2.0 * (1.0 - material.poisson_ratio**2))


def hertz_coefficient(e_star: float, radius: float) -> float:
    """C = (4/3)·E*·sqrt(R*) of F = C·δ^(3/2) (MODEL.md (3.3))."""
    return 4.0 / 3.0 * e_star * math.sqrt(radius)


def yield_force(e_star: float, radius: float, yield_stress: float, theta_y: float) -> float:
    """F_Y = π·(3π/4)²·(ϑ_Y·Y)³·R*²/E*² (MODEL.md (4.2), with the leading π)."""
    return (
        math.pi * (3.0 * math.pi / 4.0) ** 2 * (theta_y * yield_stress) ** 3 * radius**2 / e_star**2
    )


@dataclass(frozen=True)
class DerivedQuantities:
    """The contract's ``derived`` block (CONTRACT.md), SI units.

    ``yield_force`` and ``yield_indentation`` are ``None`` without a yield stress.
    """

    effective_modulus: float
    contact_coefficient: float
    static_indentation: float
    contact_frequency: float
    contact_stiffness: float
    yield_force: float | None
    yield_indentation: float | None


def derive(material: Material, radius: float, load: float, mass: float) -> DerivedQuantities:
    """Derive C, δ0 = (P/C)^(2/3), f0 = sqrt(k_lin/m)/2π with k_lin = 1.5·C·sqrt(δ0), F_Y, δ_Y."""
    for name, value in (("radius", radius), ("load", load), ("mass", mass)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    e_star = effective_modulus(material)
    c = hertz_coefficient(e_star, radius)
    delta0 = (load / c) ** (2.0 / 3.0)
    k_lin = 1.5 * c * math.sqrt(delta0)
    f0 = math.sqrt(k_lin / mass) / (2.0 * math.pi)
    f_y: float | None = None
    d_y: float | None = None
    if material.yield_stress is not None:
        f_y = yield_force(e_star, radius, material.yield_stress, material.johnson_coefficient)
        d_y = (f_y / c) ** (2.0 / 3.0)
    return DerivedQuantities(
        effective_modulus=e_star,
        contact_coefficient=c,
        static_indentation=delta0,
        contact_frequency=f0,
        contact_stiffness=k_lin,
        yield_force=f_y,
        yield_indentation=d_y,
    )
