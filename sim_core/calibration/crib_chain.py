"""The cribs' channels through the measuring chain in a single pass (the forward model's last step).

``forward.predict_channels`` builds a crib's channel on a fine grid (``FINE_RATE``) as the
smooth part (the rail's inertia, simulated at ``SIM_RATE``) interpolated linearly, plus the
contact force times the crib's indicator (the fraction of each fine interval the wheel spends
between the gauges), runs the chain's Butterworth sections over it from steady state on its
first value, and reads the result at the record's instants by linear interpolation. Written
with NumPy that is four arrays of the fine grid's length a crib (a slow wheel's is 300 000
samples) and two ``np.interp``; here it is one loop over the grid for all the cribs that
holds none of them: the same numbers to rounding (``tests/test_calibration_crib_chain.py``
compares the two to 1e-12 of the load), in a fraction of the time.

Worked example (a steady load reads P inside a crib and 0 outside it):

    >>> import numpy as np
    >>> from sim_core.diagnosis.sensor import SensorModel
    >>> t = np.linspace(0.0, 0.2, 401)
    >>> f = np.full(t.size, 80e3)
    >>> t_meas = np.array([0.02, 0.1, 0.21])  # x_C = 0.1, 0.5, 1.05 m at 5 m/s
    >>> out = np.empty((3, 2))
    >>> crib_channels(t, f, np.zeros((2, t.size)), 0.0, 200_000.0, 40_001, 5.0,
    ...               np.array([0.4, 0.9]), np.array([0.8, 1.3]), SensorModel(2000.0, 4),
    ...               t_meas, out)
    >>> [[round(float(v) / 80e3, 3) + 0.0 for v in row] for row in out]
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.diagnosis.sensor import SensorModel, _butter

__all__ = ["crib_channels"]


def crib_channels(
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    smooth: NDArray[np.float64],
    t0: float,
    fine_rate: float,
    n_fine: int,
    v: float,
    x_a: NDArray[np.float64],
    x_b: NDArray[np.float64],
    chain: SensorModel,
    t_meas: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    """``out[:, i]`` = the channel of crib i, (x_a[i], x_b[i]), at ``t_meas`` (increasing;
    module docstring): the force ``f`` and each crib's smooth part ``smooth[i]`` sampled at
    ``t`` (increasing), the fine grid t0 + j/fine_rate for j < n_fine, the wheel at x = v·t.
    The cribs run side by side: their filters' recursions are independent, so the processor
    overlaps them."""
    if chain.cutoff_hz is None:
        sos = np.zeros((0, 6))
        zi = np.zeros((0, 2))
    else:
        if chain.cutoff_hz >= 0.45 * fine_rate:
            raise ValueError(
                f"sensor: cut-off {chain.cutoff_hz:g} Hz is not below the Nyquist limit of "
                f"{fine_rate:g} Hz"
            )
        sos, zi = _butter(chain.order, float(chain.cutoff_hz), float(fine_rate))
    if out.shape != (t_meas.size, x_a.size) or smooth.shape != (x_a.size, t.size):
        raise ValueError("crib_channels: smooth must be cribs x samples, out instants x cribs")
    _run(
        np.ascontiguousarray(t, dtype=np.float64),
        np.ascontiguousarray(f, dtype=np.float64),
        np.ascontiguousarray(smooth, dtype=np.float64),
        float(t0),
        float(fine_rate),
        int(n_fine),
        float(v),
        np.ascontiguousarray(x_a, dtype=np.float64),
        np.ascontiguousarray(x_b, dtype=np.float64),
        sos,
        zi,
        np.ascontiguousarray(t_meas, dtype=np.float64),
        out,
    )


@numba.njit(cache=True, nogil=True)
def _run(
    t: NDArray[np.float64],
    f: NDArray[np.float64],
    smooth: NDArray[np.float64],
    t0: float,
    fine_rate: float,
    n_fine: int,
    v: float,
    x_a: NDArray[np.float64],
    x_b: NDArray[np.float64],
    sos: NDArray[np.float64],
    zi: NDArray[np.float64],
    t_meas: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    ns = sos.shape[0]
    nc = x_a.size
    z0 = np.empty((nc, ns))
    z1 = np.empty((nc, ns))
    y = np.zeros(nc)
    y_prev = np.zeros(nc)
    dx = v / fine_rate
    last = t.size - 1
    k = 0
    m = 0
    t_prev = 0.0
    for j in range(n_fine):
        tj = t0 + j / fine_rate
        while k < last - 1 and t[k + 1] <= tj:
            k += 1
        # linear interpolation on interval k, held at the ends (as np.interp)
        if tj <= t[0]:
            kk, w = 0, 0.0
        elif tj >= t[last]:
            kk, w = last, 0.0
        else:
            kk, w = k, (tj - t[k]) / (t[k + 1] - t[k])
        fj = f[kk] if w == 0.0 else f[kk] + w * (f[kk + 1] - f[kk])
        xj = tj * v
        for c in range(nc):
            sj = (
                smooth[c, kk]
                if w == 0.0
                else smooth[c, kk] + w * (smooth[c, kk + 1] - smooth[c, kk])
            )
            ind = max(min(xj + 0.5 * dx, x_b[c]) - max(xj - 0.5 * dx, x_a[c]), 0.0) / dx
            u = sj + fj * ind
            if j == 0:
                for s in range(ns):
                    z0[c, s] = zi[s, 0] * u
                    z1[c, s] = zi[s, 1] * u
            for s in range(ns):
                yy = sos[s, 0] * u + z0[c, s]
                z0[c, s] = sos[s, 1] * u - sos[s, 4] * yy + z1[c, s]
                z1[c, s] = sos[s, 2] * u - sos[s, 5] * yy
                u = yy
            y[c] = u
        while m < t_meas.size and t_meas[m] <= tj:
            if j == 0:
                for c in range(nc):
                    out[m, c] = y[c]
            else:
                a = (t_meas[m] - t_prev) / (tj - t_prev)
                for c in range(nc):
                    out[m, c] = y_prev[c] + a * (y[c] - y_prev[c])
            m += 1
        t_prev = tj
        for c in range(nc):
            y_prev[c] = y[c]
    while m < t_meas.size:
        for c in range(nc):
            out[m, c] = y[c]
        m += 1
