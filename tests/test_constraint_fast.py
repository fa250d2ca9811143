"""The piece sweep (sim_core.constraint.wheel_pieces) against the general ψ-search and brute force."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_core.constraint import evaluate_exact, tabulate_constraint
from sim_core.constraint.table import ConstraintTable
from sim_core.constraint.wheel_pieces import supports
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from sim_core.wheel_roughness import bundled_measurement, load_wheel_roughness

R = 0.475


def measured() -> WheelOutline:
    return load_wheel_roughness(bundled_measurement("flat_0p3_01.dat")).to_outline()


def brute(
    wheel: WheelOutline, rail: RailProfile, x: NDArray[np.float64], phase: float = 0.0
) -> NDArray[np.float64]:
    """max over a dense ψ grid plus every wheel sample (numpy): within ~1e-16 m of the maximum for these outlines."""
    Rn = wheel.nominal_radius
    out = np.empty(x.size)
    for i, xc in enumerate(x):
        phi = phase + xc / Rn
        psi = np.linspace(-0.06, 0.06, 240001)
        if wheel.kind == "sampled":
            t = wheel.theta - phi
            t = (t + np.pi) % (2 * np.pi) - np.pi
            psi = np.concatenate((psi, t[np.abs(t) < 0.06]))
        rho = wheel.radius_at(psi + phi)
        out[i] = np.max(rail.height(xc + rho * np.sin(psi)) + rho * np.cos(psi)) - Rn
    return out


def strong_kinks(t: ConstraintTable, lo: float, hi: float) -> NDArray[np.float64]:
    i = np.searchsorted(t.x, t.kinks)
    big = np.abs(t.slope_right[i] - t.slope_left[i]) > 1e-6
    k = t.kinks[big]
    return np.sort(k[(k > lo) & (k < hi)])


def compare(
    fast: ConstraintTable,
    gen: ConstraintTable,
    lo: float,
    hi: float,
    wheel: WheelOutline,
    rail: RailProfile,
    phase: float = 0.0,
) -> None:
    xq = np.random.default_rng(7).uniform(lo, hi, 20000)
    diff = np.abs(fast.evaluate(xq) - gen.evaluate(xq))
    assert np.quantile(diff, 0.999) < 1e-12 and diff.max() < 1e-11
    # where the two tables differ most, the fast one is the exact one
    worst = xq[np.argsort(diff)[-10:]]
    assert np.abs(brute(wheel, rail, worst, phase) - fast.evaluate(worst)).max() < 1e-12
    # exact node values, and the Hermite table between nodes, against brute force
    yd, _ = evaluate_exact(wheel, rail, fast.x[(fast.x > lo) & (fast.x < hi)][::7], phase=phase)
    assert np.abs(yd - fast.y[(fast.x > lo) & (fast.x < hi)][::7]).max() < 1e-12
    xb = xq[:40]
    assert np.abs(brute(wheel, rail, xb, phase) - fast.evaluate(xb)).max() < 1e-12
    kf, kg = strong_kinks(fast, lo + 1e-3, hi - 1e-3), strong_kinks(gen, lo + 1e-3, hi - 1e-3)
    assert kf.size == kg.size and (kf.size == 0 or np.abs(kf - kg).max() < 1e-9)


def test_measured_wheel_flat_rail() -> None:
    w, rail = measured(), RailProfile.flat()
    fast = tabulate_constraint(w, rail, 0.0, 6.0)
    gen = tabulate_constraint(w, rail, 0.0, 6.0, method="general")
    assert fast.period == pytest.approx(gen.period) and fast.kinks.size > 1000
    compare(fast, gen, 0.0, fast.period, w, rail)


@pytest.mark.parametrize("phase", [0.0, 2.0])
def test_measured_wheel_cosine_rail(phase: float) -> None:
    w, rail = measured(), RailProfile.cosine(2e-6, 0.06)
    fast = tabulate_constraint(w, rail, 1.0, 1.25, phase=phase)
    gen = tabulate_constraint(w, rail, 1.0, 1.25, phase=phase, method="general")
    compare(fast, gen, 1.0, 1.25, w, rail, phase)


def test_rounded_flat_cosine_rail() -> None:
    # a haversine whose concave middle is curved less than the paper's cosine's crests: its
    # middle cells are not certified (sim_core.constraint.cosine_cells), the ψ-search takes the
    # positions where they can carry the wheel (sim_core.constraint.cosine_hybrid, tested in
    # test_constraint_cosine_hybrid.py), the sweep the rest
    w, rail = WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R)), RailProfile.cosine(1e-4, 0.05)
    assert not supports(w, rail) and supports(measured(), RailProfile.cosine(2e-6, 0.06))
    fast = tabulate_constraint(w, rail, -0.05, 0.05)
    gen = tabulate_constraint(w, rail, -0.05, 0.05, method="general")
    xq = np.random.default_rng(3).uniform(-0.05, 0.05, 300)
    assert np.abs(fast.evaluate(xq) - gen.evaluate(xq)).max() < 1e-11


def test_rounded_flat_concave_flat_rail() -> None:
    ln = 0.05
    w, rail = WheelOutline.rounded_flat(R, ln, ln * ln / (16 * R)), RailProfile.flat()
    fast = tabulate_constraint(w, rail, 0.0, 1.0, phase=0.3)
    gen = tabulate_constraint(w, rail, 0.0, 1.0, phase=0.3, method="general")
    compare(fast, gen, 0.0, fast.period, w, rail, 0.3)
    assert strong_kinks(fast, 0.0, fast.period).size == 1


def test_sampled_rail_takes_the_polyline_sweep() -> None:
    # the piece sweep covers flat and cosine rails; a sampled rail takes the polyline sweep
    # (sim_core.constraint.polyline, tested in test_constraint_polyline.py), not the ψ-search
    rng = np.random.default_rng(5)
    x = np.arange(0.0, 0.3, 1e-3)
    y = np.cumsum(rng.normal(0.0, 2e-6, x.size))
    w, rail = measured(), RailProfile.sampled(x, y - y.mean())
    fast = tabulate_constraint(w, rail, 0.1, 0.14)
    gen = tabulate_constraint(w, rail, 0.1, 0.14, method="general")
    assert fast.x.size != gen.x.size
    xq = rng.uniform(0.1, 0.14, 500)
    assert np.abs(fast.evaluate(xq) - gen.evaluate(xq)).max() < 1e-11
