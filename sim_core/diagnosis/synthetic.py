"""Synthetic measured passages: what a site would record, with what the twin does not know.

The validation of the diagnosis needs measurements whose truth is known. This generator
simulates the true wheel with the twin's own physics (run-in before the site, combined
irregularity, the site's contact law) and then adds what the twin's model of the site
leaves out:

- rail roughness of a few µm that is not in the site file (a random profile with a
  power-law spectrum, wavelengths 1 cm to 1 m, scaled to ``roughness_rms``);
- damping in the foundation (the twin's site may have none);
- a speed off by ``speed_error`` (the wheel rolls at V·(1 + ε), the passage reports V);
- the measuring chain: the site's low-pass and sampling, then white noise of
  ``noise_fraction``·P per sample.

Worked example: a round wheel on an even rail measures its static load, give or take
the noise:

    >>> from sim_core.materials import Material, derive
    >>> from sim_core.contact_laws import ContactLaw, ContactModel
    >>> from sim_core.rail import RailProfile
    >>> from sim_core.diagnosis.sensor import SensorModel
    >>> from sim_core.diagnosis.forward import WheelOnSite
    >>> d = derive(Material(2.14e11, 0.3), radius=0.46, load=60e3, mass=500.0)
    >>> w = WheelOnSite(500.0, 60e3, 0.46, ContactModel(ContactLaw.HERTZ, d.contact_coefficient))
    >>> m = synthetic_measurement(w, 30.0, None, RailProfile.flat(), 3.0, 10e3,
    ...                           SensorModel(3000.0, 2), Perturbations(roughness_rms=0.0, seed=1))
    >>> bool(abs(m.force.mean() / 60e3 - 1) < 0.01), m.force.size
    (True, 1001)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from sim_core.diagnosis.forward import (
    TABLE_MARGIN,
    RailTables,
    Tread,
    WheelOnSite,
    run_in_length,
    simulate_passage_run_in,
)
from sim_core.diagnosis.sensor import SensorModel
from sim_core.passage import Foundation, PassageOutput
from sim_core.rail import RailProfile
from sim_core.roughness import power_law_psd, random_roughness

__all__ = [
    "Perturbations",
    "SimulatedPassage",
    "SyntheticMeasurement",
    "rough_rail",
    "simulated_passage",
    "synthetic_measurement",
]

ROUGHNESS_DX = 1e-3
"""m between the samples of the generated roughness."""


@dataclass(frozen=True)
class Perturbations:
    """What the twin does not know about a passage (defaults: a realistic site)."""

    noise_fraction: float = 0.03
    roughness_rms: float = 3e-6
    foundation_damping: float | None = None
    speed_error: float = 0.0
    seed: int = 0


@dataclass(frozen=True)
class SyntheticMeasurement:
    """A measured passage: ``force`` (N) at t = t_start + k/sample_rate, and its truth."""

    t_start: float
    sample_rate: float
    force: NDArray[np.float64]
    true_speed: float
    true_peak_force: float

    @property
    def t(self) -> NDArray[np.float64]:
        return self.t_start + np.arange(self.force.size) / self.sample_rate


def rough_rail(rail: RailProfile, x0: float, x1: float, rms: float, seed: int) -> RailProfile:
    """``rail`` plus random roughness of ``rms`` (m) sampled every mm on [x0, x1]."""
    if rms <= 0.0:
        return rail
    k = np.geomspace(2 * math.pi / 1.0, 2 * math.pi / 0.01, 300)
    S = power_law_psd(k, level=1.0)
    r = random_roughness(x1 - x0, ROUGHNESS_DX, k, S, seed=seed)
    y = r.y - r.y.mean()
    y *= rms / float(np.sqrt(np.mean(y * y)))
    x = r.x + x0
    return RailProfile.sampled(x, rail.height(x) + y)


@dataclass(frozen=True)
class SimulatedPassage:
    """The true passage behind a synthetic measurement, before the measuring chain.

    ``wheel`` rolls at ``speed`` (both true) over ``rails`` (the rough rail); ``output`` is
    the simulation from the run-in on, up to ``x_end`` (m), sampled at the chain's fine
    rate; ``t_measure`` are the site's sample times. A second solver can re-integrate the
    same passage on ``rails`` (``validation/line_truth_reference.py``).
    """

    wheel: WheelOnSite
    speed: float
    rails: RailTables
    x_end: float
    output: PassageOutput
    t_measure: NDArray[np.float64]


def simulated_passage(
    wheel: WheelOnSite,
    speed: float,
    flat: Tread | None,
    rail: RailProfile,
    site_length: float,
    sample_rate: float,
    sensor: SensorModel,
    perturbations: Perturbations,
) -> SimulatedPassage:
    """The true passage of ``wheel`` (reported ``speed``) over the site, unmeasured: the
    rough rail, the true wheel and speed, the run-in, the sample times (noise not drawn)."""
    p = perturbations
    true_speed = speed * (1.0 + p.speed_error)
    true_wheel = wheel
    if p.foundation_damping is not None:
        f = wheel.foundation
        if not f.is_compliant:
            raise ValueError("synthetic: foundation damping needs a compliant foundation")
        true_wheel = replace(
            wheel, foundation=Foundation.compliant(f.mass, f.stiffness, p.foundation_damping)
        )
    x0 = -run_in_length(wheel.radius) - 2 * TABLE_MARGIN - 1.0
    x1 = site_length * true_speed / speed + 2 * TABLE_MARGIN + 1.0
    rails = RailTables(rough_rail(rail, x0, x1, p.roughness_rms, p.seed))
    fine = sensor.fine_rate(sample_rate)
    duration = site_length / speed
    n = math.floor(duration * sample_rate + 1e-9) + 1
    x_end = true_speed * (duration + 2.0 / sample_rate)
    out = simulate_passage_run_in(true_wheel, true_speed, flat, rails, 0.0, x_end, fine)
    return SimulatedPassage(true_wheel, true_speed, rails, x_end, out, np.arange(n) / sample_rate)


def synthetic_measurement(
    wheel: WheelOnSite,
    speed: float,
    flat: Tread | None,
    rail: RailProfile,
    site_length: float,
    sample_rate: float,
    sensor: SensorModel,
    perturbations: Perturbations,
) -> SyntheticMeasurement:
    """What the site records of ``wheel`` (reported ``speed``) passing its ``site_length``:
    ``simulated_passage`` through the site's chain, plus noise."""
    p = perturbations
    sim = simulated_passage(
        wheel, speed, flat, rail, site_length, sample_rate, sensor, perturbations
    )
    out, n = sim.output, sim.t_measure.size
    measured = sensor.measure(out.t, out.force, sim.t_measure)
    rng = np.random.default_rng(p.seed + 7919)
    measured = measured + rng.normal(0.0, p.noise_fraction * wheel.load, n)
    return SyntheticMeasurement(0.0, sample_rate, measured, sim.speed, out.peak_force)
