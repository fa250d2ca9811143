"""The calibration's estimator and identifiability (``sim_core.calibration``), on records made
by its own forward model at a known track with known noise, and on Fisher matrices whose
answer is known in closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_core.calibration.estimator import calibrate
from sim_core.calibration.forward import Wheel, predict_channels
from sim_core.calibration.identifiability import analyse
from sim_core.calibration.parameters import scaled
from sim_core.calibration.residuals import Passage, Site, noise_sigma
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.diagnosis.sensor import SensorModel
from sim_core.materials import Material, derive
from sim_core.track.spec import Crib, Support, TrackSpec

NOMINAL = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.4, pad=Support(6e7, 2.0e4))
CRIBS = (Crib("c1", 1.1, 1.5), Crib("c2", 1.7, 2.1), Crib("c3", 2.3, 2.7))
CHAIN = SensorModel(3000.0, 4)
TRUE_Z = np.array([math.log(0.8), math.log(1.25)])


def _wheel(speed: float, load: float, mass: float, radius: float) -> Wheel:
    d = derive(Material(2.14e11, 0.3), radius=radius, load=load, mass=mass)
    return Wheel(speed, load, mass, ContactModel(ContactLaw.HERTZ, d.contact_coefficient))


def _records(seed: int) -> tuple[list[Passage], list[float]]:
    rng = np.random.default_rng(seed)
    truth = scaled(NOMINAL, TRUE_Z)
    out, sigmas = [], []
    for k, (v, p, m) in enumerate(((42.0, 90e3, 700.0), (36.0, 70e3, 600.0))):
        t = np.arange(0.0, 3.2 / v, 1e-4)
        wheel = _wheel(v, p, m, 0.46)
        clean = predict_channels(truth, wheel, CRIBS, CHAIN, t)
        sigma = 0.01 * p
        out.append(Passage(f"w{k}", wheel, t, clean + rng.normal(0.0, sigma, clean.shape)))
        sigmas.append(sigma)
    return out, sigmas


@pytest.fixture(scope="module")
def fitted() -> tuple[object, list[float]]:
    passages, sigmas = _records(7)
    return calibrate(NOMINAL, passages, Site(CRIBS, CHAIN)), sigmas


def test_the_estimator_finds_the_track_that_made_the_records(fitted: tuple) -> None:
    est, sigmas = fitted
    # the pad's stiffness 0.8 x nominal and damping 1.25 x, from 2 fast wheels at 1 % noise
    for i, z_true in enumerate(TRUE_Z):
        assert abs(est.z[i] - z_true) < 3.0 * est.sd[i] + 0.01, (est.names[i], est.z, est.sd)
        lo, hi = est.interval(i)
        assert lo <= est.nominal[i] * math.exp(z_true) <= hi
    assert abs(est.estimate[0] / (0.8 * 6e7) - 1.0) < 0.03
    assert est.identifiability.identifiable[0] == "yes"
    # the noise is found from the records, and the calibrated track explains them to it
    for s_est, s_true in zip(est.sigma, sigmas, strict=True):
        assert abs(s_est / s_true - 1.0) < 0.05
    assert max(est.rms_calibrated) < 1.02
    assert max(est.rms_nominal) > max(est.rms_calibrated)


def test_noise_sigma_is_robust_to_a_few_outliers() -> None:
    rng = np.random.default_rng(3)
    r = rng.normal(0.0, 1.0, 50_000)
    r[:1000] = 40.0  # 2 % of the samples far off: the median shifts by about 2.5 % of σ
    assert abs(noise_sigma(r) - 1.0) < 0.06


def test_a_product_the_data_cannot_see_is_reported_as_such() -> None:
    # the channels depend on k/m only: J has equal and opposite columns
    j = np.array([[10.0, -10.0], [20.0, -20.0]])
    a = analyse(j.T @ j, 0.2, ("k", "m"))
    assert a.identifiable == ("partly", "partly")  # each marginal: 1/sqrt(2) of the prior
    assert [c.label(("k", "m")) for c in a.weak] == ["k·m"]
    assert [c.label(("k", "m")) for c in a.strong] == ["k·m^-1"]
    # ln k - ln m is fixed to sqrt(2)/sqrt(1000): the eigenvalue 1000 along (1, -1)/sqrt(2)
    assert a.strong[0].data_sd == pytest.approx(math.sqrt(2.0 / 1000.0))
    assert math.isinf(a.data_sd[0]) and math.isinf(a.weak[0].data_sd)
    # with the prior (variance 0.04 along each direction): half of each marginal's variance
    # lies along (1, 1), where only the prior holds it, half along (1, -1), data and prior
    expected = math.sqrt(0.5 * 0.04 + 0.5 / (1000.0 + 1.0 / 0.04))
    assert a.posterior_sd[0] == pytest.approx(expected, rel=1e-9)


def test_a_slow_wheel_is_blind_to_the_track() -> None:
    # statically a round wheel's channel is P inside the crib and 0 outside, whatever the track
    wheel = _wheel(2.0, 80e3, 700.0, 0.46)
    t = np.array([0.95, 1.3, 1.6]) / 2.0  # x_C: before crib c1, inside it, between c1 and c2
    soft = predict_channels(scaled(NOMINAL, np.log([0.7, 1.0])), wheel, CRIBS, CHAIN, t)
    hard = predict_channels(scaled(NOMINAL, np.log([1.3, 1.0])), wheel, CRIBS, CHAIN, t)
    assert np.allclose(soft[:, 0] / 80e3, [0.0, 1.0, 0.0], atol=2e-3)
    assert np.allclose(soft[:, 1] / 80e3, [0.0, 0.0, 0.0], atol=2e-3)
    assert np.allclose(hard, soft, atol=2e-3 * 80e3)
