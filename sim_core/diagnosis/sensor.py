"""The site's measuring chain: a causal Butterworth low-pass, then sampling.

A wheel impact load detector does not see the contact force itself: strain gauges on
the rail, an amplifier and an anti-aliasing filter smooth it. The site file describes
that chain as a causal Butterworth low-pass (``sensor_lowpass_hz``, ``sensor_lowpass_order``;
none when absent). The twin passes its simulated force through the same chain before
it compares it with a measurement, so a sharp 1 ms impact is matched as the site
records it, not as the contact feels it.

The filter acts on the force as a continuous signal: it is applied at a fine internal
rate (at least 50 kHz and 25 times the cut-off; the bilinear transform's pre-warping
keeps the cut-off exact), started in steady state on the
first value, and the result is read at the measurement instants by linear interpolation.

Worked example: a 1 kHz second-order low-pass passes a static load unchanged and
delays a 2 ms step by about 0.22 ms (its group delay at low frequency):

    >>> import numpy as np
    >>> s = SensorModel(cutoff_hz=1000.0, order=2)
    >>> t = np.arange(0.0, 0.01, 1e-6)
    >>> f = np.where(t < 0.002, 50e3, 80e3)
    >>> out = s.measure(t, f, np.array([0.0, 0.0099]))
    >>> [round(float(v)) for v in out]
    [50000, 80000]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["FINE_RATE_MIN", "SensorModel"]

FINE_RATE_MIN = 50_000.0
"""Hz: the lowest internal rate at which the low-pass is applied (``fine_rate``)."""


@dataclass(frozen=True)
class SensorModel:
    """A causal Butterworth low-pass of ``order`` at ``cutoff_hz`` (None: an ideal sensor)."""

    cutoff_hz: float | None = None
    order: int = 2

    def __post_init__(self) -> None:
        if self.cutoff_hz is not None and not (
            math.isfinite(self.cutoff_hz) and self.cutoff_hz > 0
        ):
            raise ValueError(f"sensor: cutoff_hz must be positive (Hz), got {self.cutoff_hz!r}")
        if not (1 <= self.order <= 8):
            raise ValueError(f"sensor: order must be 1..8, got {self.order!r}")

    def fine_rate(self, measurement_rate: float = 0.0) -> float:
        """The internal rate (Hz) at which a simulated force should be sampled for ``measure``."""
        rate = max(FINE_RATE_MIN, 4.0 * measurement_rate)
        if self.cutoff_hz is not None:
            rate = max(rate, 25.0 * self.cutoff_hz)
        return rate

    def filter(self, f: NDArray[np.float64], rate: float) -> NDArray[np.float64]:
        """The low-pass applied to ``f`` sampled uniformly at ``rate``, steady state at f[0]."""
        if self.cutoff_hz is None or f.size == 0:
            return np.asarray(f, dtype=np.float64)
        if self.cutoff_hz >= 0.45 * rate:
            raise ValueError(
                f"sensor: cut-off {self.cutoff_hz:g} Hz is not below the Nyquist limit of {rate:g} Hz"
            )
        sos, zi_unit = _butter(self.order, float(self.cutoff_hz), float(rate))
        out = np.empty(f.size)
        _sosfilt(sos, zi_unit * float(f[0]), np.ascontiguousarray(f, dtype=np.float64), out)
        return out

    def measure(
        self, t: NDArray[np.float64], f: NDArray[np.float64], t_out: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """What the site records at ``t_out`` of a force ``f`` sampled uniformly at times ``t``."""
        if t.size < 2:
            raise ValueError("sensor: need at least two force samples")
        rate = (t.size - 1) / (t[-1] - t[0])
        return np.interp(t_out, t, self.filter(f, rate))


_SOS_CACHE: dict[tuple[int, float, float], tuple[NDArray[np.float64], NDArray[np.float64]]] = {}


def _butter(
    order: int, cutoff: float, rate: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(second-order sections [b0, b1, b2, 1, a1, a2], their steady-state states for a
    unit input) of a digital Butterworth low-pass of ``order`` at ``cutoff`` Hz.

    The analogue prototype's poles p = ω·exp(iπ(2k + order + 1)/(2·order)) at the
    pre-warped ω = 2·rate·tan(π·cutoff/rate), mapped by the bilinear transform
    z = (2·rate + p)/(2·rate - p), all zeros at z = -1 (what ``scipy.signal.butter`` does,
    written out so that the diagnosis does not import ``scipy.signal``, half a second; one
    pole pair per section, each section scaled to unit gain at DC, so the chain's gain is 1
    exactly; ``tests/test_diagnosis_sensor.py`` compares it with SciPy's).
    """
    key = (order, cutoff, round(rate, 6))
    got = _SOS_CACHE.get(key)
    if got is None:
        fs2 = 2.0 * rate
        w = fs2 * math.tan(math.pi * cutoff / rate)
        rows: list[list[float]] = []
        for k in range(order // 2):  # the upper half-plane pole of each conjugate pair
            p = w * complex(np.exp(1j * math.pi * (2 * k + order + 1) / (2 * order)))
            z = (fs2 + p) / (fs2 - p)
            a1, a2 = -2.0 * z.real, abs(z) ** 2
            g = (1.0 + a1 + a2) / 4.0
            rows.append([g, 2.0 * g, g, 1.0, a1, a2])
        if order % 2:  # the real pole -ω
            z1 = (fs2 - w) / (fs2 + w)
            g = (1.0 - z1) / 2.0
            rows.append([g, g, 0.0, 1.0, -z1, 0.0])
        sos = np.array(rows, dtype=np.float64)
        # transposed direct form II in steady state at a unit input (each section's output 1)
        zi = np.empty((sos.shape[0], 2))
        zi[:, 1] = sos[:, 2] - sos[:, 5]
        zi[:, 0] = sos[:, 1] - sos[:, 4] + zi[:, 1]
        got = (sos, zi)
        if len(_SOS_CACHE) > 64:
            _SOS_CACHE.clear()
        _SOS_CACHE[key] = got
    return got


@numba.njit(cache=True, nogil=True)
def _sosfilt(
    sos: NDArray[np.float64],
    zi: NDArray[np.float64],
    x: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    """``out`` = the cascade of second-order sections applied to ``x`` from the states ``zi``
    (transposed direct form II, as ``scipy.signal.sosfilt``)."""
    ns = sos.shape[0]
    z0 = zi[:, 0].copy()
    z1 = zi[:, 1].copy()
    for i in range(x.size):
        v = x[i]
        for s in range(ns):
            y = sos[s, 0] * v + z0[s]
            z0[s] = sos[s, 1] * v - sos[s, 4] * y + z1[s]
            z1[s] = sos[s, 2] * v - sos[s, 5] * y
            v = y
        out[i] = v
