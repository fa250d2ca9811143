"""The site's measuring chain written out (sim_core.diagnosis.sensor) against SciPy's."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from sim_core.diagnosis.sensor import SensorModel


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
@pytest.mark.parametrize(("cutoff", "rate"), [(2000.0, 50_000.0), (4000.0, 100_000.0)])
def test_butterworth_matches_scipy(order: int, cutoff: float, rate: float) -> None:
    """Same response as scipy.signal.butter + sosfilt started in steady state, to round-off,
    on a noisy static load with a short impact."""
    rng = np.random.default_rng(order)
    x = 60e3 + rng.normal(0.0, 1e3, 8000)
    x[3000:3050] += 5e5
    sos = signal.butter(order, cutoff, btype="low", output="sos", fs=rate)
    ref, _ = signal.sosfilt(sos, x, zi=signal.sosfilt_zi(sos) * x[0])
    got = SensorModel(cutoff, order).filter(x, rate)
    assert np.max(np.abs(got - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_static_load_passes_unchanged() -> None:
    """Unit gain at DC, started in steady state: a constant stays that constant."""
    got = SensorModel(3000.0, 4).filter(np.full(500, 106e3), 75_000.0)
    assert np.allclose(got, 106e3, rtol=1e-12, atol=0.0)
