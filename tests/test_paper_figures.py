"""The paper's Figs. 3–9 (MODEL.md §6): each figure's facts asserted on the numbers.

The numbers come from ``sim_core.paper`` (full windows: 300 excitation
periods); the pictures are only smoke-tested. Figs. 4 and 6 are at f0 = 270.6 Hz
and 2f0 = 541.2 Hz, where MODEL.md §6 gives the numbers of two independent
solvers; the paper's rounded 280 and 560 Hz are checked as reported facts.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim_core import paper


def test_fig3_cosine_and_flat_spectra() -> None:
    f = paper.fig3().facts
    assert f["cosine_max_over_a"] == pytest.approx(1.0, abs=1e-9)
    assert f["cosine_min_over_a"] == pytest.approx(-1.0, abs=1e-9)
    h = f["cosine_harmonics_over_a"]
    assert h[0] == pytest.approx(0.93, abs=0.005)  # fundamental 0.93a (0.931)
    assert h[1] == pytest.approx(0.155, abs=0.002)  # 2nd harmonic 0.155a
    assert f["flat_depth_m"] == pytest.approx(1e-3, rel=1e-3)
    # the flat's spectrum is nearly flat: 10th wheel harmonic about as large as the 1st
    assert f["flat_10th_over_1st"] == pytest.approx(1.0, abs=0.05)
    assert f["flat_max_over_min_harmonic_1_to_10"] < 1.05


def test_fig4_hertz_on_the_cosine() -> None:
    f = paper.fig4().facts
    assert paper.FREQUENCIES == (56.0, 270.6, 541.2)
    assert f["contact_frequency_hz"] == pytest.approx(270.6, abs=0.05)
    low, res, high = f["56"], f["270.6"], f["541.2"]
    # 56 Hz: the wheel never leaves the rail
    assert low["losses"] == 0 and low["min_delta_m"] > 0.0
    # f0 = 270.6 Hz: high bounces (mm to cm), out of contact most of the time
    assert res["fraction_out_of_contact"] > 0.8
    assert res["early_fraction_out_of_contact"] > 0.8
    assert 1e-3 < res["max_gap_m"] < 1e-1
    # F_max in the first 20 periods: MODEL 22.9P (measured 22.901P). The impacts
    # grow one by one as the undamped resonance builds up (MODEL §7): at 270.603 Hz
    # (f0 unrounded) it is 22.5P, at 280 Hz 33.3P, so the band is ±0.05P.
    assert res["early_peak_force_over_load"] == pytest.approx(22.9, abs=0.05)
    # with the paper's curvature-dependent C (measured 25.47P): tens of P too
    assert 15.0 < f["f0_curvature_stiffness_early_peak_force_over_load"] < 40.0
    # 2f0 = 541.2 Hz: exactly one loss of contact per period, over all 300 periods;
    # F_max = 5.13P (measured 5.1267P over 300 periods, 5.1258P over the first 20)
    assert high["early_losses_per_period"] == [1] * paper.EARLY_PERIODS
    assert high["periods_with_exactly_one_loss"] == paper.PERIODS
    assert high["peak_force_over_load"] == pytest.approx(5.13, abs=0.01)
    # the paper's rounded frequencies, which MODEL §6 also gives: 33.3P at 280 Hz
    # (measured 33.3P), 4.87P and one loss per period at 560 Hz
    assert f["at_280_early_peak_force_over_load"] == pytest.approx(33.3, abs=0.1)
    assert f["at_560_peak_force_over_load"] == pytest.approx(4.87, abs=0.01)
    assert f["at_560_periods_with_exactly_one_loss"] == paper.PERIODS


def test_fig5_johnson_static_curves() -> None:
    f = paper.fig5().facts
    assert f["johnson_force_at_2dy_over_fy"] == pytest.approx(4.00, abs=0.005)
    assert f["final_over_dy"] == pytest.approx(0.268, abs=0.0005)
    # drawn as stated: unloading above loading for 0.86 < δ/δ_Y < 1.36
    assert f["unloading_above_loading_from"] == pytest.approx(0.86, abs=0.01)
    assert f["unloading_above_loading_to"] == pytest.approx(1.36, abs=0.01)


def test_fig6_johnson_vs_hertz_at_2f0() -> None:
    f = paper.fig6().facts
    hertz, j800 = f["hertz"], f["johnson_800"]
    assert hertz["frequency_hz"] == 541.2
    # MODEL §6: Hertz 47.4 % of the time out of contact (measured 47.38 %), F_max =
    # 5.13P above F_Y(800 MPa) = 4.94P, so Johnson yields (150 yield events in 300 periods)
    # and is out of contact slightly longer, ≈ 47.5 % (measured 47.54 %)
    assert hertz["fraction_out_of_contact"] == pytest.approx(0.474, abs=0.001)
    assert hertz["peak_force_over_load"] == pytest.approx(5.13, abs=0.01)
    assert j800["yield_force_over_load"] == pytest.approx(4.94, abs=0.005)
    assert hertz["peak_force_over_load"] > j800["yield_force_over_load"]
    assert j800["yields"] > 0
    assert j800["fraction_out_of_contact"] == pytest.approx(0.475, abs=0.001)
    assert j800["fraction_out_of_contact"] > hertz["fraction_out_of_contact"] + 1e-3
    # Y = 600/700 MPa: Johnson escapes into high bouncing (cm), Hertz stays ~0.1 mm
    assert hertz["max_gap_m"] < 3e-4
    for key in ("johnson_700", "johnson_600"):
        assert f[key]["yields"] > 0
        assert f[key]["max_gap_m"] > 5e-3
        assert f[key]["fraction_out_of_contact"] > 0.8
    # at the paper's rounded 560 Hz: F_max = 4.87P < F_Y, Johnson never yields and
    # both laws give 43.7 %
    assert f["at_560_hertz_800_peak_force_over_load"] == pytest.approx(4.87, abs=0.01)
    assert f["at_560_johnson_800_yields"] == 0
    for law in ("hertz", "johnson"):
        assert f[f"at_560_{law}_800_fraction_out_of_contact"] == pytest.approx(0.437, abs=0.001)


def test_fig7_hertz_perfectly_plastic_static_curves() -> None:
    f = paper.fig7().facts
    assert f["plateau_min_over_fy"] == pytest.approx(1.0, abs=1e-12)
    assert f["plateau_max_over_fy"] == pytest.approx(1.0, abs=1e-12)
    assert f["recovery_over_dy"] == pytest.approx(1.0, abs=1e-12)


def test_fig8_self_sustained_bouncing_and_periodic_dents() -> None:
    f = paper.fig8().facts
    expected = {"600": 0.41e-3, "700": 0.17e-3, "800": 0.07e-3}
    for key, depth in expected.items():
        case = f[key]
        assert case["energy_drift_over_initial_kinetic"] < 1e-5
        depths = np.array(case["dent_depths_m"])
        assert depths.size >= 4  # self-sustained: a dent every bounce
        assert depths.mean() == pytest.approx(depth, rel=0.06)
        assert depths.std() < 1e-3 * depths.mean()  # periodic
        spacing = np.array(case["dent_spacings_m"])
        assert spacing.std() < 1e-3 * spacing.mean()
    assert (
        f["600"]["dent_depths_m"][0] > f["700"]["dent_depths_m"][0] > f["800"]["dent_depths_m"][0]
    )


def test_fig9_compliant_foundation() -> None:
    f = paper.fig9().facts
    assert f["foundation_stiffness_n_per_m"] == pytest.approx(2.31e8, rel=0.005)
    assert f["foundation_mode_hz"]["0.25m"] == pytest.approx(590.0, rel=0.02)
    rigid, heavy, same, light = f["rigid"], f["exact_10m"], f["exact_1m"], f["exact_0.25m"]
    # M = 10m bounces like the rigid case. 300 periods at resonance are chaotic
    # (MODEL.md §7): the count of losses moves by tens of percent and the time in
    # flight by ~0.015 between rtol 1e-9 and 1e-11 (113 vs 127 transitions, 92.6 %
    # vs 91.3 % for the M = 10m case), so compare the time in flight with that
    # spread allowed, and require that the heavy foundation keeps losing contact.
    assert heavy["losses"] > 0
    assert heavy["fraction_out_of_contact"] == pytest.approx(
        rigid["fraction_out_of_contact"], abs=0.04
    )
    # M = m: less time out of contact than rigid. (MODEL says "fewer losses";
    # counted as loss events it has *more* — 99 vs 50 in 300 periods — because
    # its bounces are lower and more frequent; the time in flight is what drops.)
    # Over the whole 300 periods the comparison is chaotic (0.92 vs 0.94 or 0.89 vs
    # 0.95 depending on the 1e-13 s details of one landing), so it is made on the
    # first 20 periods, before the chaos sets in, where it is robust.
    assert same["early_fraction_out_of_contact"] < rigid["early_fraction_out_of_contact"] - 0.05
    # M = 0.25m: the exact constraint's 2nd harmonic drives the ≈ 590 Hz mode: contact lost
    assert light["losses"] > 0 and light["min_delta_m"] < 0.0
    # ... with the profile as the constraint δ > 0 always
    prof = f["profile_0.25m"]
    assert prof["losses"] == 0 and prof["min_delta_m"] > 0.0


def test_make_figures_writes_the_pngs(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from service.cli.figures import make_figures

    paths = make_figures(tmp_path, quick=True)
    names = sorted(p.name for p in paths)
    assert names == sorted([f"fig{i}.png" for i in range(3, 10)] + ["facts.json"])
    for p in paths:
        assert p.stat().st_size > 1000
        if p.suffix == ".png":
            assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
