"""The calibration's one-pass crib channel against the NumPy fine-grid computation it replaces.

``crib_chain.crib_channels`` interpolates, adds the force inside each crib, filters and
samples in one loop for all the cribs; ``forward.chain_on_grid`` builds the fine grid's arrays and uses ``np.interp``
and the chain's ``filter``. The two must agree to rounding: within 1e-12 of the load, on a
rough smooth part and force, at the record's instants and beyond both ends of the grid, for
even, odd and no low-pass, at a slow and a fast wheel; and ``predict_channels`` must give
the same channels through either.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.calibration import forward
from sim_core.calibration.crib_chain import crib_channels
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.diagnosis.sensor import SensorModel
from sim_core.materials import Material, derive
from sim_core.track.spec import Crib, Support, TrackSpec

LOAD = 80e3


def _signals(v: float, rng: np.random.Generator) -> tuple[np.ndarray, ...]:
    """A force and a smooth part sampled at uneven instants over 2.5 m of travel."""
    x0, x1 = -1.2, 1.3
    n = int((x1 - x0) / v * 20_000.0)
    t = np.sort(x0 / v + (x1 - x0) / v * rng.random(n))
    t[0], t[-1] = x0 / v, x1 / v
    f = LOAD * (1.0 + 0.05 * np.sin(2 * np.pi * 300.0 * t) + 0.01 * rng.standard_normal(n))
    smooth = 0.02 * LOAD * np.sin(2 * np.pi * 900.0 * t) + 200.0 * rng.standard_normal(n)
    return t, f, smooth


@pytest.mark.parametrize("speed", [5.5, 42.0])
@pytest.mark.parametrize(
    "chain",
    [SensorModel(2000.0, 4), SensorModel(3000.0, 3), SensorModel(4000.0, 2), SensorModel(None)],
    ids=["2k-4", "3k-3", "4k-2", "ideal"],
)
def test_one_pass_equals_the_fine_grid(speed: float, chain: SensorModel) -> None:
    rng = np.random.default_rng(26)
    t, f, smooth = _signals(speed, rng)
    t0 = float(t[0])
    rate = forward.FINE_RATE
    n_fine = int(np.floor((t[-1] - t0) * rate)) + 1
    # the record's 10 kHz instants, and some before the grid and after it
    t_meas = np.concatenate(([t0 - 0.01, t0], np.arange(0.0, float(t[-1]), 1e-4), [t[-1] + 0.1]))
    x_a, x_b = np.array([0.4, 0.9, -2.0]), np.array([0.8, 1.25, -1.6])
    got = np.empty((t_meas.size, x_a.size))
    smooth3 = np.stack([smooth, 0.5 * smooth[::-1], smooth])
    crib_channels(t, f, smooth3, t0, rate, n_fine, speed, x_a, x_b, chain, t_meas, got)
    for i in range(x_a.size):
        ref_i = forward.chain_on_grid(
            t, f, smooth3[i], t0, rate, n_fine, speed, x_a[i], x_b[i], chain, t_meas
        )
        assert np.max(np.abs(got[:, i] - ref_i)) < 1e-12 * LOAD, i
    ref = got[:, 0]
    # the channel does read the load inside the crib (not a vacuous comparison)
    assert np.max(ref) > 0.9 * LOAD and np.min(np.abs(ref[t_meas * speed < 0.2])) < 0.1 * LOAD


def test_predict_channels_is_the_same_through_either(monkeypatch: pytest.MonkeyPatch) -> None:
    track = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.3, pad=Support(6e7, 1.5e4))
    d = derive(Material(2.14e11, 0.3), radius=0.46, load=LOAD, mass=700.0)
    wheel = forward.Wheel(
        speed=30.0,
        load=LOAD,
        mass=700.0,
        contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
    )
    cribs = (Crib("c1", 0.4, 0.8), Crib("c2", 1.0, 1.4))
    chain = SensorModel(2000.0, 4)
    t = np.arange(0.0, 1.6 / 30.0, 1e-4)
    one_pass = forward.predict_channels(track, wheel, cribs, chain, t, pre_roll=0.6, cutoff=4000.0)
    # out of order instants take the fine-grid path; put them back in order to compare
    order = np.random.default_rng(1).permutation(t.size)
    grid = forward.predict_channels(
        track, wheel, cribs, chain, t[order], pre_roll=0.6, cutoff=4000.0
    )
    back = np.empty_like(grid)
    back[order] = grid
    assert np.max(np.abs(one_pass - back)) < 1e-9 * LOAD
    assert np.max(one_pass) > 0.9 * LOAD
