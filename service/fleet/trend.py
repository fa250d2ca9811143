"""A wheel's growth trend: weighted least squares of a quantity against time, and when it
is predicted to cross a limit, with a 95 % interval.

The model is a straight line y = a + b·(t - t_ref), t in days, fitted by weighted least
squares (weights 1/σ², t_ref the weighted mean time so that a and b are uncorrelated).

- σ of a flat length comes from the diagnosis's 95 % length interval:
  σ = (length_high - length_low) / (2·1.96), at least ``MIN_LENGTH_SIGMA``. The
  covariance is scaled by the Birge ratio max(1, χ²/(n-2)): scatter beyond the stated
  intervals widens the uncertainty, never narrows it.
- Without per-point σ (the peak force at line speed when the diagnosis gives no interval)
  the line is fitted unweighted and σ is estimated from the residuals: that needs 3 points.

The crossing of a limit L is where the line reaches L; its interval is Fieller's: every
time at which L lies inside the line's 95 % confidence band,
(a + b·x - L)² <= z²·(var_a + x²·var_b). When the slope is not significantly positive
(b <= z·se_b) the band never closes: only the earliest date is given.

    >>> tr = fit_trend([0.0, 86400.0, 2 * 86400.0], [0.030, 0.040, 0.050], [0.002] * 3)
    >>> round(tr.slope_per_day * 1e3, 6), tr.points
    (10.0, 3)
    >>> c = crossing(tr, "remove", 0.06)
    >>> c.status, round(c.at / 86400, 6)
    ('forecast', 3.0)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, Literal

DAY = 86400.0
"""Seconds in a day: slopes are per day."""

Z95 = 1.959963984540054
"""Two-sided 95 % normal quantile."""

MIN_LENGTH_SIGMA = 1e-4
"""m: the smallest σ given to a flat length (a zero-width interval would dominate the fit)."""

CrossingStatus = Literal["reached", "forecast", "not_growing"]


@dataclass(frozen=True)
class Trend:
    """y(t) = value_at_ref + slope_per_day·(t - t_ref)/DAY, with standard errors."""

    points: int
    t_first: float
    t_last: float
    t_ref: float
    value_at_ref: float
    value_se: float
    slope_per_day: float
    slope_se_per_day: float
    weighted: bool
    chi2_per_dof: float | None

    def predict(self, t: float) -> tuple[float, float]:
        """(value, standard error of the fitted line) at UNIX time t."""
        x = (t - self.t_ref) / DAY
        se = math.sqrt(self.value_se**2 + (x * self.slope_se_per_day) ** 2)
        return self.value_at_ref + self.slope_per_day * x, se

    @property
    def growing(self) -> bool:
        """The slope is significantly positive at 95 %."""
        return self.slope_per_day - Z95 * self.slope_se_per_day > 0

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class Crossing:
    """When the trend reaches ``limit`` (UNIX s); ``earliest``/``latest``: its 95 % interval."""

    level: str
    limit: float
    status: CrossingStatus
    at: float | None
    earliest: float | None
    latest: float | None

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def fit_trend(
    t: Sequence[float], y: Sequence[float], sigma: Sequence[float] | None = None
) -> Trend | None:
    """The weighted least-squares line of y against t (UNIX s), or None when it is not
    determined (fewer than 2 distinct times, or 3 without ``sigma``)."""
    n = len(t)
    if len(y) != n or (sigma is not None and len(sigma) != n):
        raise ValueError("t, y and sigma must have the same length")
    if n < (2 if sigma is not None else 3):
        return None
    if sigma is not None and any(not (s > 0 and math.isfinite(s)) for s in sigma):
        raise ValueError("every sigma must be finite and > 0")
    w = [1.0 / (s * s) for s in sigma] if sigma is not None else [1.0] * n
    t0 = t[0]
    x = [(ti - t0) / DAY for ti in t]
    sw = sum(w)
    xm = sum(wi * xi for wi, xi in zip(w, x, strict=True)) / sw
    sxx = sum(wi * (xi - xm) ** 2 for wi, xi in zip(w, x, strict=True))
    if sxx <= 1e-18 * max(1.0, sw):
        return None  # all at one time: no slope
    ym = sum(wi * yi for wi, yi in zip(w, y, strict=True)) / sw
    b = sum(wi * (xi - xm) * (yi - ym) for wi, xi, yi in zip(w, x, y, strict=True)) / sxx
    chi2 = sum(wi * (yi - ym - b * (xi - xm)) ** 2 for wi, xi, yi in zip(w, x, y, strict=True))
    dof = n - 2
    if sigma is not None:
        scale = max(1.0, chi2 / dof) if dof > 0 else 1.0
        chi2_dof = chi2 / dof if dof > 0 else None
    else:
        scale = chi2 / dof
        chi2_dof = None
    return Trend(
        points=n,
        t_first=min(t),
        t_last=max(t),
        t_ref=t0 + xm * DAY,
        value_at_ref=ym,
        value_se=math.sqrt(scale / sw),
        slope_per_day=b,
        slope_se_per_day=math.sqrt(scale / sxx),
        weighted=sigma is not None,
        chi2_per_dof=chi2_dof,
    )


def crossing(trend: Trend, level: str, limit: float) -> Crossing:
    """When ``trend`` reaches ``limit``: ``reached`` if the line is at or above it at the
    last point, ``forecast`` if it grows towards it, else ``not_growing``."""
    a, b = trend.value_at_ref, trend.slope_per_day
    va, vb = trend.value_se**2, trend.slope_se_per_day**2
    last_value, _ = trend.predict(trend.t_last)
    if last_value >= limit:
        status: CrossingStatus = "reached"
    elif b > 0:
        status = "forecast"
    else:
        return Crossing(level, limit, "not_growing", None, None, None)
    at = trend.t_ref + (limit - a) / b * DAY
    # Fieller: q(x) = A x² + B x + C <= 0 where L is inside the band
    z2 = Z95 * Z95
    A = b * b - z2 * vb
    B = 2.0 * b * (a - limit)
    C = (a - limit) ** 2 - z2 * va
    disc = B * B - 4.0 * A * C
    earliest: float | None = None
    latest: float | None = None
    if A > 0 and disc >= 0:
        r = math.sqrt(disc)
        x1, x2 = sorted(((-B - r) / (2 * A), (-B + r) / (2 * A)))
        earliest, latest = trend.t_ref + x1 * DAY, trend.t_ref + x2 * DAY
    elif A <= 0 and disc >= 0 and A != 0:
        # the band never closes: the upper edge first meets L at the root before the estimate
        r = math.sqrt(disc)
        roots = sorted(((-B - r) / (2 * A), (-B + r) / (2 * A)))
        x_at = (limit - a) / b
        before = [x for x in roots if x <= x_at]
        if before:
            earliest = trend.t_ref + max(before) * DAY
    return Crossing(level, limit, status, at, earliest, latest)
