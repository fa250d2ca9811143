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


@pytest.mark.parametrize("tau", [2e-5, 1e-9])
def test_merged_rows_fold_the_pending_part(tau: float) -> None:
    """Rows 6-7 (given ``CO_ROWS`` rows): e^{λτ}·τφ₂ + τ(φ₁ − φ₂), the coefficient of a
    nominal step after one of the same length, against the extended-precision reference."""
    w = 2 * np.pi * np.geomspace(1.0, 2e5, 200)
    lam = np.concatenate([-w * 0.05 + 1j * w, -np.geomspace(1e-1, 1e6, 20) + 0j])
    md = _modes(lam)
    co = np.empty((st.CO_ROWS, lam.size), dtype=st.MODE_DTYPE)
    st.coefficients(md, tau, co)
    ref = _reference(md.lam_r.astype(np.float64) + 1j * md.lam_i.astype(np.float64), tau)
    e = ref[0] + 1j * ref[1]
    merged = e * (ref[4] + 1j * ref[5]) + (ref[2] + 1j * ref[3])
    got = co[6].astype(np.float64) + 1j * co[7].astype(np.float64)
    assert float(np.max(np.abs(got - merged) / np.abs(merged))) < 4 * np.finfo(np.float32).eps
    # and the first six rows are those of a six-row call
    six = np.empty((6, lam.size), dtype=st.MODE_DTYPE)
    st.coefficients(md, tau, six)
    np.testing.assert_array_equal(co[:6], six)


def test_merged_step_equals_the_step_with_its_pending_part() -> None:
    """``predict`` on a nominal step after one of the same length: the merged rows give the
    same prediction as adding the pending τφ₂·R·F to the state first (to single precision)."""
    rng = np.random.default_rng(5)
    m = 64
    lam = -rng.uniform(10, 3e3, m) + 1j * 2 * np.pi * rng.uniform(50, 1.2e4, m)
    md = _modes(lam)
    row_r = rng.normal(size=(4, m)).astype(st.MODE_DTYPE) * 1e-4
    row_i = rng.normal(size=(4, m)).astype(st.MODE_DTYPE) * 1e-4
    wk = np.zeros((st.WORK_ROWS, m), dtype=st.MODE_DTYPE)
    st.coefficients(md, 2e-5, wk[st.CO_NOMINAL : st.CO_NOMINAL + st.CO_ROWS])
    z, p, ha, hb = (st.FIRST_STATE + 2 * k for k in range(4))
    wk[z : z + 2] = rng.normal(size=(2, m)) * 1e-6
    wk[ha : ha + 2] = rng.normal(size=(2, m)) * 1e-4
    n = np.array([0.3, 0.01, 0.7, -0.02])
    force = 9.0e4
    out = {}
    for merged in (True, False):
        sl = st.Slots(z, p, ha, hb, st.CO_NOMINAL + 4)
        w, b = st.predict(0, n, row_r, row_i, wk, st.CO_NOMINAL, sl, force, merged)
        out[merged] = (w, b, wk[p : p + 2].astype(np.float64).copy(), wk[hb : hb + 2].copy())
    (w1, b1, p1, h1), (w0, b0, p0, h0) = out[True], out[False]
    np.testing.assert_array_equal(h1, h0)  # R at the step's end: the same arithmetic
    size = float(np.max(np.abs(p0)))
    assert float(np.max(np.abs(p1 - p0))) < 1e-5 * size
    assert abs(w1 - w0) < 1e-5 * float(np.sum(np.abs(p0)) * np.max(np.abs(h0)))
    assert b1 == pytest.approx(b0, rel=1e-6)


def test_exp_cos_sin_polynomials_match_libm_over_their_ranges() -> None:
    """The Taylor polynomials ``coefficients`` takes when every λτ is in range: within two
    double-precision ulps of 1 (4.4e-16) of libm's exp, cos and sin up to the ranges' ends
    (the values are at most e^0.5; the coefficients are kept in single precision)."""
    a = np.linspace(-st.EXP_RANGE, st.EXP_RANGE, 2001)
    b = np.linspace(-st.TRIG_RANGE, st.TRIG_RANGE, 2001)
    got = np.array([st._exp_cos_sin(float(x), float(y)) for x, y in zip(a, b, strict=True)])
    want = np.array([(math.exp(x), math.cos(y), math.sin(y)) for x, y in zip(a, b, strict=True)])
    err = np.abs(got - want) / np.maximum(np.abs(want), 1.0)
    assert float(err.max()) <= 2 * np.spacing(1.0)


@pytest.mark.parametrize("tau", [2e-5, 1e-5])
def test_coefficients_in_range_take_the_polynomials_and_match(tau: float) -> None:
    """A 12 kHz track's modes at its steps (every |Re λτ| ≤ EXP_RANGE, |Im λτ| ≤ TRIG_RANGE:
    the vectorised path) against the extended-precision reference, and against the same
    modes with one far mode added (libm's path for all)."""
    rng = np.random.default_rng(2)
    w = 2 * np.pi * np.geomspace(20.0, 1.2e4, 400)
    lam = -w * rng.uniform(1e-3, 0.05, w.size) + 1j * w
    assert np.all(np.abs(lam.real * tau) <= st.EXP_RANGE)
    assert np.all(np.abs(lam.imag * tau) <= st.TRIG_RANGE)
    md = _modes(lam)
    co = np.empty((st.CO_ROWS, lam.size), dtype=st.MODE_DTYPE)
    st.coefficients(md, tau, co)
    ref = _reference(md.lam_r.astype(np.float64) + 1j * md.lam_i.astype(np.float64), tau)
    scale = np.repeat(np.maximum(np.abs(ref[0::2]), np.abs(ref[1::2])), 2, axis=0)
    assert (
        float(np.max(np.abs(co[:6].astype(np.float64) - ref) / scale))
        < 4 * np.finfo(np.float32).eps
    )
    far = _modes(np.concatenate([lam, [-1.0 + 1j * 2 * np.pi * 1e6]]))
    co_far = np.empty((st.CO_ROWS, lam.size + 1), dtype=st.MODE_DTYPE)
    st.coefficients(far, tau, co_far)
    ulps = np.abs(co_far[:, :-1].astype(np.float64) - co.astype(np.float64)) / np.spacing(
        np.abs(co).astype(np.float32)
    ).astype(np.float64)
    assert float(ulps.max()) <= 1.0
