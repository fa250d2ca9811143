"""The round wheel's crib channels without a simulation, and the screen that dismisses it.

A load standing between a crib's gauges gives that crib's channel +P, a load outside it ~0,
whatever the track (MODEL.md §8: a load outside the crib gives Q(x_a) = Q(x_b)). A round
wheel rolling at V therefore gives, to within its dynamic load, the *template*

    T_c(t) = chain(P · [x_a < V·t < x_b])

per crib c, where ``chain`` is the site's measuring chain (``sensor.SensorModel``), steps and
overshoot included. What a flat adds is an impact of 1.5-5 × P in whichever crib holds the
wheel; what a rough rail adds is a dynamic load of a few % of P, up to ~20 % at 150 km/h.

The screen compares the record's largest excess over the template with the larger of
``SCREEN_SIGMAS`` noise σ (estimated from the record) and the round wheel's dynamic-load
allowance ``round_allowance`` (a fraction of P growing with V²). Below both, the wheel is
dismissed as round without any simulation.

Worked example: a round wheel's noise-free channels are the template, so nothing is excess:

    >>> import numpy as np
    >>> from sim_core.diagnosis.sensor import SensorModel
    >>> from sim_core.track.spec import Crib
    >>> cribs = (Crib("a", 1.0, 1.45), Crib("b", 1.65, 2.1))
    >>> t = np.arange(0.0, 0.1, 1e-4)
    >>> tpl = round_template(cribs, 30.0, 80e3, t, SensorModel(2000.0, 4))
    >>> round(float(tpl[0].max()) / 80e3, 2), round(float(tpl[0][-1]), 3)
    (1.1, 0.0)
    >>> screen(tpl, tpl, 30.0, 80e3, 500.0).flat_suspected
    False
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.diagnosis.sensor import SensorModel
from sim_core.track.spec import Crib

__all__ = [
    "ROUGH_RAIL_LOAD_AT_REF",
    "ROUND_ALLOWANCE_AT_REF",
    "ROUND_ALLOWANCE_STATIC",
    "SCREEN_SIGMAS",
    "Screen",
    "channel_noise",
    "excess",
    "rough_rail_load",
    "round_allowance",
    "round_template",
    "screen",
    "step_response",
]

SCREEN_SIGMAS = 5.0
"""Noise σ the largest excess must exceed (white noise over a few ten thousand samples
reaches ~4.5 σ)."""

ROUND_ALLOWANCE_STATIC = 0.12
"""Fraction of P a round wheel's channels may stand above its template at any speed: the
chain's step response on a gauge passes slightly off the template's, and the rail's own
inertia between the gauges."""

ROUND_ALLOWANCE_AT_REF = 0.35
"""Fraction of P a round wheel's dynamic load may add at ``ALLOWANCE_REF_SPEED``: the
physics' upper bound of ~20 % of P at 150 km/h from 10 µm of rail roughness, with margin
(the dynamic load grows about as V² for a given roughness)."""

ALLOWANCE_REF_SPEED = 41.7
"""m/s (150 km/h) at which ``ROUND_ALLOWANCE_AT_REF`` holds."""

ROUGH_RAIL_LOAD_AT_REF = 0.20
"""Fraction of P a rail's roughness may add to or take from a wheel's load at
``ALLOWANCE_REF_SPEED``: the physics' bound of ~20 % of P at 150 km/h from 10 µm of
roughness (``ROUND_ALLOWANCE_AT_REF`` without its margin)."""

TEMPLATE_RATE = 200_000.0
"""Hz at which the template's steps are filtered before sampling at the record's instants."""


def round_template(
    cribs: Sequence[Crib],
    speed: float,
    load: float,
    t: NDArray[np.float64],
    sensor: SensorModel,
) -> NDArray[np.float64]:
    """T_c(t) for each crib (rows, in ``cribs``' order) at the record's times ``t``.

    The gauge is a point: a sample exactly on it takes half the load (as the twin's channels).
    """
    tau, step = step_response(sensor)
    out = np.empty((len(cribs), t.size))
    for i, c in enumerate(cribs):
        on = np.interp(t - c.x_a / speed, tau, step, left=0.0, right=1.0)
        off = np.interp(t - c.x_b / speed, tau, step, left=0.0, right=1.0)
        out[i] = load * (on - off)
    return out


STEP_SPAN = 0.02
"""s of the chain's step response kept (it has settled to 1e-6 long before)."""


def step_response(sensor: SensorModel) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(τ, S(τ)): the chain's response to a unit step at τ = 0 on a fine grid (S = 0 before,
    and 1 after ``STEP_SPAN``); a step exactly on a sample takes half, as the twin's gauges."""
    tau = np.arange(-2, int(STEP_SPAN * TEMPLATE_RATE) + 1, dtype=np.float64) / TEMPLATE_RATE
    unit = np.where(tau > 0.0, 1.0, np.where(tau == 0.0, 0.5, 0.0))
    return tau, sensor.filter(unit, TEMPLATE_RATE)


def channel_noise(channels: NDArray[np.float64]) -> float:
    """σ (N) of the record's white noise: the median absolute third difference / 0.6745
    over sqrt(20), pooled over the channels (robust to the gauge steps and the impacts,
    which fill a small part of each channel)."""
    if channels.shape[1] <= 4:
        return 0.0
    d = np.diff(channels, 3, axis=1)
    return float(np.median(np.abs(d)) / 0.6745 / math.sqrt(20.0))


def round_allowance(speed: float, load: float) -> float:
    """N: how far above its template a round wheel's channels may stand (see the constants)."""
    return load * (
        ROUND_ALLOWANCE_STATIC + ROUND_ALLOWANCE_AT_REF * (speed / ALLOWANCE_REF_SPEED) ** 2
    )


def rough_rail_load(speed: float, load: float) -> float:
    """N: how far the rail's roughness, which the twin's even rail leaves out, may move a
    wheel's load at ``speed`` either way (``ROUGH_RAIL_LOAD_AT_REF``, as V²)."""
    return load * ROUGH_RAIL_LOAD_AT_REF * (speed / ALLOWANCE_REF_SPEED) ** 2


def excess(
    channels: NDArray[np.float64], template: NDArray[np.float64], load: float
) -> NDArray[np.float64]:
    """Per sample, the wheel's load beyond P as the crib that holds it sees it: the sum over
    cribs of (channel - template) weighted by how fully the crib holds the wheel
    (template / P within [0, 1]); ~0 while the wheel is over a sleeper. Its white noise is
    at most the channels' σ."""
    w = np.clip(template / load, 0.0, 1.0)
    return np.asarray(np.sum((channels - template) * w, axis=0), dtype=np.float64)


@dataclass(frozen=True)
class Screen:
    """The screen's answer: the largest excess (N), the noise σ, the threshold and whether a
    flat is suspected (the excess above the threshold)."""

    peak_excess: float
    noise: float
    threshold: float
    residual_rms: float

    @property
    def flat_suspected(self) -> bool:
        return self.peak_excess > self.threshold


def screen(
    channels: NDArray[np.float64],
    template: NDArray[np.float64],
    speed: float,
    load: float,
    noise: float | None = None,
) -> Screen:
    """Compare the record's channels (rows per crib) with the round template."""
    sigma = channel_noise(channels) if noise is None else noise
    allowance = round_allowance(speed, load)
    e = excess(channels, template, load)
    peak = float(np.max(np.abs(e))) if e.size else 0.0
    # and unweighted: an impact over a sleeper shows in the neighbouring cribs' channels
    # while the template's weight there is small; that sum's noise is sqrt(cribs) x σ
    s = np.sum(channels - template, axis=0)
    peak_sum = float(np.max(np.abs(s))) if s.size else 0.0
    n = channels.shape[0]
    threshold = max(SCREEN_SIGMAS * sigma, allowance)
    threshold_sum = max(SCREEN_SIGMAS * sigma * math.sqrt(n), allowance)
    rms = float(np.sqrt(np.mean((channels - template) ** 2))) if channels.size else 0.0
    # report the test that stands out more, in units of its own threshold
    if peak_sum / threshold_sum > peak / threshold:
        return Screen(peak_sum, sigma, threshold_sum, rms)
    return Screen(peak, sigma, threshold, rms)
