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
from sim_core.passage import PassageOutput
from sim_core.rail import RailProfile

DENT_RAIL_SPACING = 5e-4
"""Spacing (m) of the dent samples written into the rail. Dents are cm long and shallow
(curvature below ~0.1 /m in Fig. 8), so chords 0.5 mm long stay within ~1e-8 m of the
dent while the next wheel's table (a kink at every concave vertex) stays small."""

COSINE_CHORD_ERROR = 1e-9
"""Largest distance (m) between a cosine rail and the polyline that replaces it once dented:
a·(π/n)²/2 <= this fixes the samples per wavelength n (32 to 1024)."""


def dent_profile(
    output: PassageOutput, contact: ContactModel
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(x, depth) of the permanent dents of one passage, depth >= 0 (m).

    Empty arrays for an elastic passage or a law without permanent set
    (only the Hertzian–perfectly plastic law leaves dents; MODEL.md §5).
    """
    if contact.law != ContactLaw.HERTZ_PLASTIC or output.delta_c.size == 0:
        return np.empty(0), np.empty(0)
    t, x, d = output.delta_c_t, output.delta_c_x, output.delta_c
    yields = np.array([tr.t for tr in output.transitions if tr.kind == "yield"])
    plastic_changes = [tr.kind for tr in output.transitions if tr.kind in ("yield", "unyield")]
    # phase id: number of yields at or before each record (0 = plastic from the start)
    phase = np.searchsorted(yields, t, side="right")
    ends_plastic = (plastic_changes[-1] == "yield") if plastic_changes else True
    if ends_plastic:
        keep = (
            phase < (yields.size if yields.size else 1)
            if plastic_changes
            else np.zeros(t.size, bool)
        )
        t, x, d, phase = t[keep], x[keep], d[keep], phase[keep]
    if t.size == 0:
        return np.empty(0), np.empty(0)
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


def cosine_samples_per_wavelength(rail: RailProfile) -> int:
    """Samples per wavelength that keep a dented cosine rail within ``COSINE_CHORD_ERROR``.

    The chord of a·cos between samples λ/n apart deviates by at most a·(π/n)²/2: for the
    paper's a = 0.1 mm that is n = 703, for a 2 µm corrugation n = 100.
    """
    n = np.pi * np.sqrt(abs(rail.amplitude) / (2.0 * COSINE_CHORD_ERROR))
    return int(min(1024, max(32, np.ceil(n))))


def _base_grid(rail: RailProfile, x_start: float, x_end: float) -> NDArray[np.float64]:
    if rail.kind == "sampled":
        inside = rail.x[(rail.x > x_start) & (rail.x < x_end)]
        return np.concatenate(([x_start], inside, [x_end]))
    if rail.kind == "cosine":
        n = (
            int(np.ceil((x_end - x_start) / rail.wavelength * cosine_samples_per_wavelength(rail)))
            + 1
        )
        return np.linspace(x_start, x_end, n)
    if rail.kind == "step":
        pos = rail.step_position
        if x_start < pos < x_end:
            return np.array([x_start, pos - 1e-12, pos, x_end])
    return np.array([x_start, x_end])


def dented_rail(
    rail: RailProfile,
    dents_x: NDArray[np.float64],
    dents_depth: NDArray[np.float64],
    x_start: float,
    x_end: float,
) -> RailProfile:
    """The rail ``rail`` with dents pressed in, as a sampled profile over [x_start, x_end].

    Inside each dented stretch the rail is resampled on the fixed lattice
    k·spacing (spacing = ``DENT_RAIL_SPACING``, or the rail's own median sample
    spacing if finer), replacing the samples there: wheel after wheel the
    dents land on the same lattice, so samples never crowd together (the union
    of each pass's records once left samples 1 µm apart and tables of millions
    of nodes). A step rail's riser becomes a 1e-12 m ramp (a sampled rail has
    strictly increasing x); outside [x_start, x_end] the result is flat at its
    end values.
    """
    if dents_x.size == 0 or not np.any(dents_depth > 0):
        return rail
    base = _base_grid(rail, x_start, x_end)
    spacing = DENT_RAIL_SPACING
    if rail.kind == "sampled" and rail.x.size > 2:
        spacing = min(spacing, float(np.median(np.diff(rail.x))))
    if rail.kind == "cosine":
        spacing = min(spacing, rail.wavelength / cosine_samples_per_wavelength(rail))
    inside = np.concatenate(([0], (dents_depth > 0.0).astype(np.int8), [0]))
    change = np.flatnonzero(np.diff(inside))
    first, last = change[0::2], change[1::2] - 1
    n = dents_x.size
    keep_base = np.ones(base.size, dtype=bool)
    lattice: list[NDArray[np.float64]] = []
    riser = rail.step_position if rail.kind == "step" else np.nan
    for i, j in zip(first, last, strict=True):
        a = max(dents_x[max(i - 1, 0)], x_start)
        b = min(dents_x[min(j + 1, n - 1)], x_end)
        keep_base &= ~((base > a) & (base < b) & (np.abs(base - riser) > 1e-9))
        k = np.arange(np.ceil(a / spacing), np.floor(b / spacing) + 1.0)
        lattice.append(k * spacing)
    kept = base[keep_base]
    pts = np.concatenate(lattice) if lattice else np.empty(0)
    if kept.size and pts.size:
        # no lattice point crowding a sample kept outside the dents
        pos = np.clip(np.searchsorted(kept, pts), 1, kept.size - 1)
        gap = np.minimum(np.abs(pts - kept[pos - 1]), np.abs(pts - kept[pos]))
        pts = pts[gap > 0.25 * spacing]
    grid = np.union1d(kept, pts)
    grid = grid[(grid >= x_start) & (grid <= x_end)]
    y = rail.height(grid)
    if rail.kind == "step" and x_start < rail.step_position < x_end:
        y[grid == rail.step_position - 1e-12] = 0.0
    depth = np.interp(grid, dents_x, dents_depth, left=0.0, right=0.0)
    return RailProfile.sampled(grid, y - depth)
