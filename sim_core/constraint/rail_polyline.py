"""A polyline rail (sampled, file, dented or step) as the tabulators read it, made once per rail.

The rail's vertices are extended flat far beyond the stretch asked for (a wheel of radius R
reaches at most R on either side of its centre), with the segment slopes and the height
range. This is wheel-independent work: it is cached per rail object while that object lives
(:class:`PerRailCache`), so tabulating many wheels on one rail does it once.

Worked example: a 1 mm step at x = 0 is the polyline (…, 0, 0) → (0, 1 mm) → (…, 1 mm), its
riser a vertical segment of infinite slope:

    >>> from sim_core.rail import RailProfile
    >>> p = rail_polyline(RailProfile.step(1e-3, 0.0), -0.1, 0.1, 0.46)
    >>> p.vx[1:3].tolist(), p.vy.tolist(), p.slope.tolist()
    ([0.0, 0.0], [0.0, 0.0, 0.001, 0.001], [0.0, inf, 0.0])
"""

from __future__ import annotations

import weakref
from typing import Generic, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from sim_core.rail import RailProfile

__all__ = ["PerRailCache", "RailPolyline", "rail_polyline"]

T = TypeVar("T")


class PerRailCache(Generic[T]):
    """Values computed from a rail object over a stretch [lo, hi], kept while the rail lives.

    A request is served by an entry for the same rail and ``key`` whose stretch covers it;
    at most ``size`` entries (the oldest goes first), entries of dead rails are dropped.
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self._entries: dict[
            tuple[int, object], tuple[weakref.ref[RailProfile], float, float, T]
        ] = {}

    def get(self, rail: RailProfile, key: object, lo: float, hi: float) -> T | None:
        hit = self._entries.get((id(rail), key))
        if hit is not None and hit[0]() is rail and hit[1] <= lo and hit[2] >= hi:
            return hit[3]
        return None

    def put(self, rail: RailProfile, key: object, lo: float, hi: float, value: T) -> None:
        for k in [k for k, v in self._entries.items() if v[0]() is None]:
            del self._entries[k]
        while len(self._entries) >= self.size:
            del self._entries[next(iter(self._entries))]
        self._entries[(id(rail), key)] = (weakref.ref(rail), lo, hi, value)


class RailPolyline(NamedTuple):
    """The wheel-independent preprocessing of a polyline rail."""

    vx: NDArray[np.float64]
    vy: NDArray[np.float64]
    slope: NDArray[np.float64]
    ymax: float
    ymin: float


_CACHE: PerRailCache[RailPolyline] = PerRailCache(64)


def rail_polyline(rail: RailProfile, lo: float, hi: float, R: float) -> RailPolyline:
    """The rail's vertices extended flat to cover [lo - 2R, hi + 2R] and 1 m more, with segment slopes.

    A step rail is the polyline with a vertical riser (slope inf). Cached per rail object.
    """
    if rail.kind not in ("sampled", "step"):
        raise ValueError(f"rail polyline: a {rail.kind!r} rail is not a polyline")
    poly = _CACHE.get(rail, None, lo - 2 * R, hi + 2 * R)
    if poly is not None:
        return poly
    if rail.kind == "step":
        xs = np.array([rail.step_position, rail.step_position])
        ys = np.array([0.0, rail.step_height])
    else:
        xs, ys = rail.x, rail.y
    a = min(lo, float(xs[0])) - 2 * R - 1.0
    b = max(hi, float(xs[-1])) + 2 * R + 1.0
    vx = np.concatenate(([a], xs, [b]))
    vy = np.concatenate(([ys[0]], ys, [ys[-1]]))
    dx = np.diff(vx)
    dy = np.diff(vy)
    with np.errstate(divide="ignore", invalid="ignore"):
        slope = np.where(dx > 0, dy / np.where(dx > 0, dx, 1.0), np.copysign(np.inf, dy))
    poly = RailPolyline(vx, vy, slope, float(vy.max()), float(vy.min()))
    _CACHE.put(rail, None, a, b, poly)
    return poly
