"""Harmonic amplitudes of a constraint table (the paper's Fig. 3 check)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.table import ConstraintTable

__all__ = ["amplitude_spectrum"]


def amplitude_spectrum(
    table: ConstraintTable, x_start: float, length: float, n_harmonics: int
) -> NDArray[np.float64]:
    """One-sided harmonic amplitudes of y_C^k over [x_start, x_start + length] (m).

    ``length`` is taken as the fundamental period (λ for a cosine rail, 2πR for
    one wheel turn); returns A[0..n_harmonics], A[0] the mean and A[k] the
    amplitude of the k-th harmonic cos(2πk x/length). Computed from 2^16 (or
    more) samples of the table by FFT.

    >>> from sim_core.constraint.profile import profile_constraint
    >>> from sim_core.rail import RailProfile
    >>> t = profile_constraint(RailProfile.cosine(2e-4, 0.1), 0.0, 1.0)
    >>> [round(v * 1e4, 6) for v in amplitude_spectrum(t, 0.0, 0.1, 2).tolist()]
    [0.0, 2.0, 0.0]
    """
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"amplitude spectrum: length must be positive (m), got {length!r}")
    if n_harmonics < 1:
        raise ValueError(f"amplitude spectrum: n_harmonics must be >= 1, got {n_harmonics!r}")
    n = max(1 << 16, 8 * n_harmonics)
    x = float(x_start) + length * np.arange(n) / n
    c = np.fft.rfft(table.evaluate(x)) / n
    amp = 2.0 * np.abs(c[: n_harmonics + 1])
    amp[0] = abs(c[0].real)
    return np.asarray(amp)
