"""The finite stretch of track that stands for the endless one: nodes, elements, sleepers.

The track runs on beyond the simulated stretch both ways (MODEL.md §8). A finite
model of it holds the stretch the wheel rolls over and the detector's cribs, a
``margin`` of plain track each side, and beyond that an ``absorber`` each side:
track whose rail carries a dashpot to ground growing smoothly (quadratically)
from zero, so that waves leaving the stretch die out instead of coming back
from the model's ends (the reference solver of ``validation/track`` does the
same over 60 bays). Nodes lie on every sleeper, ``elements_per_bay`` to a bay
in the stretch and its margins (half as many in the absorbers), and on every
gauge of the detector, so that a crib's rail segment is a whole number of
elements.

Worked example:

    >>> from sim_core.track.spec import Support, TrackSpec
    >>> t = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    >>> lay = layout(t, 0.0, 3.0, gauges=(0.1, 0.5), margin_bays=2, absorber_bays=4)
    >>> lay.sleepers[0], lay.sleepers[-1], round(float(lay.x[0]), 6)
    (-3.6, 6.6, -3.6)
    >>> bool(np.isclose(lay.x, 0.1).any() and np.isclose(lay.x, 0.5).any())
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.track.spec import TrackSpec

MARGIN_BAYS = 3
"""Plain bays each side of the simulated stretch (convergence: docs/MODEL.md §8)."""

ABSORBER_BAYS = 12
"""Absorbing bays beyond each margin."""

ELEMENTS_PER_BAY = 16
"""Rail elements per sleeper bay along the stretch and its margins."""


@dataclass(frozen=True)
class TrackLayout:
    """Nodes ``x`` (increasing), sleeper positions, and each element's absorber factor in [0, 1]."""

    x: NDArray[np.float64]
    sleepers: tuple[float, ...]
    sleeper_nodes: NDArray[np.int64]
    absorb: NDArray[np.float64]

    @property
    def n_nodes(self) -> int:
        return int(self.x.size)

    @property
    def lengths(self) -> NDArray[np.float64]:
        return np.diff(self.x)


def layout(
    track: TrackSpec,
    x0: float,
    x1: float,
    *,
    gauges: tuple[float, ...] = (),
    margin_bays: int = MARGIN_BAYS,
    absorber_bays: int = ABSORBER_BAYS,
    elements_per_bay: int = ELEMENTS_PER_BAY,
) -> TrackLayout:
    """The finite model of ``track`` for a wheel from ``x0`` to ``x1`` and gauges at ``gauges``."""
    ls = track.sleeper_spacing
    lo = min([x0, *gauges])
    hi = max([x1, *gauges])
    s0 = track.first_sleeper + math.floor((lo - track.first_sleeper) / ls + 1e-9) * ls
    s1 = track.first_sleeper + math.ceil((hi - track.first_sleeper) / ls - 1e-9) * ls
    core0 = s0 - margin_bays * ls
    core1 = s1 + margin_bays * ls
    n_core = round((core1 - core0) / ls)
    sleepers = [core0 + (i - absorber_bays) * ls for i in range(n_core + 2 * absorber_bays + 1)]
    sleepers = [round(s, 12) for s in sleepers]
    coarse = max(1, elements_per_bay // 2)
    ends = np.array(sleepers)
    bay = np.arange(ends.size - 1)
    per = np.where(
        (bay >= absorber_bays) & (bay < absorber_bays + n_core), elements_per_bay, coarse
    )
    # bay i's nodes a + (b - a)·k/n, k = 0 … n - 1, all bays at once (the same operations)
    first = np.repeat(np.cumsum(per) - per, per)
    k = np.arange(first.size) - first
    a = np.repeat(ends[:-1], per)
    nodes = np.append(a + np.repeat(np.diff(ends), per) * k / np.repeat(per, per), ends[-1])
    if gauges:
        g = np.asarray(gauges, dtype=np.float64)
        near = np.abs(nodes[:, None] - g[None, :]) < 1e-9
        nodes = np.union1d(nodes, g[~near.any(axis=0)])
        # a plain subdivision node closer than 1/8 element to a gauge is moved onto it, not
        # doubled; sleeper nodes and gauges always stay
        keep = np.concatenate([np.asarray(sleepers), g])
        nodes = _merge_close(nodes, g, keep, 0.125 * ls / elements_per_bay)
    mid = 0.5 * (nodes[:-1] + nodes[1:])
    depth = np.maximum(
        sleepers[0] + absorber_bays * ls - mid, mid - (sleepers[-1] - absorber_bays * ls)
    )
    absorb = np.clip(depth / max(absorber_bays * ls, 1e-12), 0.0, 1.0) ** 2
    idx = np.searchsorted(nodes, np.array(sleepers) - 1e-9)
    return TrackLayout(nodes, tuple(sleepers), idx.astype(np.int64), absorb)


def _merge_close(
    nodes: NDArray[np.float64],
    gauges: NDArray[np.float64],
    fixed: NDArray[np.float64],
    tol: float,
) -> NDArray[np.float64]:
    """``nodes`` without the plain ones closer than ``tol`` to a gauge (``fixed`` ones stay)."""
    d = np.abs(nodes[:, None] - gauges[None, :])
    keep = ~((d < tol) & (d > 1e-9)).any(axis=1)
    is_fixed = (np.abs(nodes[:, None] - fixed[None, :]) <= 1e-9).any(axis=1)
    return nodes[keep | is_fixed]
