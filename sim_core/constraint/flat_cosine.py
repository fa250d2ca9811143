"""A flat's chord on a cosine rail in closed form: where on the chord the rail touches.

The piece sweep (:mod:`sim_core.constraint.wheel_pieces`) needs, at each wheel position,
the maximum over each wheel piece of

    G = y_r(x_D) + D(x_D) - R,

the height of the wheel centre if that piece alone carried it (x_D: the contact point, D:
the depth of the wheel point below the centre). On an ideal flat's chord D is linear in
x_D (slope m, the chord's tilt), so on a cosine rail y_r = a·cos(2πx/λ)

    G'(x_D) = -|a|k·sin(k·u) + m,   u = x_D - c_j  (c_j: a crest, k = 2π/λ)

is not of one sign of curvature: G is concave on the crest's half wave and convex on the
trough's. The chord's maximum is at a corner or inside a crest's *concave window*
[c_j - λ/4, c_j + λ/4] (between the rail's inflections; on the convex half waves between
them G is convex, so its maximum there is at an end). On a window G is concave: its maximum
is at the one stationary point

    u = arcsin(m / (|a|k)) / k   (exists if |m| ≤ |a|k),

or at an end of the window (a corner of the flat, or an inflection, which never carries the
wheel: G rises beyond it). A window's maximum and a corner's value are continuous in the
wheel position, so the sweep locates the jumps of the contact point (from one crest to the
next, from a crest to a corner in a hollow: kinks) by the root of the difference of two, and
the contact sliding on to a corner inside its window (tangent, no kink) by G' = 0 there.

Worked example: a chord whose depth below the wheel centre grows by m = 1e-3 per metre to
the right on the paper's cosine (a = 0.1 mm, λ = 5 cm, |a|k = 0.0126) touches 0.63 mm past
the crest, where the rail falls as steeply as the chord:

    >>> u = crest_contact(1e-3, 1e-4, 0.05)
    >>> round(u * 1e3, 4)
    0.6339
"""

from __future__ import annotations

import math

import numba

from sim_core.rail import RailProfile
from sim_core.wheel import TWO_PI, WheelOutline

__all__ = ["crest_centre", "crest_contact", "crest_index", "supports_flat_cosine"]

MAX_CURVATURE = 0.9
"""Largest rail curvature |a|k² (in units of 1/R) on which the round part of the wheel
(arcs of at most π/4) has one contact per arc (G concave on it)."""


def supports_flat_cosine(wheel: WheelOutline, rail: RailProfile) -> bool:
    """True for an ideal flat on a cosine rail gentler than ``MAX_CURVATURE``/R (e.g. the
    paper's a = 0.1 mm, λ = 5 cm: |a|k² R = 0.75 on R = 0.475 m)."""
    if wheel.kind != "ideal_flat" or rail.kind != "cosine":
        return False
    k = TWO_PI / rail.wavelength
    return abs(rail.amplitude) * k * k * wheel.nominal_radius <= MAX_CURVATURE


@numba.njit(cache=True, inline="always")
def crest_centre(ra: float, rl: float, j: int) -> float:
    """Position (m) of crest j of a·cos(2πx/λ): jλ for a > 0, (j + ½)λ for a < 0."""
    return (j + (0.0 if ra >= 0.0 else 0.5)) * rl


@numba.njit(cache=True, inline="always")
def crest_index(ra: float, rl: float, x: float) -> int:
    """The crest j whose wave [c_j - λ/2, c_j + λ/2) (trough to trough) holds x."""
    return math.floor(x / rl - (0.0 if ra >= 0.0 else 0.5) + 0.5)


@numba.njit(cache=True)
def crest_contact(m: float, ra: float, rl: float) -> float:
    """u = x_D - c_j (m) where the rail's slope equals ``m`` on the crest's concave half
    wave (|u| ≤ λ/4), nan if the rail is nowhere that steep."""
    k = TWO_PI / rl
    s = m / (abs(ra) * k)
    if not (-1.0 <= s <= 1.0):
        return math.nan
    return math.asin(s) / k
