"""Where a flat can change a wheel's constraint on a polyline rail: the stretches around the
passes of its flat over the round wheel's contact point.

A flat lies inside the nominal circle, so y_C^k equals the round wheel's constraint wherever
the round wheel's own contact point is on the round part of the outline. That point's wheel
angle θ*(x) = asin((x_D - x)/R) + x/R + φ0 is non-decreasing along the stretch (the contact
point of a round wheel only moves forward; while it pivots on a rail vertex θ* falls by at
most (1 - cos ψ)/(R cos ψ) per metre, ~1e-7 rad per node interval, far below
``FLAT_ZONE_MARGIN``), so between two nodes of the round table it stays between its values at
the nodes: an interval belongs to a zone if that range meets a flat.

θ* - φ0 is wheel-independent: it is kept per rail and radius with the round table
(:func:`~sim_core.constraint.round_polyline.round_nodes`), as the running bounds of each
interval's range, so that a wheel's zones are two binary searches per flat pass.

Worked example: a wheel of R = 0.46 m with an 80 mm flat (half angle 0.087 rad) passes its
flat over the contact point once per turn (2.89 m): on 6 m of rail it makes two or three
zones of ~81 mm each (the flat's length plus the angle the contact point swings through).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from sim_core.constraint.nodes import XD, X
from sim_core.constraint.rail_polyline import PerRailCache
from sim_core.constraint.round_polyline import round_nodes
from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI

__all__ = ["FLAT_ZONE_MARGIN", "contact_zones"]

FLAT_ZONE_MARGIN = 1e-4
"""Margin (rad) on the flat's angular extent when deciding where the round table holds."""


class ContactAngles(NamedTuple):
    """The round wheel's contact angle θ* - φ0 between its table's nodes, as running bounds."""

    x: NDArray[np.float64]
    """The round table's node positions (m)."""
    lo: NDArray[np.float64]
    """Per interval i (nodes i, i + 1): the least lower end (θ* - margin) of intervals >= i."""
    hi: NDArray[np.float64]
    """Per interval i: the largest upper end (θ* + margin) of intervals <= i."""


_CACHE: PerRailCache[ContactAngles] = PerRailCache(16)


def _contact_angles(
    rail: RailProfile, R: float, step: float, x0: float, x1: float
) -> ContactAngles:
    """The :class:`ContactAngles` of the round wheel of radius R on ``rail``, once per rail and R."""
    hit = _CACHE.get(rail, (float(R), float(step)), x0, x1)
    if hit is not None:
        return hit
    rn = round_nodes(rail, R, step, x0, x1)
    n = rn.shape[0]
    x = np.empty(n)
    lo = np.empty(max(n - 1, 0))
    hi = np.empty(max(n - 1, 0))
    _bounds(rn, float(R), FLAT_ZONE_MARGIN, x, lo, hi)
    out = ContactAngles(x, lo, hi)
    _CACHE.put(rail, (float(R), float(step)), float(x[0]), float(x[-1]), out)
    return out


ASIN_SERIES = 0.1
"""|u| up to which :func:`_asin` sums the series (a rough rail's contact point lies within
|u| = |x_D - x|/R ~ 1e-3 of the wheel's centre line; a 1 mm step's corner ~0.07)."""


@numba.njit(cache=True, inline="always")
def _asin(u: float) -> float:
    """asin u: its Taylor series through u¹⁵ for |u| ≤ ``ASIN_SERIES`` (the first term left
    out is 1.4e-18 of u there), libm's beyond: ~5x faster than libm's call on a 6 m rail's
    31 000 nodes, within one ulp of it (``tests/test_constraint_contact_angles.py``)."""
    if abs(u) > ASIN_SERIES:
        return math.asin(u)
    u2 = u * u
    # Horner from the u¹⁵ term down: the coefficients (2k)!/(4^k (k!)² (2k + 1))
    p = 143.0 / 10240.0
    p = 231.0 / 13312.0 + u2 * p
    p = 63.0 / 2816.0 + u2 * p
    p = 35.0 / 1152.0 + u2 * p
    p = 5.0 / 112.0 + u2 * p
    p = 3.0 / 40.0 + u2 * p
    p = 1.0 / 6.0 + u2 * p
    return u * (1.0 + u2 * p)


@numba.njit(cache=True, _nrt=False)  # type: ignore[call-overload]  # _nrt: not in the stubs
def _bounds(
    rn: NDArray[np.float64],
    R: float,
    margin: float,
    x: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
) -> None:
    """:func:`_contact_angles`' arrays in one pass over the round table's nodes ``rn``: their
    positions into ``x``; θ* - φ0 = asin((x_D - x)/R) + x/R at each, and its running bounds
    (monotone, so that each flat pass is found by binary search; they enclose every
    interval's own range: a zone may only grow where θ* dips, by < 1e-7 rad) into ``lo`` and
    ``hi`` (the numpy form cost 0.75 ms of a 6 m rail's 4 ms table in its reversed
    accumulations and copies). asin is :func:`_asin`: its series near the centre line, libm's
    beyond, within one ulp of libm (numpy's arcsin, vectorised per CPU, differed from libm by
    1 ulp on ~5 % of arguments); x/R is taken as x·(1/R), which moves ~6 % of the bounds by an
    ulp. Both far below ``FLAT_ZONE_MARGIN``."""
    n = rn.shape[0]
    inv_r = 1.0 / R
    for i in range(n):
        xi = rn[i, X]
        x[i] = xi
        th = _asin(min(max((rn[i, XD] - xi) * inv_r, -1.0), 1.0)) + xi * inv_r
        if i < n - 1:
            lo[i] = th - margin  # interval i starts at node i
        if i > 0:
            hi[i - 1] = th + margin  # interval i - 1 ends at node i
    for i in range(1, n - 1):
        if hi[i] < hi[i - 1]:
            hi[i] = hi[i - 1]
    for i in range(n - 3, -1, -1):
        if lo[i] > lo[i + 1]:
            lo[i] = lo[i + 1]


def contact_zones(
    rail: RailProfile,
    R: float,
    step: float,
    half: float,
    phase: float,
    x0: float,
    x1: float,
) -> list[tuple[float, float]]:
    """Stretches of [x0, x1] where a flat (|θ| <= ``half``, r <= R) at wheel ``phase`` can
    change y_C^k on ``rail`` (elsewhere the round wheel's closed form is exact): the round
    table's node intervals whose contact-angle range meets a flat, merged."""
    ca = _contact_angles(rail, R, step, x0, x1)
    x, lo, hi = ca.x, ca.lo, ca.hi
    i0 = max(int(np.searchsorted(x, x0, side="right")) - 1, 0)
    i1 = min(int(np.searchsorted(x, x1, side="left")), x.size - 1)  # intervals i0 .. i1 - 1
    if i1 <= i0:
        return []
    zones: list[tuple[float, float]] = []
    k = math.floor((lo[i0] + phase - half) / TWO_PI)
    while TWO_PI * k - half - phase <= hi[i1 - 1]:
        c = TWO_PI * k - phase  # the flat's centre in θ* - φ0
        k += 1
        # the first interval reaching c - half, the last starting at or before c + half
        first = max(int(np.searchsorted(hi, c - half, side="left")), i0)
        last = min(int(np.searchsorted(lo, c + half, side="right")) - 1, i1 - 1)
        if last < first:
            continue
        a, b = max(float(x[first]), x0), min(float(x[last + 1]), x1)
        if b <= a:
            continue
        if zones and a <= zones[-1][1]:
            zones[-1] = (zones[-1][0], max(b, zones[-1][1]))
        else:
            zones.append((a, b))
    return zones
