"""The wheel outline r(θ): round, ideal flat, rounded (haversine) flat, sampled.

θ is the angle in wheel coordinates, measured from the flat's centre (θ = 0);
MODEL.md §2 turns the wheel by φ = φ0 + x_C/R, and the wheel point at angle ψ
from the downward vertical has θ = ψ + φ. All outlines are periodic in 2π.

- ``round(R)``: r ≡ R.
- ``ideal_flat(R, l)``: a fresh flat, the chord of length l:
  d = R - sqrt(R² - l²/4), θ0 = asin(l/2R), r(θ) = (R - d)/cos θ for |θ| ≤ θ0.
- ``rounded_flat(R, l, d)``: a worn flat (haversine):
  r(θ) = R - (d/2)(1 + cos(2π·Rθ/l)) for |Rθ| ≤ l/2.
- ``sampled(θ, r)``: one turn of samples, linear in θ between them, periodic.

Worked example: the paper's ideal flat of length 61.6 mm on R = 0.475 m is
0.9996 mm deep (d ≈ 1 mm), and its centre sits d below the nominal circle:

    >>> w = WheelOutline.ideal_flat(0.475, 0.0616)
    >>> round(w.max_depth * 1e3, 4)
    0.9996
    >>> import numpy as np
    >>> round(float(w.radius_at(np.array([0.0]))[0]), 6), float(w.radius_at(np.array([0.5]))[0])
    (0.474, 0.475)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim_core.lookup import linear, locate

WHEEL_ROUND = 0
WHEEL_IDEAL_FLAT = 1
WHEEL_ROUNDED_FLAT = 2
WHEEL_SAMPLED = 3

WheelKind = Literal["round", "ideal_flat", "rounded_flat", "sampled"]
"""The kinds of wheel outline (CONTRACT.md)."""

_KIND_CODES: dict[str, int] = {
    "round": WHEEL_ROUND,
    "ideal_flat": WHEEL_IDEAL_FLAT,
    "rounded_flat": WHEEL_ROUNDED_FLAT,
    "sampled": WHEEL_SAMPLED,
}

TWO_PI = 2.0 * math.pi


def _empty() -> NDArray[np.float64]:
    return np.empty(0)


def _check_radius(radius: float, what: str = "wheel radius") -> float:
    r = float(radius)
    if not (math.isfinite(r) and r > 0.0):
        raise ValueError(f"{what} must be a positive finite number (m), got {radius!r}")
    return r


@dataclass(frozen=True)
class WheelOutline:
    """A wheel outline r(θ) (m) in wheel coordinates; build it with the classmethods.

    Attributes:
        kind: ``"round"``, ``"ideal_flat"``, ``"rounded_flat"`` or ``"sampled"``.
        radius: the nominal radius R (m): the rolling radius (φ = φ0 + x_C/R)
            and the reference of y_C^k (a round wheel on a flat rail is at 0).
        flat_length: l of a flat (m), 0 otherwise.
        flat_depth: d of a flat (m), 0 otherwise.
        theta: sampled outline: angles (rad), strictly increasing, span < 2π.
        offsets: sampled outline: r(θ) - R at ``theta`` (m).
    """

    kind: WheelKind
    radius: float
    flat_length: float = 0.0
    flat_depth: float = 0.0
    theta: NDArray[np.float64] = field(default_factory=_empty)
    offsets: NDArray[np.float64] = field(default_factory=_empty)

    def __post_init__(self) -> None:
        if self.kind not in _KIND_CODES:
            raise ValueError(
                f"wheel outline kind must be one of {sorted(_KIND_CODES)}, got {self.kind!r}"
            )
        _check_radius(self.radius)

    # -- constructors -------------------------------------------------------------------
    @classmethod
    def round(cls, radius: float) -> WheelOutline:
        """A perfectly round wheel of radius ``radius`` (m)."""
        return cls("round", _check_radius(radius))

    @classmethod
    def ideal_flat(cls, radius: float, length: float) -> WheelOutline:
        """A fresh flat: the chord of length ``length`` (m), centred at θ = 0.

        Its depth is d = R - sqrt(R² - l²/4) (MODEL.md §2).
        """
        R = _check_radius(radius)
        ln = float(length)
        if not (math.isfinite(ln) and ln > 0.0):
            raise ValueError(
                f"ideal flat: length must be a positive finite number (m), got {length!r}"
            )
        if ln >= 2.0 * R:
            raise ValueError(
                f"ideal flat: the chord length {ln!r} m must be shorter than the diameter 2R = {2 * R!r} m"
            )
        half = 0.5 * ln
        depth = half * half / (R + math.sqrt(R * R - half * half))
        return cls("ideal_flat", R, ln, depth)

    @classmethod
    def rounded_flat(cls, radius: float, length: float, depth: float) -> WheelOutline:
        """A worn (haversine) flat of arc length ``length`` and depth ``depth`` (m)."""
        R = _check_radius(radius)
        ln, d = float(length), float(depth)
        if not (math.isfinite(ln) and ln > 0.0):
            raise ValueError(
                f"rounded flat: length must be a positive finite number (m), got {length!r}"
            )
        if ln >= TWO_PI * R:
            raise ValueError(
                f"rounded flat: the flat does not fit: length {ln!r} m must be shorter than the "
                f"circumference 2πR = {TWO_PI * R!r} m"
            )
        if not (math.isfinite(d) and d > 0.0):
            raise ValueError(
                f"rounded flat: depth must be a positive finite number (m), got {depth!r}"
            )
        if d >= R:
            raise ValueError(f"rounded flat: depth {d!r} m must be smaller than the radius {R!r} m")
        return cls("rounded_flat", R, ln, d)

    @classmethod
    def sampled(
        cls,
        theta: ArrayLike,
        radius_values: ArrayLike,
        nominal_radius: float | None = None,
    ) -> WheelOutline:
        """One turn of samples r(θ_i) (m), linear in θ between them, periodic in 2π.

        ``theta`` (rad) must be strictly increasing and span less than 2π (the
        last sample joins the first one a turn later). ``nominal_radius``
        defaults to the mean radius (trapezoidal in θ over the closed turn).
        """
        th = np.asarray(theta, dtype=np.float64)
        rv = np.asarray(radius_values, dtype=np.float64)
        if th.ndim != 1 or rv.ndim != 1 or th.shape != rv.shape:
            raise ValueError(
                f"sampled wheel: theta and radius_values must be 1-D arrays of equal length, "
                f"got shapes {th.shape} and {rv.shape}"
            )
        if th.size < 3:
            raise ValueError(f"sampled wheel: need at least 3 samples, got {th.size}")
        if not np.all(np.isfinite(th)):
            raise ValueError(
                f"sampled wheel: theta has non-finite values at indices {np.flatnonzero(~np.isfinite(th))[:5].tolist()}"
            )
        if not np.all(np.isfinite(rv)):
            raise ValueError(
                f"sampled wheel: radius_values has non-finite values at indices {np.flatnonzero(~np.isfinite(rv))[:5].tolist()}"
            )
        bad = np.flatnonzero(np.diff(th) <= 0.0)
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"sampled wheel: theta must be strictly increasing; theta[{i}] = {float(th[i])!r} >= "
                f"theta[{i + 1}] = {float(th[i + 1])!r}"
            )
        span = float(th[-1] - th[0])
        if span >= TWO_PI:
            raise ValueError(
                f"sampled wheel: theta must span less than one turn (2π), got a span of {span!r} rad"
            )
        if np.any(rv <= 0.0):
            i = int(np.flatnonzero(rv <= 0.0)[0])
            raise ValueError(
                f"sampled wheel: radius_values must be positive, got {float(rv[i])!r} at index {i}"
            )
        if nominal_radius is None:
            dth = np.diff(np.append(th, th[0] + TWO_PI))
            rr = np.append(rv, rv[0])
            R = float(np.sum(0.5 * (rr[:-1] + rr[1:]) * dth) / TWO_PI)
        else:
            R = _check_radius(nominal_radius, "sampled wheel: nominal_radius")
        return cls("sampled", R, theta=th.copy(), offsets=rv - R)

    # -- queries ------------------------------------------------------------------------
    @property
    def code(self) -> int:
        """The integer code of ``kind`` used by compiled code."""
        return _KIND_CODES[self.kind]

    @property
    def nominal_radius(self) -> float:
        """R (m): the rolling radius and the reference of y_C^k."""
        return self.radius

    @property
    def flat_half_angle(self) -> float:
        """θ0 = asin(l/2R) of an ideal flat, l/2R of a rounded flat, 0 otherwise (rad)."""
        if self.kind == "ideal_flat":
            return math.asin(0.5 * self.flat_length / self.radius)
        if self.kind == "rounded_flat":
            return 0.5 * self.flat_length / self.radius
        return 0.0

    @property
    def max_depth(self) -> float:
        """max(R - r(θ)) (m), at least 0: how far the outline dips inside the nominal circle."""
        if self.kind in ("ideal_flat", "rounded_flat"):
            return self.flat_depth
        if self.kind == "sampled":
            return max(0.0, -float(self.offsets.min()))
        return 0.0

    @property
    def max_excess(self) -> float:
        """max(r(θ) - R) (m), at least 0: how far the outline bulges beyond the nominal circle."""
        if self.kind == "sampled":
            return max(0.0, float(self.offsets.max()))
        return 0.0

    @property
    def min_feature_length(self) -> float:
        """The finest feature along the tread (m): flat length/16, sample arc length; inf if round."""
        if self.kind in ("ideal_flat", "rounded_flat"):
            return self.flat_length / 16.0
        if self.kind == "sampled":
            dth = np.diff(np.append(self.theta, self.theta[0] + TWO_PI))
            return float(dth.min()) * self.radius
        return math.inf

    def compiled_args(
        self,
    ) -> tuple[int, float, float, float, NDArray[np.float64], NDArray[np.float64]]:
        """(code, R, a, b, theta, offsets) for :func:`wheel_offset`.

        a, b: θ0 and d of an ideal flat, l and d of a rounded flat; for a
        sampled outline a is the sample spacing if uniform (else 0).
        """
        if self.kind == "ideal_flat":
            a = self.flat_half_angle
        elif self.kind == "sampled":
            d = np.diff(self.theta)
            a = float(d.mean()) if float(d.max() - d.min()) <= 1e-9 * float(d.mean()) else 0.0
        else:
            a = self.flat_length
        th = self.theta if self.theta.size else np.zeros(1)
        dr = self.offsets if self.offsets.size else np.zeros(1)
        return self.code, self.radius, a, self.flat_depth, th, dr

    def radius_at(self, theta: NDArray[np.float64]) -> NDArray[np.float64]:
        """r(θ) (m) at the angles ``theta`` (rad, any real, periodic in 2π), vectorised."""
        t = np.asarray(theta, dtype=np.float64)
        out = np.empty(t.shape)
        code, R, a, b, th, dr = self.compiled_args()
        _offsets_many(code, R, a, b, th, dr, t.ravel(), out.reshape(-1))
        return out + R


@numba.njit(cache=True, inline="always")
def wrap_angle(theta: float) -> float:
    """θ wrapped into [-π, π)."""
    return theta - TWO_PI * math.floor((theta + math.pi) / TWO_PI)


@numba.njit(cache=True)
def wheel_offset(
    code: int,
    R: float,
    a: float,
    b: float,
    th: NDArray[np.float64],
    dr: NDArray[np.float64],
    theta: float,
) -> float:
    """r(θ) - R (m) of an outline given by :meth:`WheelOutline.compiled_args`.

    Computed without cancellation (flats: (2R sin²(θ/2) - d)/cos θ), so that
    depths are exact to ~1e-20 m, not ~1e-16 m.
    """
    if code == WHEEL_ROUND:
        return 0.0
    if code == WHEEL_IDEAL_FLAT:
        t = wrap_angle(theta)
        if abs(t) <= a:
            s = math.sin(0.5 * t)
            return (2.0 * R * s * s - b) / math.cos(t)
        return 0.0
    if code == WHEEL_ROUNDED_FLAT:
        t = wrap_angle(theta)
        s = R * t
        if abs(s) <= 0.5 * a:
            return -0.5 * b * (1.0 + math.cos(TWO_PI * s / a))
        return 0.0
    # sampled, periodic
    n = th.size
    t0 = th[0]
    t = theta - TWO_PI * math.floor((theta - t0) / TWO_PI)
    if t >= th[n - 1]:
        w = (t - th[n - 1]) / (t0 + TWO_PI - th[n - 1])
        return dr[n - 1] + w * (dr[0] - dr[n - 1])
    # uniform samples (a > 0): the interval is found from its index directly
    hint = min(max(int((t - t0) / a), 0), n - 2) if a > 0.0 else 0
    return linear(th, dr, t, locate(th, t, hint))


@numba.njit(cache=True)
def _offsets_many(
    code: int,
    R: float,
    a: float,
    b: float,
    th: NDArray[np.float64],
    dr: NDArray[np.float64],
    t: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    for i in range(t.size):
        out[i] = wheel_offset(code, R, a, b, th, dr, t[i])
