"""Synthetic detector records (``sim_core.diagnosis.crib_synthetic``) on the demo site's
ballasted track: a round wheel reads its load in a crib and nothing over a sleeper; the
noise is what was asked; a flat's record carries its impact."""

from __future__ import annotations

import numpy as np
import pytest

from schemas.messages import WheelPassage
from service.clients.synthesize import measure_channels, measured_passage
from service.physics.diagnosis import Diagnoser
from service.wire.site import load_site
from sim_core.diagnosis.forward import Flat
from tests.conftest import ROOT

SITE = load_site(ROOT / "examples" / "site.toml")


@pytest.fixture(scope="module")
def diagnoser() -> Diagnoser:
    return Diagnoser(SITE)


def _passage(speed: float) -> WheelPassage:
    return WheelPassage.model_validate(
        {
            "passage_id": "syn-1",
            "train_id": "t",
            "axle_index": 0,
            "side": "right",
            "timestamp": 1.7e9,
            "speed": speed,
            "load": 80e3,
            "mass": 600.0,
            "radius": 0.46,
            "outline": {"kind": "round"},
        }
    )


def test_a_round_wheel_reads_its_load_in_a_crib_and_nothing_over_a_sleeper(
    diagnoser: Diagnoser,
) -> None:
    cs = diagnoser.crib_site
    assert cs is not None
    speed = 20.0
    rec = measure_channels(
        SITE, _passage(speed), None, seed=3, noise=0.0, roughness=0.0, diagnoser=diagnoser
    )
    assert rec.channels.shape == (len(cs.cribs), rec.t.size) and rec.noise_sigma == 0.0
    for i, c in enumerate(cs.cribs):
        mid = 0.5 * (c.x_a + c.x_b) / speed  # the wheel between the gauges: P (MODEL.md §8)
        assert rec.channels[i][np.argmin(abs(rec.t - mid))] == pytest.approx(80e3, rel=0.03)
        far = (c.x_b + 0.35) / speed  # past the crib, over the next support and beyond
        assert abs(rec.channels[i][np.argmin(abs(rec.t - far))]) < 0.03 * 80e3
    assert rec.true_peak_force == pytest.approx(80e3, rel=0.05)


def test_noise_is_as_asked_and_a_flat_shows_its_impact(diagnoser: Diagnoser) -> None:
    p = _passage(25.0)
    quiet = measure_channels(SITE, p, None, seed=5, noise=0.0, roughness=0.0, diagnoser=diagnoser)
    noisy = measure_channels(SITE, p, None, seed=5, noise=0.02, roughness=0.0, diagnoser=diagnoser)
    sigma = float(np.std(noisy.channels - quiet.channels))
    assert sigma == pytest.approx(0.02 * 80e3, rel=0.1)
    flat = Flat.ideal(0.46, 0.05, 1.0)
    m, peak = measured_passage(
        SITE, p.model_copy(update={"passage_id": "syn-2"}), flat, seed=7, diagnoser=diagnoser
    )
    assert m.channels is not None and SITE.detector is not None
    assert set(m.channels) == {c.id for c in SITE.detector.cribs}
    assert peak > 1.8 * 80e3  # a 50 mm fresh flat at 90 km/h: an impact of about 2-3 P
