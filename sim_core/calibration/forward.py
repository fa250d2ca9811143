"""What a detector records of a round wheel on a given track: the calibration's forward model.

A crib's channel is the contact force F while the wheel is between the crib's gauges, plus
the rail's inertia between them (MODEL.md §8), passed through the site's measuring chain
(a causal Butterworth low-pass, ``sim_core.diagnosis.sensor``) and sampled. At each gauge
the channel steps by the wheel load at once, and the chain's step response shows at every
speed: where the step falls between two samples of the simulation decides a few samples
after it to several % of P. So the channel is split in two:

- the smooth part, ``s = channel - F·1[in crib]`` (the rail's inertia) and F itself,
  simulated at a moderate rate (``SIM_RATE``) and interpolated linearly onto a fine grid;
- the crib's indicator 1[x_a < x_C < x_b] on the fine grid, each fine sample holding the
  exact fraction of its interval the wheel spends inside the crib, so that the step falls
  where the wheel crosses the gauge, not on a grid line;

and the chain runs on ``s + F·indicator`` at the fine rate, started in steady state on the
first value (the wheel then stands outside every crib), as the detector's own chain runs
from the start of the run-in.
(``crib_chain.crib_channels`` does this in one pass without the fine grid's arrays;
``chain_on_grid`` is the same with NumPy arrays, its reference.)

The wheel starts ``pre_roll`` metres before x = 0 in static equilibrium, so that the start
transient has decayed where the record begins (the record's t = 0 is x_C = 0).

Worked example (a slow wheel's channel is P inside its crib and 0 outside, whatever the
track: the chain's gain is 1):

    >>> import numpy as np
    >>> from sim_core.contact_laws import ContactLaw, ContactModel
    >>> from sim_core.diagnosis.sensor import SensorModel
    >>> from sim_core.materials import Material, derive
    >>> from sim_core.track.spec import Crib, Support, TrackSpec
    >>> track = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.3, pad=Support(6e7, 1.5e4))
    >>> d = derive(Material(2.14e11, 0.3), radius=0.46, load=80e3, mass=700.0)
    >>> wheel = Wheel(speed=5.0, load=80e3, mass=700.0,
    ...               contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient))
    >>> t = np.array([0.06, 0.10, 0.2])  # x_C = 0.3, 0.5 (mid-crib), 1.0 m
    >>> ch = predict_channels(track, wheel, (Crib("c1", 0.4, 0.8),), SensorModel(2000.0, 4),
    ...                       t, pre_roll=0.3, cutoff=4000.0)
    >>> [round(float(v) / 80e3, 2) + 0.0 for v in ch[:, 0]]
    [0.0, 1.0, 0.0]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.calibration.crib_chain import crib_channels
from sim_core.constraint import flat_constraint
from sim_core.contact_laws import ContactModel
from sim_core.diagnosis.sensor import SensorModel
from sim_core.track.modal import reduce_track
from sim_core.track.spec import Crib, TrackSpec

__all__ = [
    "ABSORBER_BAYS",
    "CUTOFF",
    "ELEMENTS_PER_BAY",
    "FINE_RATE",
    "MARGIN_BAYS",
    "MAX_STEP",
    "PRE_ROLL",
    "SIM_RATE",
    "STEP_TRAVEL",
    "STRETCH_GRID",
    "Wheel",
    "chain_on_grid",
    "crib_indicator",
    "predict_channels",
]

SIM_RATE = 20_000.0
"""Hz: the rate at which the smooth parts (F and the rail's inertia) are simulated. Their
content through a ≤ 4 kHz chain is below ~2 kHz on a round wheel; linear interpolation at
this rate errs by < 0.3 % of that content."""

FINE_RATE = 200_000.0
"""Hz: the rate at which the chain is applied (a detector's chain acts on a continuous signal)."""

CUTOFF = 5000.0
"""Hz: the track's modes kept for calibration (the static residual keeps the rest
statically); above the fastest chain's cut-off (4 kHz)."""

ELEMENTS_PER_BAY = 8
"""Rail elements per sleeper bay (0.08 m at 0.65 m): eight a bending wavelength at 5 kHz."""

ABSORBER_BAYS = 6
"""Absorbing bays each side (the twin's 12 are for flats' impacts, up to 12 kHz)."""

MARGIN_BAYS = 2
"""Plain bays each side of the stretch.

With these four settings a reduction takes a tenth of a second to a second instead of seconds,
and on the handed-over records (an independent solver's, true track) the channels change by
less than 0.002 σ rms against the twin's own settings of the time (16 kHz, since 12 kHz;
16 elements, 12 and 3 bays):
docs/calibration.md."""

STEP_TRAVEL = 1.0e-3
"""m: the stepper's longest step is the time the wheel takes to roll this far, at most
``MAX_STEP`` and at least the twin's 20 µs: a slow round wheel's force changes slowly."""

MAX_STEP = 1.0e-4
"""s: the longest step at any speed (ten a period at 1 kHz, the wheel on the contact)."""

STRETCH_GRID = 0.5
"""m: the simulated stretch ends on a multiple of this, so that the wheels of a site share
the track's reduction."""

PRE_ROLL = 1.2
"""m: the wheel starts this far before x = 0, from static equilibrium."""


@dataclass(frozen=True)
class Wheel:
    """A round wheel of a passage: speed (m/s), static load (N), unsprung mass (kg), contact."""

    speed: float
    load: float
    mass: float
    contact: ContactModel


def crib_indicator(
    x_fine: NDArray[np.float64], dx: float, x_a: float, x_b: float
) -> NDArray[np.float64]:
    """The fraction of each fine interval [x - dx/2, x + dx/2] that lies inside (x_a, x_b).

    >>> crib_indicator(np.array([0.0, 1.0, 2.0, 3.0]), 1.0, 0.75, 2.0)
    array([0.  , 0.75, 0.5 , 0.  ])
    """
    lo = np.maximum(x_fine - 0.5 * dx, x_a)
    hi = np.minimum(x_fine + 0.5 * dx, x_b)
    return np.clip(hi - lo, 0.0, None) / dx


def predict_channels(
    track: TrackSpec,
    wheel: Wheel,
    cribs: tuple[Crib, ...],
    chain: SensorModel,
    t_meas: NDArray[np.float64],
    *,
    pre_roll: float = PRE_ROLL,
    cutoff: float = CUTOFF,
    sim_rate: float = SIM_RATE,
    fine_rate: float = FINE_RATE,
) -> NDArray[np.float64]:
    """The channels (N, one column per crib) a detector records at ``t_meas`` (s, t = 0 at
    x_C = 0) of a round wheel on an even rail over ``track`` (module docstring)."""
    from sim_core.passage import PassageSpec
    from sim_core.track.passage import STEP, simulate_on_track

    v = wheel.speed
    x0 = -pre_roll
    # one stretch for every wheel of a site (a reduction per stretch): the record's end
    # rounded up to the next STRETCH_GRID
    x1 = STRETCH_GRID * math.ceil((float(np.max(t_meas)) * v + 2.0 * v / sim_rate) / STRETCH_GRID)
    mt = reduce_track(
        track,
        x0,
        x1,
        cribs,
        cutoff=cutoff,
        elements_per_bay=ELEMENTS_PER_BAY,
        absorber_bays=ABSORBER_BAYS,
        margin_bays=MARGIN_BAYS,
    )
    duration = (x1 - x0) / v
    spec = PassageSpec(
        mass=wheel.mass,
        load=wheel.load,
        speed=v,
        duration=duration,
        sample_rate=sim_rate,
        contact=wheel.contact,
        foundation=track,
        t0=x0 / v,
        cribs=cribs,
    )
    step = max(STEP, min(MAX_STEP, STEP_TRAVEL / v))
    out = simulate_on_track(flat_constraint(), spec, track, model=mt, step=step)
    t, x, f = out.t, out.x, out.force
    n_fine = math.floor(duration * fine_rate) + 1
    smooth = np.empty((len(cribs), t.size))
    for i, c in enumerate(cribs):
        inside = np.where((x > c.x_a) & (x < c.x_b), 1.0, 0.0)
        inside[np.abs(x - c.x_a) <= 1e-12] = 0.5
        inside[np.abs(x - c.x_b) <= 1e-12] = 0.5
        smooth[i] = out.channels[c.id] - f * inside
    result = np.empty((t_meas.size, len(cribs)))
    if bool(np.all(np.diff(t_meas) >= 0.0)):
        lo = np.array([c.x_a for c in cribs], dtype=np.float64)
        hi = np.array([c.x_b for c in cribs], dtype=np.float64)
        crib_channels(t, f, smooth, x0 / v, fine_rate, n_fine, v, lo, hi, chain, t_meas, result)
        return result
    for i, c in enumerate(cribs):  # instants out of order: the fine grid's arrays
        result[:, i] = chain_on_grid(
            t, f, smooth[i], x0 / v, fine_rate, n_fine, v, c.x_a, c.x_b, chain, t_meas
        )
    return result


def chain_on_grid(
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    smooth: NDArray[np.float64],
    t0: float,
    fine_rate: float,
    n_fine: int,
    v: float,
    x_a: float,
    x_b: float,
    chain: SensorModel,
    t_meas: NDArray[np.float64],
) -> NDArray[np.float64]:
    """A crib's channel at ``t_meas`` built on the fine grid with NumPy (module docstring):
    what ``crib_chain.crib_channels`` computes in one pass, kept for ``t_meas`` out of order
    and as its reference."""
    t_fine = t0 + np.arange(n_fine) / fine_rate
    x_fine = t_fine * v
    u = np.interp(t_fine, t, smooth) + np.interp(t_fine, t, f) * crib_indicator(
        x_fine, v / fine_rate, x_a, x_b
    )
    return np.interp(t_meas, t_fine, chain.filter(u, fine_rate))
