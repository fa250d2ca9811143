"""Random rail roughness from a one-sided displacement spectrum, reproducible by seed.

A stationary random profile with one-sided power spectral density S(k)
(m²/(rad/m), k the angular wavenumber in rad/m) is synthesised as a sum of
cosines with random phases:

    y(x) = Σ_j sqrt(2·S(k_j)·Δk_j) · cos(k_j·x + φ_j),   φ_j ~ U(0, 2π)

so that its mean square is Σ S(k_j)Δk_j ≈ ∫ S dk (Δk_j: trapezoidal widths of
the given wavenumber grid). The phases come from ``numpy.random.default_rng(seed)``.

Worked example: a power-law spectrum between wavelengths 1 m and 1 cm sampled
every 1 mm has an rms close to sqrt(∫S dk):

    >>> import numpy as np
    >>> k = np.geomspace(2 * np.pi / 1.0, 2 * np.pi / 0.01, 400)
    >>> S = power_law_psd(k, level=1e-11)
    >>> rail = random_roughness(20.0, 1e-3, k, S, seed=1)
    >>> target = np.sqrt(np.trapezoid(S, k))
    >>> bool(abs(np.std(rail.y) / target - 1.0) < 0.05)
    True
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.rail import RailProfile


def power_law_psd(
    wavenumbers: NDArray[np.float64], level: float, reference: float = 1.0, exponent: float = 3.0
) -> NDArray[np.float64]:
    """S(k) = level·(reference/k)^exponent, one-sided, in m²/(rad/m).

    ``level`` (m²/(rad/m)) is S at k = ``reference`` (rad/m). Exponent 3 is the
    classic slope of measured rail roughness between ~1 cm and ~1 m wavelength
    (a roughness level falling 9 dB per octave of wavenumber).
    """
    k = np.asarray(wavenumbers, dtype=np.float64)
    if not np.all(np.isfinite(k)) or np.any(k <= 0):
        raise ValueError("power-law spectrum: wavenumbers must be positive and finite (rad/m)")
    if not (math.isfinite(level) and level >= 0):
        raise ValueError(f"power-law spectrum: level must be >= 0, got {level!r}")
    if not (math.isfinite(reference) and reference > 0):
        raise ValueError(
            f"power-law spectrum: reference must be positive (rad/m), got {reference!r}"
        )
    return np.asarray(level * (reference / k) ** exponent)


def _widths(k: NDArray[np.float64]) -> NDArray[np.float64]:
    """Trapezoidal widths Δk_j of the grid k (so that Σ S_j Δk_j is the trapezoid rule)."""
    if k.size == 1:
        return np.ones(1)
    w = np.empty(k.size)
    d = np.diff(k)
    w[0] = 0.5 * d[0]
    w[-1] = 0.5 * d[-1]
    w[1:-1] = 0.5 * (d[:-1] + d[1:])
    return w


@numba.njit(cache=True)
def _synthesise(
    n: int, dx: float, k: NDArray[np.float64], amp: NDArray[np.float64], ph: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Σ amp_j cos(k_j x_i + ph_j) on x_i = i·dx by phasor rotation, re-anchored every 512 samples."""
    y = np.zeros(n)
    block = 512
    for j in range(k.size):
        rc = math.cos(k[j] * dx)
        rs = math.sin(k[j] * dx)
        for i0 in range(0, n, block):
            c = math.cos(k[j] * i0 * dx + ph[j])
            s = math.sin(k[j] * i0 * dx + ph[j])
            a = amp[j]
            for i in range(i0, min(i0 + block, n)):
                y[i] += a * c
                c, s = c * rc - s * rs, s * rc + c * rs
    return y


def random_roughness(
    length: float,
    dx: float,
    wavenumbers: NDArray[np.float64],
    psd: NDArray[np.float64],
    seed: int,
) -> RailProfile:
    """A sampled rail of ``length`` (m) every ``dx`` (m), starting at x = 0, from S(k).

    Args:
        length, dx: extent and sample spacing (m).
        wavenumbers: angular wavenumbers k_j (rad/m), strictly increasing, positive.
        psd: one-sided S(k_j) (m²/(rad/m)), >= 0.
        seed: seed of ``numpy.random.default_rng`` (same seed, same rail).

    Wavenumbers beyond the Nyquist limit π/dx are rejected (they would alias).
    """
    if not (math.isfinite(length) and length > 0):
        raise ValueError(f"random roughness: length must be positive (m), got {length!r}")
    if not (math.isfinite(dx) and 0 < dx < length):
        raise ValueError(f"random roughness: dx must lie in (0, length), got {dx!r}")
    k = np.asarray(wavenumbers, dtype=np.float64)
    S = np.asarray(psd, dtype=np.float64)
    if k.ndim != 1 or k.shape != S.shape or k.size == 0:
        raise ValueError(
            f"random roughness: wavenumbers and psd must be 1-D of equal length, got {k.shape}, {S.shape}"
        )
    if not (np.all(np.isfinite(k)) and np.all(k > 0) and np.all(np.diff(k) > 0)):
        raise ValueError(
            "random roughness: wavenumbers must be positive, finite and strictly increasing"
        )
    if not (np.all(np.isfinite(S)) and np.all(S >= 0)):
        raise ValueError("random roughness: psd must be finite and >= 0")
    if k[-1] > math.pi / dx:
        raise ValueError(
            f"random roughness: wavenumber {k[-1]!r} rad/m exceeds the Nyquist limit π/dx = {math.pi / dx!r}"
        )
    rng = np.random.default_rng(seed)
    phases = rng.uniform(0.0, 2.0 * math.pi, k.size)
    amp = np.sqrt(2.0 * S * _widths(k))
    n = math.floor(length / dx + 1e-9) + 1
    y = _synthesise(n, float(dx), k, amp, phases)
    return RailProfile.sampled(np.arange(n) * dx, y)
