"""The exact step's coefficients against the same functions in extended precision.

``stepper.coefficients`` gives, per mode, e^{λτ}, τ(φ₁ − φ₂)(λτ) and τφ₂(λτ) with
φ₁(z) = (eᶻ − 1)/z and φ₂(z) = (eᶻ − 1 − z)/z², in single precision (``MODE_DTYPE``). The
reference sums their Taylor series (|z| < 0.5) or takes the closed forms in numpy's long
double (64-bit mantissa on x86), so that its own error stays far below a float32 ulp.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sim_core.track import stepper as st


def _modes(lam: np.ndarray) -> st.Modes:
    m = lam.size
    f = np.zeros((4, m), dtype=st.MODE_DTYPE)
    one = np.zeros(1)
    return st.Modes(
        lam.real.astype(st.MODE_DTYPE),
        lam.imag.astype(st.MODE_DTYPE),
        f,
        f,
        one,
        one,
        one,
        np.zeros((1, 4, 4)),
        np.zeros((1, 2)),
        np.zeros(0),
        np.zeros(0),
        np.zeros((0, m), dtype=st.MODE_DTYPE),
        np.zeros((0, m), dtype=st.MODE_DTYPE),
    )


def _reference(lam: np.ndarray, tau: float) -> np.ndarray:
    out = np.empty((6, lam.size))
    for j, l in enumerate(lam):
        z: Any = np.clongdouble(complex(l)) * np.longdouble(tau)
        if abs(z) < 0.5:  # the series: 30 terms leave < 1e-38
            f1 = np.clongdouble(0)
            f2 = np.clongdouble(0)
            term = np.clongdouble(1)
            for k in range(30):  # z^k / (k+1)! and z^k / (k+2)!
                f1 = f1 + term / np.longdouble(math.factorial(k + 1))
                f2 = f2 + term / np.longdouble(math.factorial(k + 2))
                term *= z
            ez = 1 + z * f1
        else:
            ez = np.exp(z)
            f1 = (ez - 1) / z
            f2 = (ez - 1 - z) / (z * z)
        a = np.longdouble(tau) * (f1 - f2)
        b = np.longdouble(tau) * f2
        out[:, j] = [ez.real, ez.imag, a.real, a.imag, b.real, b.imag]
    return out


@pytest.mark.parametrize("tau", [2e-5, 3.3e-7, 1e-9])
def test_coefficients_match_extended_precision(tau: float) -> None:
    rng = np.random.default_rng(11)
    # the track's modes: lightly damped up to 12 kHz, strongly damped absorber modes, a few
    # real ones; |λτ| from 1e-9 to ~20, both sides of the series' limit
    w = 2 * np.pi * np.geomspace(1.0, 2e5, 300)
    lam = np.concatenate(
        [
            -w * rng.uniform(1e-3, 0.3, w.size) + 1j * w,
            -np.geomspace(1e-1, 1e6, 40) + 0j,
            -(st.SERIES_LIMIT / tau) * np.array([0.5, 0.999, 1.001, 2.0]) * (0.6 + 0.8j),
        ]
    )
    md = _modes(lam)
    co = np.empty((6, lam.size), dtype=st.MODE_DTYPE)
    st.coefficients(md, tau, co)
    # the reference from the same single-precision λ the stepper reads
    ref = _reference(md.lam_r.astype(np.float64) + 1j * md.lam_i.astype(np.float64), tau)
    scale = np.maximum(np.abs(ref[0::2]), np.abs(ref[1::2]))  # each complex number's size
    scale = np.repeat(scale, 2, axis=0)
    err = np.abs(co.astype(np.float64) - ref) / scale
    assert float(err.max()) < 4 * np.finfo(np.float32).eps
