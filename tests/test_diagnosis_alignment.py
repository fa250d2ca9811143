"""The per-turn alignment's compiled kernels (``sim_core.diagnosis.estimate``) against plain
numpy: the window's cost for each shift of the template, and the costs gathered on the
(flat-centre time, period) grid. Both kernels step along uniform grids without dividing per
element; these check that they interpolate and hold the ends exactly as the definitions say,
including shifts that fall outside the template and periods that put a window off the end
of its cost curve."""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.diagnosis.estimate import SHIFT_STEP, _add_on_grid, _window_costs


def _interp_held(x: np.ndarray, x0: float, dx: float, y: np.ndarray) -> np.ndarray:
    """y (sampled every dx from x0) linearly interpolated at x, held at both ends."""
    return np.interp(x, x0 + dx * np.arange(y.size), y)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_window_costs_are_the_sum_of_squares_of_the_shifted_template(seed: int) -> None:
    rng = np.random.default_rng(seed)
    tau = -0.004 + 1e-5 * np.arange(900)  # template from -4 ms, every 10 µs
    tf = 60e3 + 20e3 * rng.standard_normal(tau.size)
    tw = 0.1003 + np.arange(120) / 3000.0  # a window of 120 samples at 3 kHz
    fw = 60e3 + 5e3 * rng.standard_normal(tw.size)
    shifts = 0.1 + SHIFT_STEP * np.arange(-200, 400)  # some push the window off the template
    got = _window_costs(tau, tf, tw, fw, shifts)
    want = np.array(
        [np.sum((fw - _interp_held(tw - s, tau[0], tau[1] - tau[0], tf)) ** 2) for s in shifts]
    )
    np.testing.assert_allclose(got, want, rtol=1e-10)


@pytest.mark.parametrize("turns", [0.0, 1.0, 3.0])
def test_costs_gathered_on_the_grid_are_interpolated_and_held_at_the_ends(turns: float) -> None:
    rng = np.random.default_rng(int(turns) + 7)
    s0 = 0.25 + SHIFT_STEP * np.arange(301)
    period = np.linspace(0.462, 0.478, 57)
    # the cost curve starts inside the grid's reach and ends before it: both ends are held
    c0 = s0[40] + turns * period[10]
    cost = rng.uniform(1.0, 2.0, 180)
    total = np.full((period.size, s0.size), 0.5)
    _add_on_grid(total, s0, turns, period, c0, SHIFT_STEP, cost)
    at = s0[None, :] + turns * period[:, None]
    want = 0.5 + _interp_held(at.ravel(), c0, SHIFT_STEP, cost).reshape(at.shape)
    np.testing.assert_allclose(total, want, rtol=1e-10)  # u0 + i against (s0[i] + ...)/dc
    assert np.any(at < c0) and np.any(at > c0 + SHIFT_STEP * (cost.size - 1))
