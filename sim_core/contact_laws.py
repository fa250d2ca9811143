"""Normal contact laws F(δ) of MODEL.md §3, as compiled scalar functions.

Three laws share one calling convention so that the integrator can switch
between them without branching on strings:

- ``HERTZ`` (3.3): F = C·δ^(3/2).
- ``JOHNSON`` (4.1): Hertz up to δ_Y, then Johnson's cavity model
  F = F_Y·(2δ/δ_Y - 1)·[1 + ln(2δ/δ_Y - 1)/(3ϑ_Y)].
- ``HERTZ_PLASTIC`` (5.1): Hertz up to δ_Y, then the plateau F = F_Y.

F = 0 for δ <= 0 (loss of contact): no power of a negative δ is ever taken.
The integrator switches between the elastic and the plastic branch at
δ_Y·(1 ± ε) (``ContactModel.switch_width``; ε = ``YIELD_HYSTERESIS`` for the
Hertzian–perfectly plastic law, docs/repeated_passages.md), so the force it
integrates stays within 1.5·ε of these laws.
In rolling only the loading branch acts (the contact point moves on to
undeformed material); the unloading branches below are for the static curves
of the paper's Figs. 5 and 7.

Worked example: at the paper's static load the Hertz law gives back the load,

    >>> import math
    >>> C = 1.0805e11; d0 = (39240.0 / C) ** (2 / 3)
    >>> round(contact_force(d0, HERTZ, C, 0.0, 0.0, 1.1) / 39240.0, 6)
    1.0

and Johnson's law at twice the yield indentation carries 4.00·F_Y
(MODEL.md §3), whatever F_Y is:

    >>> FY = 81829.0; dY = (FY / C) ** (2 / 3)
    >>> round(contact_force(2 * dY, JOHNSON, C, FY, dY, 1.1) / FY, 2)
    4.0
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.materials import DerivedQuantities

HERTZ = 0
JOHNSON = 1
HERTZ_PLASTIC = 2

YIELD_HYSTERESIS = 3e-5
"""Relative half-width ε of the elastic/plastic switch (``ContactModel.yield_hysteresis``).

