"""Permanent deformation of the rail (MODEL.md §5): the dents a passage leaves.

With the Hertzian–perfectly plastic law the rail keeps a dent wherever the
contact pressed deeper than δ_Y. With δ_c(x) the largest indentation while
the contact point x_D was at x and recovery δ_r = δ_Y,

    y_f(x) = y_r(x) - (δ_c(x) - δ_r)   where δ_c(x) > δ_Y,   else y_r(x).

The integrator records (t, x_D, δ) densely while the contact is plastic
(``PassageOutput.delta_c_*``); here they become a dent profile and a new,
sampled rail for the next wheel. A dent still being pressed when the
passage's window ends is dropped (else the next wheel would meet a vertical
wall where the record stops).

Worked example (the paper's Fig. 8): a 400 kg wheel pushed down at 0.3 m/s
onto an even rail at 100 km/h, Y = 600 MPa, leaves periodic dents about
0.41 mm deep (see ``tests/test_dents.py``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.dent_overlay import DENT_LATTICE, DentOverlay, dented_profile
from sim_core.passage import PassageOutput
from sim_core.rail import RailProfile


def plastic_records(
    output: PassageOutput,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(t, x_D, δ) of the passage's plastic records that leave a dent.

    A dent still being pressed when the window ends is dropped (else the next wheel
    would meet a vertical wall where the record stops). Empty for an elastic passage.
    """
    t, x, d = output.delta_c_t, output.delta_c_x, output.delta_c
    if t.size == 0:
        return t, x, d
    yields = np.array([tr.t for tr in output.transitions if tr.kind == "yield"])
    plastic_changes = [tr.kind for tr in output.transitions if tr.kind in ("yield", "unyield")]
    ends_plastic = (plastic_changes[-1] == "yield") if plastic_changes else True
    if ends_plastic:
        if not plastic_changes:
            return np.empty(0), np.empty(0), np.empty(0)
        # phase id: number of yields at or before each record (0 = plastic from the start)
        keep = np.searchsorted(yields, t, side="right") < yields.size
        t, x, d = t[keep], x[keep], d[keep]
    return t, x, d


def dent_profile(
    output: PassageOutput, contact: ContactModel
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x, depth) of the permanent dents of one passage by MODEL.md §5's point-wise rule,
    depth = δ_c - δ_Y >= 0 (m) at the contact point.

    Empty arrays for an elastic passage or a law without permanent set (only the
    Hertzian–perfectly plastic law leaves dents). The rail the next wheel meets is made
    by ``sim_core.rail_pass`` (the swept envelope, which is this at each circle's lowest
    point).
    """
    if contact.law != ContactLaw.HERTZ_PLASTIC:
        return np.empty(0), np.empty(0)
    t, x, d = plastic_records(output)
    if t.size == 0:
        return np.empty(0), np.empty(0)
    yields = np.array([tr.t for tr in output.transitions if tr.kind == "yield"])
    phase = np.searchsorted(yields, t, side="right")
    depth = np.clip(d - contact.yield_indentation, 0.0, None)
    grid = np.unique(x)
    out = np.zeros(grid.size)
    for p in np.unique(phase):
        sel = phase == p
        xp, dp = x[sel], depth[sel]
        order = np.argsort(xp, kind="stable")
        xp, dp = xp[order], dp[order]
        # a contact point that stands still (pivot on a corner) keeps its deepest press
        ux, inv = np.unique(xp, return_inverse=True)
        ud = np.zeros(ux.size)
        np.maximum.at(ud, inv, dp)
        out = np.maximum(out, np.interp(grid, ux, ud, left=0.0, right=0.0))
    return grid, out


def dented_rail(
    rail: RailProfile,
    dents_x: NDArray[np.float64],
    dents_depth: NDArray[np.float64],
    x_start: float,
    x_end: float,
) -> RailProfile:
    """The rail ``rail`` with point-wise dents (``dent_profile``) pressed in, as a sampled
    profile over [x_start, x_end].

    The depths are taken on the fixed lattice k·``DENT_LATTICE`` inside each dented
    stretch (``sim_core.dent_overlay``), so wheel after wheel the dents land on the same
    points. A step rail's riser becomes a 1e-12 m ramp; outside [x_start, x_end] the
    result is flat at its end values.
    """
    if dents_x.size == 0 or not np.any(dents_depth > 0):
        return rail
    h = DENT_LATTICE
    inside = np.concatenate(([0], (dents_depth > 0.0).astype(np.int8), [0]))
    change = np.flatnonzero(np.diff(inside))
    n = dents_x.size
    lattice: list[NDArray[np.float64]] = []
    for i, j in zip(change[0::2], change[1::2] - 1, strict=True):
        a = max(dents_x[max(i - 1, 0)], x_start)
        b = min(dents_x[min(j + 1, n - 1)], x_end)
        lattice.append(np.arange(np.floor(a / h), np.ceil(b / h) + 1.0) * h)
    x = np.unique(np.concatenate(lattice))
    depth = np.interp(x, dents_x, dents_depth, left=0.0, right=0.0)
    return dented_profile(rail, DentOverlay(x, depth, h), x_start, x_end)
