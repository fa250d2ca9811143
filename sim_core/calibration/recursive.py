"""The calibration learned wheel by wheel: a recursive estimate with a limited step and range.

The twin sees round wheels one at a time. Each brings the Jacobian J and residual r of its
channels at the current log-factors z (``sensitivities``); the information the wheels have
brought so far is A (the prior's I/prior_sd² at the start). A wheel updates

    A ← λ·A + JᵀJ,    Δ = A⁻¹·Jᵀr

(recursive least squares: after many wheels, the batch estimate; λ < 1 forgets old wheels
slowly, so that a track that changes with the seasons is followed). Then two limits, so that
one odd wheel cannot move the calibration:

- the step: no log-factor moves by more than ``Limits.max_step`` per wheel;
- the range: no log-factor leaves ±``Limits.max_range`` of the starting values.

    >>> import numpy as np
    >>> s = start(2, prior_sd=0.2)
    >>> s, u = update(s, np.array([[100.0, 0.0], [0.0, 1.0]]), np.array([50.0, 0.0]), Limits())
    >>> [round(v, 4) for v in u.requested], [round(v, 4) for v in s.z], u.clamped
    ([0.4988, 0.0], [0.01, 0.0], True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["FORGET", "Limits", "State", "Update", "start", "update"]

FORGET = 0.999
"""λ: the weight a wheel's information keeps after each later wheel (about 1000 wheels' memory)."""


@dataclass(frozen=True)
class Limits:
    """How far the calibration may move: per wheel, and in all from where it started."""

    max_step: float = 0.01
    """Largest change of any ln(value) per wheel (1 %)."""
    max_range: float = math.log(1.5)
    """Largest |ln(value / starting value)|: within a factor 1.5 of the site file's value."""

    def __post_init__(self) -> None:
        for name in ("max_step", "max_range"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"limits: {name} must be a positive number, got {v!r}")


@dataclass(frozen=True)
class State:
    """Where the calibration stands: the log-factors on the starting values, the information
    (n × n, row-major), the wheels that updated it."""

    z: tuple[float, ...]
    information: tuple[tuple[float, ...], ...]
    wheels: int

    def matrix(self) -> NDArray[np.float64]:
        return np.array(self.information, dtype=np.float64)

    def sd(self) -> tuple[float, ...]:
        """Each log-factor's standard deviation (the information's inverse)."""
        cov = np.linalg.inv(self.matrix())
        return tuple(float(math.sqrt(max(c, 0.0))) for c in np.diag(cov))


@dataclass(frozen=True)
class Update:
    """What one wheel asked for and what it was given."""

    requested: tuple[float, ...]
    applied: tuple[float, ...]
    clamped: bool


def start(n: int, prior_sd: float, z: tuple[float, ...] | None = None) -> State:
    """The state before any wheel: z (zeros: the site file's values) and the prior's information."""
    info = np.eye(n) / prior_sd**2
    return State(tuple(z or (0.0,) * n), tuple(tuple(float(v) for v in row) for row in info), 0)


def update(
    state: State,
    jac: NDArray[np.float64],
    r: NDArray[np.float64],
    limits: Limits,
    forget: float = FORGET,
) -> tuple[State, Update]:
    """One wheel's update (module docstring): ``jac`` the weighted Jacobian of its predicted
    channels in z, ``r`` its weighted residual, both at ``state.z``."""
    a = forget * state.matrix() + jac.T @ jac
    requested = np.linalg.solve(a, jac.T @ r)
    step = np.clip(requested, -limits.max_step, limits.max_step)
    z_old = np.array(state.z)
    z_new = np.clip(z_old + step, -limits.max_range, limits.max_range)
    applied = z_new - z_old
    clamped = bool(np.any(np.abs(applied - requested) > 1e-12))
    new = State(
        tuple(float(v) for v in z_new),
        tuple(tuple(float(v) for v in row) for row in a),
        state.wheels + 1,
    )
    return new, Update(
        tuple(float(v) for v in requested), tuple(float(v) for v in applied), clamped
    )
