"""A dented rail as its base profile plus a dent overlay (MODEL.md §5).

The rail a plastic site's wheels roll on is the site's own profile (flat,
cosine, step, sampled) minus the dents the wheels before pressed in. Kept as
two parts, the base never changes and the overlay is a short list of dent
depths on a fixed lattice k·``DENT_LATTICE``: wheel after wheel the dents land
on the same lattice points, so samples never crowd together, and a new dent
changes the rail only where its footprint lies (the round wheels' constraint
tables are re-tabulated only there: ``sim_core.rail_pass``).

How a passage presses its dent (the swept envelope). While the contact is
plastic the wheel's centre sits at y_C = y_C^k(x_C) - δ; once the wheel has
passed, the rail springs back by the recovery δ_r = δ_Y of the
Hertzian–perfectly plastic law, so the surface is left where the wheel's
outline stood, raised by δ_Y. For a round wheel that is the lower envelope of
the circles

    y_f(p) = min( y_old(p),  min over plastic records k of
                  [ y_C^k(x_Ck) - (δ_k - δ_Y) + R - sqrt(R² - (p - x_Ck)²) ] ).

At the circle's lowest point (p = x_Ck on an even rail) this is MODEL.md §5's
y_r - (δ_c - δ_r); beside it, it also keeps the material the descending or
rising wheel swept through (R·s²/2 below the point-wise rule where the wheel's
path has slope s against the rail). With it an identical wheel that follows
the same path over the dented rail meets δ = δ_Y exactly and leaves nothing
more (elastic shakedown of the geometry); with the point-wise rule it met the
walls of every dent R·s²/2 too early and each wheel added tens of µm
(docs/repeated_passages.md). An out-of-round wheel's outline is
not a circle about x_C: its records press a circle of the nominal radius
about the contact point x_D instead (the point-wise rule, with the footprint
of the nominal circle).

Worked example: a 0.475 m wheel that pressed 0.41 mm deeper than δ_Y at
x = 0.2 m of an even rail, moving level, leaves a dent 0.41 mm deep there and
sqrt(2·0.475·0.41e-3) ≈ 19.7 mm either side of it; a second identical press
changes nothing:

    >>> import numpy as np
    >>> from sim_core.rail import RailProfile
    >>> base = RailProfile.flat()
    >>> ov, changed = DentOverlay.empty().pressed(base, np.array([0.2]), np.array([-0.41e-3]), 0.475)
    >>> round(float(ov.at(np.array([0.2]))[0]) * 1e3, 3), changed is not None
    (0.41, True)
    >>> half = ov.x[ov.depth > 0]
    >>> round(float(half.max() - half.min()) / 2 * 1e3, 1)
    19.5
    >>> ov.pressed(base, np.array([0.2]), np.array([-0.41e-3]), 0.475)[1] is None
    True
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.rail import RailProfile

__all__ = ["DENT_LATTICE", "DentOverlay", "base_samples", "dented_profile"]

DENT_LATTICE = 5e-4
"""Spacing (m) of the dent samples. A dent's floor is an envelope of wheel circles (curvature
at most 1/R): chords 0.5 mm long stay within h²/8R ≈ 66 nm of it, while the next wheel's
table (a kink at every concave vertex) stays small."""

COSINE_CHORD_ERROR = 1e-9
"""Largest distance (m) between a cosine rail and the polyline that replaces it once dented:
a·(π/n)²/2 <= this fixes the samples per wavelength n (32 to 1024)."""

CHANGE_TOL = 1e-13
"""A lattice depth that grows by no more than this (m) is unchanged (round-off of the envelope)."""


def cosine_samples_per_wavelength(rail: RailProfile) -> int:
    """Samples per wavelength that keep a dented cosine rail within ``COSINE_CHORD_ERROR``.

    The chord of a·cos between samples λ/n apart deviates by at most a·(π/n)²/2: for the
    paper's a = 0.1 mm that is n = 703, for a 2 µm corrugation n = 100.
    """
    n = np.pi * np.sqrt(abs(rail.amplitude) / (2.0 * COSINE_CHORD_ERROR))
    return int(min(1024, max(32, np.ceil(n))))


def base_samples(rail: RailProfile, x_start: float, x_end: float) -> NDArray[np.float64]:
    """The positions where a polyline through ``rail`` must have vertices on [x_start, x_end].

    A sampled rail's own samples, a cosine's every λ/n (``cosine_samples_per_wavelength``),
    a step's riser as a 1e-12 m ramp, else the two ends.
    """
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


def _base_heights(rail: RailProfile, x: NDArray[np.float64]) -> NDArray[np.float64]:
    y = rail.height(x)
    if rail.kind == "step":  # the ramp's foot (base_samples) is still at 0
        y[x == rail.step_position - 1e-12] = 0.0
    return y


@numba.njit(cache=True)
def _envelope(
    p: NDArray[np.float64],
    centres: NDArray[np.float64],
    bottoms: NDArray[np.float64],
    radius: float,
    surface: NDArray[np.float64],
) -> NDArray[np.float64]:
    """min(surface, lowest circle of radius ``radius`` with lowest point (centres, bottoms))
    at the sorted positions ``p``; a circle only reaches where it dips below ``surface``."""
    out = surface.copy()
    top = surface.max()
    for k in range(centres.size):
        c, b = centres[k], bottoms[k]
        if b >= top:
            continue
        h = min(top - b, radius)
        w = math.sqrt(h * (2.0 * radius - h))
        j = np.searchsorted(p, c - w)
        while j < p.size and p[j] <= c + w:
            u = p[j] - c
            v = b + radius - math.sqrt(max(radius * radius - u * u, 0.0))
            if v < out[j]:
                out[j] = v
            j += 1
    return out


@dataclass(frozen=True)
class DentOverlay:
    """Dent depths (m, >= 0) at sorted positions ``x`` (m), linear between, 0 outside.

    Every stretch of positive depth is framed by zero-depth points, so stretches far
    apart stay separate. ``x`` holds lattice points k·``spacing`` (and, after a restore
    from a stored rail, that rail's samples).
    """

    x: NDArray[np.float64]
    depth: NDArray[np.float64]
    spacing: float = DENT_LATTICE

    def __post_init__(self) -> None:
        if self.x.shape != self.depth.shape or self.x.ndim != 1:
            raise ValueError(
                f"dent overlay: x and depth must be 1-D of equal length, got {self.x.shape} "
                f"and {self.depth.shape}"
            )
        if self.x.size and not np.all(np.diff(self.x) > 0):
            raise ValueError("dent overlay: x must be strictly increasing")
        if self.depth.size and not (np.all(np.isfinite(self.depth)) and self.depth.min() >= 0):
            raise ValueError("dent overlay: depths must be finite and >= 0 (m)")
        if not (math.isfinite(self.spacing) and self.spacing > 0):
            raise ValueError(f"dent overlay: spacing must be positive (m), got {self.spacing!r}")

    @classmethod
    def empty(cls, spacing: float = DENT_LATTICE) -> DentOverlay:
        return cls(np.empty(0), np.empty(0), spacing)

    @classmethod
    def from_profile(
        cls, base: RailProfile, rail: RailProfile, spacing: float = DENT_LATTICE
    ) -> DentOverlay:
        """The overlay that turns ``base`` into the sampled ``rail`` (a stored dented rail)."""
        if rail.kind != "sampled":
            return cls.empty(spacing)
        depth = np.clip(_base_heights(base, rail.x) - rail.y, 0.0, None)
        depth[depth <= CHANGE_TOL] = 0.0
        return cls(rail.x, depth, spacing)._trimmed()

    @property
    def is_empty(self) -> bool:
        return not bool(np.any(self.depth > 0))

    @property
    def max_depth(self) -> float:
        return float(self.depth.max()) if self.depth.size else 0.0

    def at(self, xq: NDArray[np.float64]) -> NDArray[np.float64]:
        """Dent depth at ``xq`` (m)."""
        if self.x.size == 0:
            return np.zeros(np.shape(xq))
        return np.interp(xq, self.x, self.depth, left=0.0, right=0.0)

    def _trimmed(self) -> DentOverlay:
        """Without the zero-depth points that frame nothing."""
        d = self.depth
        pos = d > 0
        keep = pos.copy()
        keep[:-1] |= pos[1:]
        keep[1:] |= pos[:-1]
        return DentOverlay(self.x[keep], d[keep], self.spacing)

    def pressed(
        self,
        base: RailProfile,
        centres: NDArray[np.float64],
        bottoms: NDArray[np.float64],
        radius: float,
    ) -> tuple[DentOverlay, tuple[float, float] | None]:
        """The overlay after circles of ``radius`` with lowest points (centres, bottoms) (m)
        were pressed into the rail (base minus this overlay); and the stretch (a, b) whose
        heights changed, or None if none did."""
        if centres.size == 0:
            return self, None
        h = self.spacing
        hi_b = base.height_range[1]
        reach_h = float(hi_b - bottoms.min()) + self.max_depth
        w = math.sqrt(max(reach_h, 0.0) * 2.0 * radius) + h
        k = np.arange(math.floor((centres.min() - w) / h), math.ceil((centres.max() + w) / h) + 1)
        lattice = k * h
        if self.x.size:  # no lattice point crowding a kept (restored) sample
            pos = np.clip(np.searchsorted(self.x, lattice), 1, max(self.x.size - 1, 1))
            gap = np.minimum(np.abs(lattice - self.x[pos - 1]), np.abs(lattice - self.x[pos]))
            lattice = lattice[(gap > 0.25 * h) | (gap == 0.0)]
        a0, b0 = float(lattice[0]), float(lattice[-1])
        mine = (self.x >= a0) & (self.x <= b0)
        p = np.union1d(lattice, self.x[mine])
        old = self.at(p)
        base_y = _base_heights(base, p)
        surface = base_y - old
        env = _envelope(
            p, np.ascontiguousarray(centres), np.ascontiguousarray(bottoms), float(radius), surface
        )
        new = np.maximum(old, base_y - env)
        grew = np.flatnonzero(new > old + CHANGE_TOL)
        if grew.size == 0:
            return self, None
        changed = (float(p[max(grew[0] - 1, 0)]), float(p[min(grew[-1] + 1, p.size - 1)]))
        xs = np.concatenate((self.x[self.x < a0], p, self.x[self.x > b0]))
        ds = np.concatenate((self.depth[self.x < a0], new, self.depth[self.x > b0]))
        return DentOverlay(xs, ds, self.spacing)._trimmed(), changed


def dented_profile(
    base: RailProfile, overlay: DentOverlay, x_start: float, x_end: float
) -> RailProfile:
    """``base`` minus ``overlay`` as one sampled profile over [x_start, x_end] (``base``
    itself when there is no dent).

    Vertices: the base's own (``base_samples``: a cosine within ``COSINE_CHORD_ERROR``) and
    the overlay's, except overlay points closer than a quarter lattice step to a base vertex
    (the dent is then sampled there: no segment is shorter than that, which would shorten
    the integrator's steps). Outside [x_start, x_end] the result is flat at its end values.
    """
    if overlay.is_empty:
        return base
    grid = base_samples(base, x_start, x_end)
    pts = overlay.x[(overlay.x > x_start) & (overlay.x < x_end)]
    if pts.size:
        pos = np.clip(np.searchsorted(grid, pts), 1, grid.size - 1)
        gap = np.minimum(np.abs(pts - grid[pos - 1]), np.abs(pts - grid[pos]))
        pts = pts[gap > 0.25 * overlay.spacing]
    x = np.union1d(grid, pts)
    return RailProfile.sampled(x, _base_heights(base, x) - overlay.at(x))
