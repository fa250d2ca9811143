"""The weighted residuals' Jacobian in the log-factors, by forward differences.

Changing a track value means a new modal reduction of the track (seconds; the reduction is
``sim_core.track``'s, kept on disk), so the Jacobian costs one reduction and one passage
per parameter and wheel: J[:, i] = (r(z + h·e_i) − r(z)) / h, with the step h = ``STEP``
in ln(value), 5 %: large against the simulation's last bits (the residual is smooth in z),
small against the ±30 % the factors range over. The response is close to linear over that
range (the dynamic load is a few % of P), so the estimator reuses one Jacobian for its
steps (a chord method) and checks each step on the full model.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from sim_core.calibration.parameters import names, scaled
from sim_core.calibration.residuals import Passage, Site, residual
from sim_core.track.spec import TrackSpec

__all__ = ["STEP", "Progress", "jacobian", "residuals"]

STEP = 0.05
"""Forward-difference step in ln(value)."""

Progress = Callable[[str, int, int], None]
"""progress(what, done, total): called after each simulated passage."""


def _quiet(what: str, done: int, total: int) -> None:
    return None


def residuals(
    nominal: TrackSpec,
    z: NDArray[np.float64],
    passages: Sequence[Passage],
    site: Site,
    sigmas: Sequence[float],
    progress: Progress = _quiet,
    what: str = "residuals",
) -> list[NDArray[np.float64]]:
    """Each passage's weighted residual on ``scaled(nominal, z)``."""
    track = scaled(nominal, z)
    out = []
    for k, (p, s) in enumerate(zip(passages, sigmas, strict=True)):
        out.append(residual(track, p, site, s))
        progress(what, k + 1, len(passages))
    return out


def jacobian(
    nominal: TrackSpec,
    z: NDArray[np.float64],
    passages: Sequence[Passage],
    site: Site,
    sigmas: Sequence[float],
    base: Sequence[NDArray[np.float64]],
    progress: Progress = _quiet,
    step: float = STEP,
) -> list[NDArray[np.float64]]:
    """Each passage's Jacobian of the weighted *prediction* (samples·cribs × parameters) at z;
    ``base`` the residuals at z. (The residual's Jacobian is its negative.)"""
    n = len(names(nominal))
    cols: list[list[NDArray[np.float64]]] = [[] for _ in passages]
    for i in range(n):
        zi = np.array(z, dtype=np.float64)
        zi[i] += step
        ri = residuals(nominal, zi, passages, site, sigmas, progress, f"sensitivity {i + 1}/{n}")
        for k, (r0, r1) in enumerate(zip(base, ri, strict=True)):
            cols[k].append((r0 - r1) / step)
    return [np.stack(c, axis=1) for c in cols]
