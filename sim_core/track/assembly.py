"""The track's mass, damping and stiffness matrices, assembled from its parts.

Each part owns its matrices (as ROSE's model parts do): the rail elements
(``sim_core.track.beam``), the pads (a spring and dashpot from a rail node over
a sleeper to the sleeper mass, or to the ground on a slab), the sleeper masses,
the ballast (sleeper to ground), and the absorbers' dashpots (rail to ground,
mass-proportional). Degrees of freedom: (w, θ) of every rail node in order, then
one vertical displacement per sleeper (discrete track only).

Worked example (a slab track's static stiffness over a sleeper is of the order
of its pads' and the rail's):

    >>> from sim_core.track.spec import Support, TrackSpec
    >>> from sim_core.track.layout import layout
    >>> t = TrackSpec.slab(sleeper_spacing=0.6, first_sleeper=0.0, pad=Support(6e7, 1.5e4))
    >>> m = assemble(t, layout(t, 0.0, 1.2))
    >>> m.k.shape == m.m.shape == m.c.shape, m.n_rail_dofs == 2 * m.layout.n_nodes
    (True, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sim_core.track.beam import mass_matrix, stiffness_matrix
from sim_core.track.layout import TrackLayout
from sim_core.track.spec import TrackSpec

ABSORBER_RATE = 2.0 * np.pi * 600.0
"""Deepest absorber damping per unit rail mass, 1/s (c = rate·ρA per metre at full depth)."""


@dataclass(frozen=True)
class TrackMatrices:
    """Dense M, C, K of the finite track and where its dofs are."""

    track: TrackSpec
    layout: TrackLayout
    m: NDArray[np.float64]
    c: NDArray[np.float64]
    k: NDArray[np.float64]

    @property
    def n_rail_dofs(self) -> int:
        return 2 * self.layout.n_nodes


def assemble(
    track: TrackSpec, lay: TrackLayout, absorber_rate: float = ABSORBER_RATE
) -> TrackMatrices:
    """M, C, K of ``track`` on ``lay``."""
    n_nodes = lay.n_nodes
    n_sl = len(lay.sleepers) if track.kind == "discrete" else 0
    n = 2 * n_nodes + n_sl
    M = np.zeros((n, n))
    C = np.zeros((n, n))
    K = np.zeros((n, n))
    cache: dict[float, tuple[NDArray[np.float64], ...]] = {}
    for e, length in enumerate(lay.lengths):
        key = round(float(length), 12)
        if key not in cache:
            cache[key] = (
                stiffness_matrix(track.rail, key),
                mass_matrix(track.rail, key),
                mass_matrix(track.rail, key, rotary=False),
            )
        ke, me, me_w = cache[key]
        d = slice(2 * e, 2 * e + 4)
        K[d, d] += ke
        M[d, d] += me
        if lay.absorb[e] > 0.0:
            # a dashpot to ground along the element, proportional to its translational mass
            C[d, d] += absorber_rate * lay.absorb[e] * me_w
    for i, node in enumerate(lay.sleeper_nodes):
        w = 2 * int(node)
        kp, cp = track.pad.stiffness, track.pad.damping
        if track.kind == "discrete":
            assert track.ballast is not None
            s = 2 * n_nodes + i
            for mat, v in ((K, kp), (C, cp)):
                mat[w, w] += v
                mat[s, s] += v
                mat[w, s] -= v
                mat[s, w] -= v
            M[s, s] += track.sleeper_mass
            K[s, s] += track.ballast.stiffness
            C[s, s] += track.ballast.damping
        else:
            K[w, w] += kp
            C[w, w] += cp
    return TrackMatrices(track, lay, M, C, K)
