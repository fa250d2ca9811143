"""The rail profile y_r(x): flat, cosine, step, sampled (arrays or a CSV file).

Heights are vertical (m, positive up) as a function of the position x along
the rail (m). CONTRACT.md fixes the kinds:

- ``flat()``: y = 0;
- ``cosine(a, λ)``: y = a·cos(2πx/λ);
- ``step(h, x0)``: y = 0 for x < x0, h for x >= x0 (a threshold);
- ``sampled(x, y)``: linear between samples, flat at the end values outside.

Worked example: a 0.1 mm corrugation of 5 cm wavelength has a trough half a
wavelength in, and a sampled ramp is linear inside and flat outside:

    >>> import numpy as np
    >>> rail = RailProfile.cosine(1e-4, 0.05)
    >>> float(rail.height(np.array([0.025]))[0])
    -0.0001
    >>> ramp = RailProfile.sampled(np.array([0.0, 1.0]), np.array([0.0, 1e-3]))
    >>> ramp.height(np.array([-1.0, 0.25, 2.0])).tolist()
    [0.0, 0.00025, 0.001]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim_core.lookup import linear, locate

RAIL_FLAT = 0
RAIL_COSINE = 1
RAIL_STEP = 2
RAIL_SAMPLED = 3

RailKind = Literal["flat", "cosine", "step", "sampled"]
"""The kinds of rail profile (CONTRACT.md)."""

_KIND_CODES: dict[str, int] = {
    "flat": RAIL_FLAT,
    "cosine": RAIL_COSINE,
    "step": RAIL_STEP,
    "sampled": RAIL_SAMPLED,
}


def _empty() -> NDArray[np.float64]:
    return np.empty(0)


def _finite(value: float, what: str) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return v


@dataclass(frozen=True)
class RailProfile:
    """A rail profile y_r(x) (m); build it with the classmethods.

    Attributes:
        kind: ``"flat"``, ``"cosine"``, ``"step"`` or ``"sampled"``.
        amplitude, wavelength: the cosine's a and λ (m).
        step_height, step_position: the step's h and x0 (m).
        x, y: the samples of a sampled profile (m), x strictly increasing.
    """

    kind: RailKind
    amplitude: float = 0.0
    wavelength: float = 0.0
    step_height: float = 0.0
    step_position: float = 0.0
    x: NDArray[np.float64] = field(default_factory=_empty)
    y: NDArray[np.float64] = field(default_factory=_empty)

    def __post_init__(self) -> None:
        if self.kind not in _KIND_CODES:
            raise ValueError(f"rail kind must be one of {sorted(_KIND_CODES)}, got {self.kind!r}")

    # -- constructors -------------------------------------------------------------------
    @classmethod
    def flat(cls) -> RailProfile:
        """The even rail y = 0."""
        return cls("flat")

    @classmethod
    def cosine(cls, amplitude: float, wavelength: float) -> RailProfile:
        """y = a·cos(2πx/λ): amplitude a (m, may be negative), wavelength λ > 0 (m)."""
        a = _finite(amplitude, "cosine rail: amplitude")
        lam = _finite(wavelength, "cosine rail: wavelength")
        if lam <= 0.0:
            raise ValueError(f"cosine rail: wavelength must be positive (m), got {wavelength!r}")
        return cls("cosine", amplitude=a, wavelength=lam)

    @classmethod
    def step(cls, height: float, position: float) -> RailProfile:
        """y = 0 for x < ``position``, ``height`` for x >= ``position`` (m)."""
        return cls(
            "step",
            step_height=_finite(height, "step rail: height"),
            step_position=_finite(position, "step rail: position"),
        )

    @classmethod
    def sampled(cls, x: ArrayLike, y: ArrayLike) -> RailProfile:
        """Samples (x_i, y_i) (m), x strictly increasing; linear between, flat outside."""
        xa = np.asarray(x, dtype=np.float64)
        ya = np.asarray(y, dtype=np.float64)
        if xa.ndim != 1 or ya.ndim != 1 or xa.shape != ya.shape:
            raise ValueError(
                f"sampled rail: x and y must be 1-D arrays of equal length, got shapes "
                f"{xa.shape} and {ya.shape}"
            )
        if xa.size < 2:
            raise ValueError(f"sampled rail: need at least 2 samples, got {xa.size}")
        for name, arr in (("x", xa), ("y", ya)):
            if not np.all(np.isfinite(arr)):
                i = int(np.flatnonzero(~np.isfinite(arr))[0])
                raise ValueError(f"sampled rail: {name}[{i}] is not finite: {float(arr[i])!r}")
        bad = np.flatnonzero(np.diff(xa) <= 0.0)
        if bad.size:
            i = int(bad[0])
            raise ValueError(
                f"sampled rail: x must be strictly increasing; x[{i}] = {float(xa[i])!r} >= "
                f"x[{i + 1}] = {float(xa[i + 1])!r}"
            )
        return cls("sampled", x=xa.copy(), y=ya.copy())

    @classmethod
    def from_csv(cls, path: str | Path) -> RailProfile:
        """A sampled rail from a text file of two columns x, y (m), comma-separated.

        A first line that is not numeric is taken as a header; blank lines and
        lines starting with ``#`` are skipped. Errors name the line number.
        """
        p = Path(path)
        text = p.read_text(encoding="utf-8")
        return cls.from_csv_text(text, source=str(p))

    @classmethod
    def from_csv_text(cls, text: str, source: str = "<text>") -> RailProfile:
        """As :meth:`from_csv`, from the file's content."""
        xs: list[float] = []
        ys: list[float] = []
        first_data = True
        for lineno, raw in enumerate(text.splitlines(), start=1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            parts = [s.strip() for s in (line.split(",") if "," in line else line.split())]
            try:
                if len(parts) != 2:
                    raise ValueError
                xv, yv = float(parts[0]), float(parts[1])
            except ValueError:
                if first_data and not xs:
                    first_data = False  # a header line
                    continue
                raise ValueError(
                    f"{source}: line {lineno}: expected two numbers 'x,y' (m), got {raw!r}"
                ) from None
            first_data = False
            if not (math.isfinite(xv) and math.isfinite(yv)):
                raise ValueError(f"{source}: line {lineno}: non-finite value in {raw!r}")
            if xs and xv <= xs[-1]:
                raise ValueError(
                    f"{source}: line {lineno}: x = {xv!r} does not increase (previous x = {xs[-1]!r})"
                )
            xs.append(xv)
            ys.append(yv)
        if len(xs) < 2:
            raise ValueError(f"{source}: need at least 2 data lines, got {len(xs)}")
        return cls.sampled(np.array(xs), np.array(ys))

    # -- queries ------------------------------------------------------------------------
    @property
    def code(self) -> int:
        """The integer code of ``kind`` used by compiled code."""
        return _KIND_CODES[self.kind]

    @property
    def min_feature_length(self) -> float:
        """The finest feature along the rail (m): sample spacing, λ/16; inf for flat and step."""
        if self.kind == "sampled":
            return float(np.diff(self.x).min())
        if self.kind == "cosine":
            return self.wavelength / 16.0
        return math.inf

    @property
    def height_range(self) -> tuple[float, float]:
        """(min y_r, max y_r) over the whole rail (m)."""
        if self.kind == "cosine":
            return -abs(self.amplitude), abs(self.amplitude)
        if self.kind == "step":
            return min(0.0, self.step_height), max(0.0, self.step_height)
        if self.kind == "sampled":
            return float(self.y.min()), float(self.y.max())
        return 0.0, 0.0

    def compiled_args(self) -> tuple[int, float, float, NDArray[np.float64], NDArray[np.float64]]:
        """(code, a, b, x, y) for :func:`rail_height` (a, b: amplitude/λ or height/position)."""
        if self.kind == "cosine":
            a, b = self.amplitude, self.wavelength
        elif self.kind == "step":
            a, b = self.step_height, self.step_position
        else:
            a, b = 0.0, 0.0
        xs = self.x if self.x.size else np.zeros(1)
        ys = self.y if self.y.size else np.zeros(1)
        return self.code, a, b, xs, ys

    def height(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """y_r at the positions ``x`` (m), vectorised."""
        xq = np.asarray(x, dtype=np.float64)
        out = np.empty(xq.shape)
        code, a, b, xs, ys = self.compiled_args()
        _heights_many(code, a, b, xs, ys, xq.ravel(), out.reshape(-1))
        return out

    def curvature(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Curvature κ_r = -y''/(1 + y'²)^(3/2) (1/m, positive on a crest), vectorised.

        Sampled profiles: the discrete curvature of the polyline at the nearest
        sample (slope change over the mean adjacent spacing); 0 outside. A
        step's corner is not resolved (0): its sharpness is the constraint's
        business, not the Hertz coefficient's.
        """
        xq = np.asarray(x, dtype=np.float64)
        if self.kind == "cosine":
            k = 2.0 * math.pi / self.wavelength
            d1 = -self.amplitude * k * np.sin(k * xq)
            d2 = -self.amplitude * k * k * np.cos(k * xq)
            return np.asarray(-d2 / (1.0 + d1 * d1) ** 1.5)
        if self.kind == "sampled" and self.x.size >= 3:
            s = np.diff(self.y) / np.diff(self.x)
            kap = np.zeros(self.x.size)
            h = 0.5 * (self.x[2:] - self.x[:-2])
            sm = 0.5 * (s[1:] + s[:-1])
            kap[1:-1] = -(s[1:] - s[:-1]) / h / (1.0 + sm * sm) ** 1.5
            i = np.clip(np.searchsorted(self.x, xq), 0, self.x.size - 1)
            im = np.clip(i - 1, 0, self.x.size - 1)
            nearest = np.where(np.abs(self.x[im] - xq) <= np.abs(self.x[i] - xq), im, i)
            inside = (xq >= self.x[0]) & (xq <= self.x[-1])
            return np.where(inside, kap[nearest], 0.0)
        return np.zeros(xq.shape)


@numba.njit(cache=True)
def rail_height(
    code: int, a: float, b: float, xs: NDArray[np.float64], ys: NDArray[np.float64], x: float
) -> float:
    """y_r(x) (m) of a profile given by :meth:`RailProfile.compiled_args`."""
    if code == RAIL_FLAT:
        return 0.0
    if code == RAIL_COSINE:
        return a * math.cos(2.0 * math.pi * x / b)
    if code == RAIL_STEP:
        return a if x >= b else 0.0
    n = xs.size
    if x <= xs[0]:
        return ys[0]
    if x >= xs[n - 1]:
        return ys[n - 1]
    return linear(xs, ys, x, locate(xs, x, 0))


@numba.njit(cache=True)
def _heights_many(
    code: int,
    a: float,
    b: float,
    xs: NDArray[np.float64],
    ys: NDArray[np.float64],
    xq: NDArray[np.float64],
    out: NDArray[np.float64],
) -> None:
    for i in range(xq.size):
        out[i] = rail_height(code, a, b, xs, ys, xq[i])
