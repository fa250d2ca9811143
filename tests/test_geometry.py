"""Geometry inputs: wheel outlines, rail profiles, random roughness, the trolley-export loader."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from sim_core.rail import RailProfile
from sim_core.roughness import power_law_psd, random_roughness
from sim_core.wheel import WheelOutline
from sim_core.wheel_roughness import (
    DATA_DIR,
    WheelRoughness,
    bundled_measurement,
    load_wheel_roughness,
)

R = 0.475


# ------------------------------------------------------------------------------ wheel
def test_round_wheel_is_round() -> None:
    w = WheelOutline.round(R)
    th = np.linspace(-10, 10, 101)
    assert np.all(w.radius_at(th) == R)
    assert w.max_depth == 0.0 and w.nominal_radius == R and math.isinf(w.min_feature_length)


def test_ideal_flat_matches_model_section_2() -> None:
    w = WheelOutline.ideal_flat(R, 0.0616)
    d = R - math.sqrt(R**2 - 0.0616**2 / 4)
    th0 = math.asin(0.0616 / (2 * R))
    assert w.max_depth == pytest.approx(d, rel=1e-14)
    assert abs(w.max_depth - 1e-3) < 1e-6  # "d ≈ 1 mm"
    assert w.flat_half_angle == pytest.approx(th0, rel=1e-15)
    th = np.linspace(-th0, th0, 41)
    np.testing.assert_allclose(w.radius_at(th), (R - d) / np.cos(th), rtol=0, atol=1e-15)
    # periodic in 2π, round outside the flat
    np.testing.assert_allclose(w.radius_at(th + 2 * np.pi), w.radius_at(th), atol=1e-15)
    assert np.all(w.radius_at(np.array([th0 + 1e-6, 1.0, -2.0, np.pi])) == R)
    # the flat is a straight chord: r·cos θ is constant on it
    np.testing.assert_allclose(w.radius_at(th) * np.cos(th), R - d, atol=1e-15)


def test_rounded_flat_haversine() -> None:
    ln, d = 0.05, 0.3e-3
    w = WheelOutline.rounded_flat(R, ln, d)
    th = np.linspace(-ln / (2 * R), ln / (2 * R), 31)
    np.testing.assert_allclose(
        w.radius_at(th), R - d / 2 * (1 + np.cos(2 * np.pi * R * th / ln)), atol=1e-16
    )
    assert float(w.radius_at(np.array([0.0]))[0]) == pytest.approx(R - d, abs=1e-16)
    assert w.max_depth == d and w.min_feature_length == ln / 16


def test_sampled_wheel_linear_and_periodic() -> None:
    th = np.linspace(-np.pi, np.pi, 7, endpoint=False)
    rv = R + 1e-4 * np.arange(7)
    w = WheelOutline.sampled(th, rv, nominal_radius=R)
    np.testing.assert_allclose(w.radius_at(th), rv, atol=1e-16)
    mid = 0.5 * (th[1] + th[2])
    assert float(w.radius_at(np.array([mid]))[0]) == pytest.approx(0.5 * (rv[1] + rv[2]), abs=1e-16)
    # the closing segment from the last sample back to the first, a turn later
    tw = 0.5 * (th[-1] + th[0] + 2 * np.pi)
    assert float(w.radius_at(np.array([tw]))[0]) == pytest.approx(0.5 * (rv[-1] + rv[0]), abs=1e-16)
    np.testing.assert_allclose(w.radius_at(th + 4 * np.pi), rv, atol=1e-15)
    assert w.max_depth == 0.0 and w.max_excess == pytest.approx(6e-4)
    # default nominal radius: the mean over the closed turn
    w2 = WheelOutline.sampled(th, np.full(7, 0.46))
    assert w2.nominal_radius == pytest.approx(0.46, rel=1e-15)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: WheelOutline.round(-1.0), r"positive finite.*-1\.0"),
        (lambda: WheelOutline.round(float("nan")), "nan"),
        (lambda: WheelOutline.ideal_flat(R, 1.0), r"shorter than the diameter"),
        (lambda: WheelOutline.ideal_flat(R, 0.0), r"length must be a positive"),
        (lambda: WheelOutline.rounded_flat(R, 3.0, 1e-4), r"does not fit"),
        (lambda: WheelOutline.rounded_flat(R, 0.05, 0.5), r"smaller than the radius"),
        (
            lambda: WheelOutline.sampled(np.array([0.0, 2.0, 1.0]), np.full(3, R)),
            r"strictly increasing.*theta\[1\]",
        ),
        (lambda: WheelOutline.sampled(np.linspace(0, 7, 5), np.full(5, R)), r"less than one turn"),
        (
            lambda: WheelOutline.sampled(np.linspace(0, 1, 5), np.full(4, R)),
            r"equal length.*\(5,\).*\(4,\)",
        ),
        (lambda: WheelOutline.sampled(np.array([0.0, 1.0, np.nan]), np.full(3, R)), r"non-finite"),
        (
            lambda: WheelOutline.sampled(np.array([0.0, 1.0, 2.0]), np.array([R, np.nan, R])),
            r"non-finite",
        ),
    ],
)
def test_wheel_validation(call: object, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        call()  # type: ignore[operator]


# ------------------------------------------------------------------------------ rail
def test_rail_kinds() -> None:
    x = np.array([-1.0, 0.0, 0.0125, 0.025, 1.0])
    np.testing.assert_allclose(
        RailProfile.cosine(1e-4, 0.05).height(x), 1e-4 * np.cos(2 * np.pi * x / 0.05), atol=1e-20
    )
    assert RailProfile.step(2e-3, 0.0).height(x).tolist() == [0.0, 2e-3, 2e-3, 2e-3, 2e-3]
    assert np.all(RailProfile.flat().height(x) == 0.0)
    s = RailProfile.sampled(np.array([0.0, 1.0, 3.0]), np.array([0.0, 1e-3, -1e-3]))
    assert s.height(np.array([-5.0, 0.5, 2.0, 9.0])).tolist() == pytest.approx(
        [0.0, 5e-4, 0.0, -1e-3], abs=1e-18
    )
    assert s.min_feature_length == 1.0
    assert RailProfile.cosine(1e-4, 0.05).min_feature_length == 0.05 / 16
    assert math.isinf(RailProfile.step(1e-3, 0.0).min_feature_length)
    assert s.height_range == (-1e-3, 1e-3)


def test_rail_curvature_of_cosine() -> None:
    r = RailProfile.cosine(1e-4, 0.05)
    k = 2 * np.pi / 0.05
    assert float(r.curvature(np.array([0.0]))[0]) == pytest.approx(1e-4 * k * k, rel=1e-12)


def test_rail_validation() -> None:
    with pytest.raises(ValueError, match=r"strictly increasing; x\[1\] = 1\.0 >= x\[2\] = 1\.0"):
        RailProfile.sampled(np.array([0.0, 1.0, 1.0]), np.zeros(3))
    with pytest.raises(ValueError, match=r"wavelength must be positive.*-0\.05"):
        RailProfile.cosine(1e-4, -0.05)
    with pytest.raises(ValueError, match=r"y\[1\] is not finite"):
        RailProfile.sampled(np.array([0.0, 1.0]), np.array([0.0, np.inf]))
    with pytest.raises(ValueError, match=r"rail kind must be one of"):
        RailProfile("wavy")


def test_rail_from_csv(tmp_path: Path) -> None:
    p = tmp_path / "rail.csv"
    p.write_text("x_m,y_m\n0.0,0.0\n0.5, 1e-4\n\n1.0,0\n", encoding="utf-8")
    r = RailProfile.from_csv(p)
    assert r.x.tolist() == [0.0, 0.5, 1.0] and r.y.tolist() == [0.0, 1e-4, 0.0]
    q = tmp_path / "noheader.csv"
    q.write_text("0 0\n1 1e-3\n", encoding="utf-8")
    assert RailProfile.from_csv(q).y.tolist() == [0.0, 1e-3]
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y\n0.0,0.0\n0.5,oops\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"line 3: expected two numbers.*oops"):
        RailProfile.from_csv(bad)
    back = tmp_path / "back.csv"
    back.write_text("0.0,0.0\n0.5,0.0\n0.4,0.0\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"line 3: x = 0\.4 does not increase"):
        RailProfile.from_csv(back)


# ------------------------------------------------------------------------------ roughness
def test_random_roughness_rms_matches_spectrum() -> None:
    # components Δk apart beat over 2π/Δk: keep that well inside the record (10 m vs 50 m)
    k = np.linspace(2 * np.pi / 0.5, 2 * np.pi / 0.005, 2000)
    S = power_law_psd(k, level=1e-12, reference=2 * np.pi / 0.1, exponent=2.0)
    target = math.sqrt(float(np.trapezoid(S, k)))
    for seed in (1, 2, 3):
        rail = random_roughness(50.0, 1e-3, k, S, seed=seed)
        rms = float(np.sqrt(np.mean(rail.y**2)))
        assert abs(rms / target - 1.0) < 0.03, (seed, rms, target)
    a = random_roughness(1.0, 1e-3, k[:100], S[:100], seed=7)
    b = random_roughness(1.0, 1e-3, k[:100], S[:100], seed=7)
    assert np.array_equal(a.y, b.y) and a.x.size == 1001


def test_random_roughness_matches_direct_sum() -> None:
    k = np.array([10.0, 50.0, 300.0])
    S = np.array([1e-10, 1e-11, 1e-12])
    rail = random_roughness(3.0, 1e-3, k, S, seed=4)
    ph = np.random.default_rng(4).uniform(0, 2 * np.pi, 3)
    w = np.array([20.0, 145.0, 125.0])  # trapezoidal widths of the grid
    direct = (np.sqrt(2 * S * w)[None, :] * np.cos(k[None, :] * rail.x[:, None] + ph[None, :])).sum(
        axis=1
    )
    np.testing.assert_allclose(rail.y, direct, atol=1e-15)


def test_random_roughness_validation() -> None:
    with pytest.raises(ValueError, match="Nyquist"):
        random_roughness(1.0, 1e-2, np.array([1.0, 1000.0]), np.ones(2), seed=0)
    with pytest.raises(ValueError, match="strictly increasing"):
        random_roughness(1.0, 1e-3, np.array([2.0, 1.0]), np.ones(2), seed=0)


# ------------------------------------------------------------------------------ trolley export
@pytest.mark.parametrize("name", ["flat_0p3_01.dat", "flat_0p3_03.dat", "flat_0p4_01.dat"])
def test_loader_parses_bundled_measurements(name: str) -> None:
    m = load_wheel_roughness(bundled_measurement(name))
    assert 2870 <= m.positions.size <= 2890
    assert int(m.header["Measurement points"]) == m.positions.size
    assert m.header["Base Distance"] == "70"
    assert np.all(np.diff(m.positions) > 0) and m.step == pytest.approx(1e-3)
    assert 0.06e-3 <= m.flat_depth <= 0.39e-3
    assert m.circumference == pytest.approx(m.positions.size * 1e-3)
    w = m.to_outline()
    assert w.kind == "sampled" and w.nominal_radius == pytest.approx(m.circumference / (2 * np.pi))
    assert w.theta[-1] - w.theta[0] < 2 * np.pi
    # the flat (deepest point) is at θ = 0
    assert float(w.radius_at(np.array([0.0]))[0]) == pytest.approx(
        w.nominal_radius - m.flat_depth, abs=1e-15
    )
    assert w.max_depth == pytest.approx(m.flat_depth)
    # from_text on the decoded payload gives the same
    m2 = WheelRoughness.from_text((DATA_DIR / name).read_bytes().decode("latin-1"))
    assert np.array_equal(m2.deviations, m.deviations)


def test_loader_rejects_malformed(tmp_path: Path) -> None:
    text = bundled_measurement("flat_0p4_01.dat").read_bytes().decode("latin-1")
    lines = text.splitlines()
    i = lines.index("[MeasurementData]")
    bad = [*lines]
    bad[i + 10] = "8\tabc\t"
    with pytest.raises(
        ValueError, match=rf"line {i + 11}: expected '<position><TAB><deviation>'.*abc"
    ):
        WheelRoughness.from_text("\n".join(bad))
    trunc = "\n".join(lines[: i + 50])
    with pytest.raises(ValueError, match=r"declares 2886 measurement points but the data has 48"):
        WheelRoughness.from_text(trunc)
    with pytest.raises(ValueError, match=r"line 1: expected '\[HEADER\]'"):
        WheelRoughness.from_text("hello\n")
    nodata = "\n".join(lines[:i])
    with pytest.raises(ValueError, match=r"no '\[MeasurementData\]'"):
        WheelRoughness.from_text(nodata)
    p = tmp_path / "x.dat"
    p.write_bytes("\n".join(bad).encode("latin-1"))
    with pytest.raises(ValueError, match=str(p).replace("\\", "\\\\")):
        load_wheel_roughness(p)