The integrator enters the plastic branch when δ rises through δ_Y·(1 + ε) and
leaves it when δ falls through δ_Y·(1 - ε), so the force it applies stays
within 1.5·ε of the law: Hertz up to at most C·(δ_Y(1 + ε))^(3/2) ≈ F_Y·(1 + 1.5ε),
F_Y down to δ_Y(1 - ε) where Hertz gives F_Y·(1 - 1.5ε). At ε = 3e-5 that is
4.5e-5 of F_Y (the accuracy target is 1e-4) and 2.5 nm of the paper's
δ_Y = 83 µm (Y = 600 MPa), below the 66 nm chord error of the dent lattice.
Why it is wider than round-off: on a shaken-down dented rail an identical wheel
rides at δ = δ_Y to within the lattice's few nm (docs/repeated_passages.md);
with ε = 1e-7 it crossed the switch 386 times a wheel, with ε = 3e-5 8 times.
"""

SWITCH_FLOOR = 1e-14
"""Least half-width (m) of the switch, whatever ε: the state is put 1e-15 m past a
switching surface after an event, and the step's own error is ~1e-14 m (MODEL.md §5; on a
discrete or slab track ~1e-10 m, the modes being single precision: ``sim_core.track.stepper``,
where a yield placed within that of a peak gives one yield/unyield pair or none)."""


class ContactLaw(IntEnum):
    """The contact laws by the integer code the compiled code uses."""

    HERTZ = HERTZ
    JOHNSON = JOHNSON
    HERTZ_PLASTIC = HERTZ_PLASTIC

    @classmethod
    def from_name(cls, name: str) -> ContactLaw:
        """``"hertz"``, ``"johnson"`` or ``"hertz_plastic"`` (CONTRACT.md names)."""
        try:
            return {"hertz": cls.HERTZ, "johnson": cls.JOHNSON, "hertz_plastic": cls.HERTZ_PLASTIC}[
                name
            ]
        except KeyError:
            raise ValueError(
                f"unknown contact law {name!r}: expected 'hertz', 'johnson' or 'hertz_plastic'"
            ) from None

    @property
    def is_plastic(self) -> bool:
        return self is not ContactLaw.HERTZ


@dataclass(frozen=True)
class ContactModel:
    """A contact law with its constants: what the integrator needs of §3.

    ``yield_force``/``yield_indentation`` are ignored (may be 0) for Hertz.
    ``yield_hysteresis`` is the switch's relative half-width ε: the integrated force
    stays within 1.5·ε·F_Y of the law. None (the default) takes ``YIELD_HYSTERESIS``
    for the Hertzian–perfectly plastic law, whose dented rails a wheel rides along at
    δ_Y, and 0 for Johnson's (it leaves no dents); 0 leaves only the round-off width
    ``SWITCH_FLOOR``.
    """

    law: ContactLaw
    coefficient: float
    yield_force: float = 0.0
    yield_indentation: float = 0.0
    johnson_coefficient: float = 1.1
    yield_hysteresis: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.coefficient) and self.coefficient > 0):
            raise ValueError(f"contact coefficient must be positive, got {self.coefficient!r}")
        if not (math.isfinite(self.johnson_coefficient) and self.johnson_coefficient > 0):
            raise ValueError(
                f"johnson_coefficient must be positive and finite, got {self.johnson_coefficient!r}"
            )
        eps = self.yield_hysteresis
        if eps is not None and not (math.isfinite(eps) and 0.0 <= eps <= 1e-3):
            raise ValueError(
                f"yield_hysteresis is the switch's relative half-width: need 0 <= ε <= 1e-3 "
                f"(the force then stays within 1.5·ε·F_Y of the law), got {self.yield_hysteresis!r}"
            )
        if not self.law.is_plastic:
            return
        f_y, d_y = self.yield_force, self.yield_indentation
        if not (math.isfinite(f_y) and f_y > 0 and math.isfinite(d_y) and d_y > 0):
            raise ValueError(
                f"contact law {self.law.name.lower()} needs a positive yield force and "
                f"yield indentation, both finite (got {f_y!r} N, {d_y!r} m): give the material a yield_stress"
            )
        # The laws of MODEL.md §3 are continuous at δ_Y: F_Y = C·δ_Y^(3/2).
        if abs(self.coefficient * d_y**1.5 / f_y - 1.0) > 1e-9:
            raise ValueError(
                f"yield force {f_y!r} N and yield indentation {d_y!r} m disagree: "
                f"C·δ_Y^(3/2) = {self.coefficient * d_y**1.5!r} N (use materials.derive)"
            )

    @classmethod
    def from_derived(cls, law: ContactLaw, derived: DerivedQuantities) -> ContactModel:
        """The model of ``law`` with C, F_Y, δ_Y (and ϑ_Y) from ``materials.derive``."""
        return cls(
            law,
            derived.contact_coefficient,
            derived.yield_force or 0.0,
            derived.yield_indentation or 0.0,
        )

    @property
    def switch_width(self) -> float:
        """Half-width (m) of the elastic/plastic switch: ε·δ_Y, at least ``SWITCH_FLOOR``.

        The paper's wheel at Y = 600 MPa (δ_Y = 83.08 µm), Hertzian–perfectly plastic
        with the default ε = 3e-5: 2.49 nm; the integrator yields at δ_Y + 2.49 nm and
        unyields at δ_Y - 2.49 nm.
        """
        eps = self.yield_hysteresis
        if eps is None:
            eps = YIELD_HYSTERESIS if self.law == ContactLaw.HERTZ_PLASTIC else 0.0
        return max(eps * self.yield_indentation, SWITCH_FLOOR)

    def force(self, delta: NDArray[np.float64] | float) -> NDArray[np.float64]:
        """Loading-branch force for an array of indentations (vectorised)."""
        d = np.atleast_1d(np.asarray(delta, dtype=np.float64))
        return force_array(
            d,
            int(self.law),
            self.coefficient,
            self.yield_force,
            self.yield_indentation,
            self.johnson_coefficient,
        )


@numba.njit(cache=True, inline="always")
def johnson_plastic_force(delta: float, f_y: float, d_y: float, theta_y: float) -> float:
    """Johnson's cavity-model loading force (valid for δ >= δ_Y; guarded below)."""
    s = 2.0 * delta / d_y - 1.0
    if s < 1e-300:
        s = 1e-300
    return f_y * s * (1.0 + math.log(s) / (3.0 * theta_y))


@numba.njit(cache=True)
def contact_force(
    delta: float, law: int, c: float, f_y: float, d_y: float, theta_y: float
) -> float:
    """Loading-branch force of any law at indentation δ (MODEL.md §3).

    With a yield law the Hertz branch is capped at F_Y: δ_Y = (F_Y/C)^(2/3) is itself rounded,
    and C·δ_Y^1.5 can come out a few ulp above F_Y (5 ulp at Y = 300 MPa on the paper's wheel),
    so the law would dip by them where it turns plastic; capped, it never decreases. (The
    integrator's fixed-branch ``mode_force`` keeps Hertz beyond δ_Y by design.)"""
    plastic = law != HERTZ and delta > d_y
    f = mode_force(delta, plastic, law, c, f_y, d_y, theta_y)
    if law != HERTZ and not plastic and f > f_y:
        return f_y
    return f


