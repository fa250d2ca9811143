"""One rail element: a Timoshenko (or Euler–Bernoulli) beam of length L, owning its matrices.

Interdependent interpolation (Friedman & Kosmatka, 1993): with
φ = 12·EI / (κGA·L²) the cubic deflection and quadratic rotation shape
functions solve the static beam equations exactly, so nodal loads give exact
nodal displacements, and the shear strain γ = w' − θ is constant along the
element. φ = 0 is the Euler–Bernoulli (Hermite) element. Degrees of freedom per
element: (w1, θ1, w2, θ2), w up, θ = dw/dx in the Euler–Bernoulli limit.

The mass matrix is the consistent one (translation ρA and rotary inertia ρI)
integrated exactly by Gauss–Legendre quadrature of these shape functions.

Worked example (a cantilever of one element, tip load 1 N: the tip deflection is
L³/3EI + L/κGA, exact for the interdependent element):

    >>> import numpy as np
    >>> from sim_core.track.spec import RailSection
    >>> r = RailSection()
    >>> k = stiffness_matrix(r, 1.0)[2:, 2:]
    >>> tip = np.linalg.solve(k, [1.0, 0.0])[0]
    >>> exact = 1 / (3 * r.bending_stiffness) + 1 / r.shear_stiffness
    >>> bool(abs(tip / exact - 1) < 1e-12)
    True
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sim_core.track.spec import RailSection

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(6)


def shear_ratio(rail: RailSection, length: float) -> float:
    """φ = 12·EI / (κGA·L²); 0 for Euler–Bernoulli."""
    ks = rail.shear_stiffness
    if math.isinf(ks):
        return 0.0
    return 12.0 * rail.bending_stiffness / (ks * length * length)


def deflection_shapes(
    xi: NDArray[np.float64] | float, length: float, phi: float
) -> NDArray[np.float64]:
    """N_w(ξ): the four deflection shape functions at ξ = x/L, shape (4, ...)."""
    xi = np.asarray(xi, dtype=np.float64)
    c = 1.0 / (1.0 + phi)
    L = length
    return np.stack(
        [
            c * (1.0 - 3.0 * xi**2 + 2.0 * xi**3 + phi * (1.0 - xi)),
            c * L * (xi - 2.0 * xi**2 + xi**3 + 0.5 * phi * (xi - xi**2)),
            c * (3.0 * xi**2 - 2.0 * xi**3 + phi * xi),
            c * L * (-(xi**2) + xi**3 + 0.5 * phi * (xi**2 - xi)),
        ]
    )


def deflection_shapes_at(xi: float, length: float, phi: float) -> NDArray[np.float64]:
    """:func:`deflection_shapes` at one ξ in Python floats, to rounding (numpy's 0-d ξ³ differs
    from ξ²·ξ in the last bit on ~5 % of ξ): a fifth of the time of the array form's four
    0-d arrays, paid at every passage's start."""
    c = 1.0 / (1.0 + phi)
    L = length
    x2 = xi * xi
    x3 = x2 * xi
    return np.array(
        [
            c * (1.0 - 3.0 * x2 + 2.0 * x3 + phi * (1.0 - xi)),
            c * L * (xi - 2.0 * x2 + x3 + 0.5 * phi * (xi - x2)),
            c * (3.0 * x2 - 2.0 * x3 + phi * xi),
            c * L * (-x2 + x3 + 0.5 * phi * (x2 - xi)),
        ]
    )


def rotation_shapes(
    xi: NDArray[np.float64] | float, length: float, phi: float
) -> NDArray[np.float64]:
    """N_θ(ξ): the four rotation shape functions at ξ = x/L, shape (4, ...)."""
    xi = np.asarray(xi, dtype=np.float64)
    c = 1.0 / (1.0 + phi)
    L = length
    return np.stack(
        [
            c * 6.0 * (xi**2 - xi) / L,
            c * (1.0 - 4.0 * xi + 3.0 * xi**2 + phi * (1.0 - xi)),
            -c * 6.0 * (xi**2 - xi) / L,
            c * (-2.0 * xi + 3.0 * xi**2 + phi * xi),
        ]
    )


def stiffness_matrix(rail: RailSection, length: float) -> NDArray[np.float64]:
    """The element's 4×4 stiffness matrix (bending and shear)."""
    L = length
    phi = shear_ratio(rail, L)
    a = rail.bending_stiffness / ((1.0 + phi) * L**3)
    return a * np.array(
        [
            [12.0, 6.0 * L, -12.0, 6.0 * L],
            [6.0 * L, (4.0 + phi) * L * L, -6.0 * L, (2.0 - phi) * L * L],
            [-12.0, -6.0 * L, 12.0, -6.0 * L],
            [6.0 * L, (2.0 - phi) * L * L, -6.0 * L, (4.0 + phi) * L * L],
        ]
    )


def mass_matrix(rail: RailSection, length: float, rotary: bool = True) -> NDArray[np.float64]:
    """The element's 4×4 consistent mass matrix: ∫ρA·N_wᵀN_w + ρI·N_θᵀN_θ dx (without the
    rotary part when ``rotary`` is false)."""
    L = length
    phi = shear_ratio(rail, L)
    xi = 0.5 * (_GAUSS_X + 1.0)
    w = 0.5 * _GAUSS_W * L
    nw = deflection_shapes(xi, L, phi)
    nt = rotation_shapes(xi, L, phi)
    rho_i = rail.rotary_inertia if rotary else 0.0
    return rail.mass_per_length * (nw * w) @ nw.T + rho_i * (nt * w) @ nt.T


def deflection_integral(rail: RailSection, length: float) -> NDArray[np.float64]:
    """∫₀ᴸ ρA·N_w dx: the rail's vertical inertia over the element per nodal acceleration."""
    L = length
    phi = shear_ratio(rail, L)
    xi = 0.5 * (_GAUSS_X + 1.0)
    return rail.mass_per_length * deflection_shapes(xi, L, phi) @ (0.5 * _GAUSS_W * L)


def bubble_compliance(
    rail: RailSection, length: float, xi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The local static deflection at a unit point load at ξ that the element's nodal
    interpolation leaves out: the deflection under the load of the element clamped at both
    ends (m/N), exact (closed form of a clamped–clamped Timoshenko beam).

    With a = ξL, b = L − a: bending a³b³/(3·EI·L³) and shear a·b/(κGA·L)·(1 − s), where
    the shear coupling s = φ·(...)/(1 + φ) vanishes in the Euler–Bernoulli limit. Computed here
    by splitting the element at the load into two exact elements (no formula to mistype).
    """
    out = np.zeros_like(np.asarray(xi, dtype=np.float64))
    for i, x in enumerate(np.asarray(xi, dtype=np.float64).ravel()):
        a = x * length
        b = length - a
        if a <= 1e-12 * length or b <= 1e-12 * length:
            continue
        ka = stiffness_matrix(rail, a)
        kb = stiffness_matrix(rail, b)
        # middle node (w, θ), both ends clamped
        k = ka[2:, 2:] + kb[:2, :2]
        out.flat[i] = np.linalg.solve(k, np.array([1.0, 0.0]))[0]
    return out


def shear_force(rail: RailSection, length: float, u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Q = κGA·(w' − θ) = 12EI/(L²(1+φ))·((w2 − w1)/L − (θ1 + θ2)/2): constant along the element.

    ``u`` has the element's four dofs on its first axis.
    """
    L = length
    phi = shear_ratio(rail, L)
    a = 12.0 * rail.bending_stiffness / (L * L * (1.0 + phi))
    return a * ((u[2] - u[0]) / L - 0.5 * (u[1] + u[3]))
