"""Synthetic detector records: a wheel's crib channels as a site would record them.

The channel twin of ``synthetic``: the true wheel (round, or with its flat) rolls over the
site's track (``crib_forward.CribSite``: its rail on supports, its cribs) on a rail with
roughness the site does not know, from static equilibrium ``RUN_IN`` m before x = 0; each
crib's channel goes through the site's chain (``sensor.SensorModel``) at the chain's fine
rate and is read at the detector's instants t = k / rate while the wheel crosses
[0, length]; then white noise of ``noise_fraction``·P is added to every sample.

What the twin does not know here is the rail's roughness and the noise (the track is the
site file's own: a calibration test draws its own true track and hands it in as ``site``).

Worked example (``tests/test_crib_synthetic.py`` runs it on a ballasted site): a round
wheel with no noise and an even rail reads ≈ P in the middle of a crib and ≈ 0 in the
middle of a sleeper bay's support, and a 50 mm flat's record peaks far above P.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.diagnosis.crib_forward import CribSite, CribWheel, line_times
from sim_core.diagnosis.forward import RailTables, Tread
from sim_core.diagnosis.synthetic import rough_rail
from sim_core.rail import RailProfile

__all__ = ["CribRecord", "crib_record"]


@dataclass(frozen=True)
class CribRecord:
    """A detector's record of one passage and its truth.

    ``channels``: (cribs, samples) in N, sample k at t = k / ``sample_rate`` (t = 0: the wheel
    centre at x = 0); ``true_peak_force``: the contact force's peak while the wheel crosses
    [0, length] (N); ``noise_sigma``: the noise added (N)."""

    sample_rate: float
    channels: NDArray[np.float64]
    true_peak_force: float
    noise_sigma: float

    @property
    def t(self) -> NDArray[np.float64]:
        return np.arange(self.channels.shape[1], dtype=np.float64) / self.sample_rate


def crib_record(
    site: CribSite,
    wheel: CribWheel,
    speed: float,
    tread: Tread | None,
    *,
    sample_rate: float,
    noise_fraction: float,
    roughness_rms: float,
    seed: int,
) -> CribRecord:
    """What the site's detector records of ``wheel`` with ``tread`` (None: round) at
    ``speed`` over a rail of random roughness ``roughness_rms`` (m rms, seeded), plus white
    noise of ``noise_fraction``·P (seeded too). The same seed gives the same record."""
    if speed <= 0.0 or sample_rate <= 0.0:
        raise ValueError("crib record: speed and sample rate must be positive")
    if noise_fraction < 0.0 or roughness_rms < 0.0:
        raise ValueError("crib record: noise and roughness must not be negative")
    x0, x1 = site.line_stretch
    rails = RailTables(rough_rail(RailProfile.flat(), x0 - 1.0, x1 + 1.0, roughness_rms, seed))
    t_out = line_times(site.length, speed, sample_rate)
    run = site.run(wheel, speed, tread, t_out, line=True, measurement_rate=sample_rate, rails=rails)
    rng = np.random.default_rng(seed + 1)
    sigma = noise_fraction * wheel.load
    chans = run.channels + rng.normal(0.0, sigma, run.channels.shape)
    on_site = (run.t >= 0.0) & (run.t <= site.length / speed)
    peak = float(run.force[on_site].max()) if bool(on_site.any()) else run.peak_force
    return CribRecord(sample_rate, chans, peak, sigma)