@numba.njit(cache=True, inline="always")
def mode_force(
    delta: float, plastic: bool, law: int, c: float, f_y: float, d_y: float, theta_y: float
) -> float:
    """Force of the branch the integrator is in, without testing δ against δ_Y.

    Inside one integration step the branch is fixed (switches are located as
    events), so the right-hand side stays smooth across the step: the elastic
    branch continues Hertz slightly above δ_Y, the plastic branch continues its
    own formula slightly below it.
    """
    if delta <= 0.0:
        return 0.0
    if not plastic:
        return c * delta * math.sqrt(delta)
    if law == JOHNSON:
        return johnson_plastic_force(delta, f_y, d_y, theta_y)
    return f_y


@numba.njit(cache=True, inline="always")
def mode_stiffness(
    delta: float, plastic: bool, law: int, c: float, f_y: float, d_y: float, theta_y: float
) -> float:
    """dF/dδ of the branch ``mode_force`` evaluates (0 for δ <= 0 and on the plateau)."""
    if delta <= 0.0:
        return 0.0
    if not plastic:
        return 1.5 * c * math.sqrt(delta)
    if law == JOHNSON:
        s = 2.0 * delta / d_y - 1.0
        if s < 1e-300:
            s = 1e-300
        th3 = 3.0 * theta_y
        return f_y * (2.0 / d_y) * (1.0 + math.log(s) / th3 + 1.0 / th3)
    return 0.0


@numba.njit(cache=True)
def force_array(
    delta: NDArray[np.float64], law: int, c: float, f_y: float, d_y: float, theta_y: float
) -> NDArray[np.float64]:
    out = np.empty_like(delta)
    for i in range(delta.size):
        out[i] = contact_force(delta[i], law, c, f_y, d_y, theta_y)
    return out


@numba.njit(cache=True)
def contact_potential(
    delta: float, law: int, c: float, f_y: float, d_y: float, theta_y: float
) -> float:
    """∫_0^δ F dδ' of the loading branch: the contact's stored energy (for energy checks)."""
    if delta <= 0.0:
        return 0.0
    if law == HERTZ or delta <= d_y:
        return 0.4 * c * delta * delta * math.sqrt(delta)
    e_y = 0.4 * c * d_y * d_y * math.sqrt(d_y)
    if law == HERTZ_PLASTIC:
        return e_y + f_y * (delta - d_y)
    # Johnson: with s = 2δ/δ_Y - 1, dδ = δ_Y/2 ds, F = F_Y s (1 + ln s / (3ϑ)).
    # ∫_1^s s'(1 + ln s'/(3ϑ)) ds' = (s²-1)/2 + (s² ln s / 2 - (s²-1)/4)/(3ϑ)
    s = 2.0 * delta / d_y - 1.0
    integral = 0.5 * (s * s - 1.0) + (0.5 * s * s * math.log(s) - 0.25 * (s * s - 1.0)) / (
        3.0 * theta_y
    )
    return e_y + f_y * 0.5 * d_y * integral


def johnson_unloading(
    delta: NDArray[np.float64], delta_c: float, f_y: float, d_y: float, c: float, theta_y: float
) -> tuple[NDArray[np.float64], float, float]:
    """Hertzian unloading from the maximum indentation δ_c of Johnson's loading (Fig. 5).

    Returns (F(δ), δ_r, δ_f) with recovery δ_r = δ_Y·sqrt(2δ_c/δ_Y - 1) and final
    (permanent) indentation δ_f = δ_c - δ_r; F = F_c·((δ - δ_f)/δ_r)^(3/2) on
    δ_f <= δ <= δ_c and 0 below δ_f.
    """
    if delta_c <= d_y:
        raise ValueError(f"unloading starts in the plastic range: need δ_c > δ_Y, got {delta_c}")
    f_c = contact_force(delta_c, JOHNSON, c, f_y, d_y, theta_y)
    d_r = d_y * math.sqrt(2.0 * delta_c / d_y - 1.0)
    d_f = delta_c - d_r
    x = np.clip((np.asarray(delta, dtype=np.float64) - d_f) / d_r, 0.0, None)
    return f_c * x**1.5, d_r, d_f


def hertz_plastic_unloading(
    delta: NDArray[np.float64], delta_c: float, f_y: float, d_y: float
) -> tuple[NDArray[np.float64], float, float]:
    """Unloading of the Hertzian–perfectly plastic law from δ_c > δ_Y (Fig. 7).

    Recovery δ_r = δ_Y for any δ_c, so F = F_Y·((δ - δ_f)/δ_Y)^(3/2) with δ_f = δ_c - δ_Y.
    """
    if delta_c <= d_y:
        raise ValueError(f"unloading starts in the plastic range: need δ_c > δ_Y, got {delta_c}")
    d_f = delta_c - d_y
    x = np.clip((np.asarray(delta, dtype=np.float64) - d_f) / d_y, 0.0, None)
    return f_y * x**1.5, d_y, d_f
