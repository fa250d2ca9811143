"""The exact rigid constraint y_C^k of MODEL.md §2: numbers against closed forms and brute force."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from sim_core.constraint import (
    amplitude_spectrum,
    curvature_stiffness_scale,
    evaluate_exact,
    flat_constraint,
    profile_constraint,
    tabulate_constraint,
)
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from sim_core.wheel_roughness import bundled_measurement, load_wheel_roughness

R = 0.475
A = 1e-4
LAM = 0.05


def brute_round_polyline(
    rail: RailProfile, x: NDArray[np.float64], half: float = 0.03, dp: float = 2e-7
) -> NDArray[np.float64]:
    """max over a dense p grid plus every vertex of y_r(p) + sqrt(R² - (p - x)²) - R (numpy, slow)."""
    out = np.empty(x.size)
    for i, xc in enumerate(x):
        p = np.concatenate(
            (np.arange(xc - half, xc + half, dp), rail.x[np.abs(rail.x - xc) < half])
        )
        u = p - xc
        out[i] = np.max(rail.height(p) - u * u / (R + np.sqrt(R * R - u * u)))
    return out


# ------------------------------------------------------------------------------ MODEL §2 reference
def test_round_wheel_on_cosine_reference() -> None:
    t = tabulate_constraint(WheelOutline.round(R), RailProfile.cosine(A, LAM), 0.0, 1.0)
    assert t.period == LAM and t.kinks.size == 0
    xs = np.linspace(0.0, LAM, 200001)
    y = t.evaluate(xs)
    assert abs(y.max() - A) < 1e-12 and abs(y.min() + A) < 1e-12
    amp = amplitude_spectrum(t, 0.0, LAM, 4)
    assert amp[1] / A == pytest.approx(0.93, rel=5e-3)
    assert amp[2] / A == pytest.approx(0.155, rel=5e-3)
    # the node values are the exact ones; the table agrees with the direct solution between nodes
    yd, _ = evaluate_exact(WheelOutline.round(R), RailProfile.cosine(A, LAM), t.x)
    assert np.abs(yd - t.y).max() < 1e-15
    xm = np.random.default_rng(0).uniform(0, 3 * LAM, 500)
    yd, _ = evaluate_exact(WheelOutline.round(R), RailProfile.cosine(A, LAM), xm)
    assert np.abs(yd - t.evaluate(xm)).max() < 1e-12
    # slopes: the envelope theorem, y' = (x_D - x)/sqrt(R² - (x_D - x)²)
    u = t.contact_x - t.x
    np.testing.assert_allclose(t.slope_left, u / np.sqrt(R * R - u * u), atol=1e-9)


def test_round_wheel_on_flat_rail_is_zero() -> None:
    t = tabulate_constraint(WheelOutline.round(R), RailProfile.flat(), 0.0, 6.0)
    assert np.all(t.y == 0) and t.kinks.size == 0 and t.period > 0
    assert float(t.evaluate(np.array([4.2]))[0]) == 0.0
    assert float(flat_constraint().evaluate(np.array([-7.0]))[0]) == 0.0


@pytest.mark.parametrize("phase", [0.0, 1.0])
def test_ideal_flat_on_flat_rail(phase: float) -> None:
    w = WheelOutline.ideal_flat(R, 0.0616)
    th0 = w.flat_half_angle
    assert abs(w.max_depth - 1e-3) < 1e-6
    t = tabulate_constraint(w, RailProfile.flat(), 0.0, 6.0, phase=phase)
    assert t.period == pytest.approx(2 * np.pi * R, rel=1e-15)
    # kink at the flat's centre: φ = φ0 + x/R = 0 mod 2π
    xk = 0.0 if phase == 0.0 else R * (2 * np.pi - phase)
    assert t.kinks.size == 1 and abs(t.kinks[0] - xk) < 1e-10
    i = int(np.searchsorted(t.x, t.kinks[0]))
    assert t.slope_left[i] == pytest.approx(-math.sin(th0), rel=1e-12)
    assert t.slope_right[i] == pytest.approx(math.sin(th0), rel=1e-12)
    # closed form everywhere (table interpolation included)
    x = np.random.default_rng(1).uniform(0.0, 6.0, 20000)
    x = np.concatenate((x, xk + np.linspace(-0.04, 0.04, 8001)))
    phi = phase + x / R
    phw = phi - 2 * np.pi * np.floor((phi + np.pi) / (2 * np.pi))
    ref = np.where(np.abs(phw) < th0, R * np.cos(np.abs(phw) - th0) - R, 0.0)
    assert np.abs(t.evaluate(x) - ref).max() < 1e-12
    # the general ψ-search gives the same table and kink
    g = tabulate_constraint(w, RailProfile.flat(), 0.0, 6.0, phase=phase, method="general")
    assert g.kinks.size == 1 and abs(g.kinks[0] - xk) < 1e-10
    assert np.abs(g.evaluate(x) - ref).max() < 1e-12


def test_ideal_flat_spectrum_is_broad() -> None:
    w = WheelOutline.ideal_flat(R, 0.0616)
    t = tabulate_constraint(w, RailProfile.flat(), 0.0, 6.0)
    amp = amplitude_spectrum(t, 0.0, t.period, 20)
    ratio = amp[10] / amp[1]
    print(f"ideal flat 61.6 mm: 10th/1st wheel harmonic = {ratio:.3f}")
    assert 0.7 < ratio < 1.4


def test_rounded_flat_concave_middle_has_a_kink() -> None:
    ln = 0.05
    # d = l²/16R exceeds l²/(2π²R): concave in the middle, the wheel bridges it
    concave = WheelOutline.rounded_flat(R, ln, ln * ln / (16 * R))
    t = tabulate_constraint(concave, RailProfile.flat(), 0.0, 1.0)
    assert t.kinks.size == 1 and abs(t.kinks[0]) < 1e-10
    i = int(np.searchsorted(t.x, t.kinks[0]))
    assert t.slope_left[i] < -1e-3 and t.slope_right[i] > 1e-3
    x = np.random.default_rng(2).uniform(-0.06, 0.06, 3000) % t.period
    yd, _ = evaluate_exact(concave, RailProfile.flat(), x)
    assert np.abs(yd - t.evaluate(x)).max() < 1e-12
    # shallower than l²/(2π²R): convex everywhere, no kink
    convex = WheelOutline.rounded_flat(R, ln, 0.8 * ln * ln / (2 * np.pi**2 * R))
    assert tabulate_constraint(convex, RailProfile.flat(), 0.0, 1.0).kinks.size == 0


@pytest.mark.parametrize("h", [1e-3, -1e-3])
def test_round_wheel_on_step(h: float) -> None:
    pos = 1.0
    t = tabulate_constraint(WheelOutline.round(R), RailProfile.step(h, pos), 0.0, 2.0)
    x = np.linspace(0.9, 1.1, 40001)
    u = pos - x
    pivot = np.sqrt(R * R - u * u) - R  # the centre above the corner
    if h > 0:
        ref = np.where(x < pos, np.maximum(0.0, h + pivot), h)
        xk = pos - math.sqrt(2 * R * h - h * h)
    else:
        ref = np.where(x < pos, 0.0, np.maximum(h, pivot))
        xk = pos + math.sqrt(-2 * R * h - h * h)
    assert np.abs(t.evaluate(x) - ref).max() < 1e-12
    assert t.kinks.size == 1 and abs(t.kinks[0] - xk) < 1e-12
    # the contact point sits on the corner while the wheel pivots
    lo, hi = min(xk, pos), max(xk, pos)
    pivoting = (t.x > lo + 1e-9) & (t.x < hi - 1e-9)
    assert pivoting.sum() > 10 and np.all(t.contact_x[pivoting] == pos)


def test_random_sampled_rail_against_brute_force() -> None:
    rng = np.random.default_rng(5)
    x = np.arange(0.0, 0.5, 1e-3)
    y = np.cumsum(rng.normal(0.0, 5e-6, x.size))
    rail = RailProfile.sampled(x, y - y.mean())
    t = tabulate_constraint(WheelOutline.round(R), rail, 0.05, 0.45)
    assert t.kinks.size > 5
    nodes = rng.choice(np.flatnonzero((t.x > 0.06) & (t.x < 0.44)), 40, replace=False)
    bf = brute_round_polyline(rail, t.x[nodes])
    assert np.abs(bf - t.y[nodes]).max() < 1e-12
    # Hermite interpolation between nodes
    xm = rng.uniform(0.06, 0.44, 40)
    assert np.abs(brute_round_polyline(rail, xm) - t.evaluate(xm)).max() < 1e-10
    # every kink is a jump of the contact point, and the general ψ-search agrees
    g = tabulate_constraint(WheelOutline.round(R), rail, 0.05, 0.45, method="general")
    xq = rng.uniform(0.06, 0.44, 2000)
    assert np.abs(g.evaluate(xq) - t.evaluate(xq)).max() < 1e-11
    assert (
        np.abs(
            np.sort(g.kinks[(g.kinks > 0.06) & (g.kinks < 0.44)])
            - np.sort(t.kinks[(t.kinks > 0.06) & (t.kinks < 0.44)])
        ).max()
        < 1e-9
    )


def test_measured_wheel_on_flat_rail() -> None:
    w = load_wheel_roughness(bundled_measurement("flat_0p3_01.dat")).to_outline()
    t = tabulate_constraint(w, RailProfile.flat(), 0.0, 1.0)
    assert t.period == pytest.approx(2 * np.pi * w.nominal_radius)
    assert t.kinks.size > 10
    # the wheel bridges most of the narrow dip: it sinks, but by less than the dip is deep
    assert -w.max_depth < t.y.min() < -0.1 * w.max_depth and t.y.max() <= w.max_excess + 1e-15
    x = np.random.default_rng(3).uniform(0, t.period, 300)
    yd, _ = evaluate_exact(w, RailProfile.flat(), x)
    assert np.abs(yd - t.evaluate(x)).max() < 1e-12


# ------------------------------------------------------------------------------ properties
@settings(max_examples=25, deadline=None)
@given(
    heights=st.lists(st.floats(-2e-4, 2e-4), min_size=5, max_size=30),
    spacing=st.floats(5e-4, 5e-3),
    offset=st.floats(-1e-2, 1e-2),
)
def test_round_wheel_properties(heights: list[float], spacing: float, offset: float) -> None:
    x = np.arange(len(heights)) * spacing
    rail = RailProfile.sampled(x, np.array(heights))
    t = tabulate_constraint(WheelOutline.round(R), rail, 0.0, float(x[-1]))
    xq = np.linspace(t.x[0], t.x[-1], 997)
    yk = t.evaluate(xq)
    # the wheel rests on or above the rail under its centre
    assert np.all(yk >= rail.height(xq) - 1e-12)
    # adding a constant to the rail lifts the constraint by exactly it
    lifted = RailProfile.sampled(x, np.array(heights) + offset)
    t2 = tabulate_constraint(WheelOutline.round(R), lifted, 0.0, float(x[-1]))
    assert np.abs(t2.evaluate(xq) - yk - offset).max() < 1e-12
    # a kink where two nearly parallel pieces cross (a 1e-9 m bump) is located to ~1e-11 m only
    assert t2.kinks.shape == t.kinks.shape and np.allclose(t2.kinks, t.kinks, rtol=0, atol=1e-9)


# ------------------------------------------------------------------------------ options
def test_profile_constraint() -> None:
    c = profile_constraint(RailProfile.cosine(A, LAM), 0.0, 1.0)
    xq = np.linspace(0, 0.2, 1001)
    assert np.abs(c.evaluate(xq) - A * np.cos(2 * np.pi * xq / LAM)).max() < 1e-13
    np.testing.assert_allclose(c.contact_point(xq), xq, atol=1e-15)
    amp = amplitude_spectrum(c, 0.0, LAM, 3)
    assert amp[1] == pytest.approx(A, rel=1e-9) and amp[2] < 1e-12
    rail = RailProfile.sampled(np.array([0.0, 0.1, 0.2, 0.3]), np.array([0.0, 1e-4, 0.0, 0.0]))
    s = profile_constraint(rail, 0.0, 0.3)
    np.testing.assert_allclose(s.evaluate(xq), rail.height(xq), atol=1e-18)
    assert s.kinks.tolist() == [0.0, 0.1, 0.2]
    with pytest.raises(ValueError, match="discontinuous"):
        profile_constraint(RailProfile.step(1e-3, 0.0), 0.0, 1.0)


def test_curvature_stiffness_scale() -> None:
    flat = tabulate_constraint(WheelOutline.round(R), RailProfile.flat(), 0.0, 1.0)
    assert np.all(curvature_stiffness_scale(flat, RailProfile.flat(), R) == 1.0)
    rail = RailProfile.cosine(A, LAM)
    t = tabulate_constraint(WheelOutline.round(R), rail, 0.0, 1.0)
    s = curvature_stiffness_scale(t, rail, R)
    assert s.shape == t.x.shape and np.all(s > 0)
    crest = int(np.argmin(np.abs(t.contact_x)))
    trough = int(np.argmin(np.abs(t.contact_x - LAM / 2)))
    assert s[crest] < 1.0 < s[trough]  # sharper crest: smaller radius, softer contact
    t2 = dataclasses.replace(t, stiffness_scale=s)
    assert t2.stiffness_scale.size == t.x.size


def test_validation_errors() -> None:
    w, r = WheelOutline.round(R), RailProfile.cosine(A, LAM)
    with pytest.raises(
        ValueError, match=r"x_end must exceed x_start, got x_start=1\.0, x_end=0\.5"
    ):
        tabulate_constraint(w, r, 1.0, 0.5)
    with pytest.raises(ValueError, match=r"dx must be a positive.*-0\.001"):
        tabulate_constraint(w, r, 0.0, 1.0, dx=-1e-3)
    with pytest.raises(ValueError, match=r"method must be"):
        tabulate_constraint(w, r, 0.0, 1.0, method="fast")
    with pytest.raises(ValueError, match=r"not small against R"):
        tabulate_constraint(w, RailProfile.step(0.2, 0.0), 0.0, 1.0)


# ------------------------------------------------------------------------------ speed
def test_timings() -> None:
    rng = np.random.default_rng(11)
    x = np.arange(0.0, 10.0, 1e-4)
    y = np.cumsum(rng.normal(0.0, 1e-6, x.size))
    rail = RailProfile.sampled(x, y - y.mean())
    tabulate_constraint(WheelOutline.round(R), rail, 0.0, 0.1)  # compile
    t0 = time.perf_counter()
    t = tabulate_constraint(WheelOutline.round(R), rail, 0.0, 10.0)
    long_rail = time.perf_counter() - t0
    w = WheelOutline.ideal_flat(R, 0.0616)
    tabulate_constraint(w, RailProfile.flat(), 0.0, 6.0)
    t0 = time.perf_counter()
    tabulate_constraint(w, RailProfile.flat(), 0.0, 6.0)
    flat = time.perf_counter() - t0
    print(
        f"10 m sampled rail at 0.1 mm: {long_rail * 1e3:.0f} ms ({t.x.size} nodes); "
        f"ideal flat on flat rail: {flat * 1e3:.2f} ms"
    )
    assert long_rail < 3.0 and flat < 0.1  # generous: the machine is shared
