"""Loader of a wheel-roughness trolley export → a sampled :class:`WheelOutline`.

The export (see ``sim_core/data/README.md``) is Latin-1 text: an INI-like
``[HEADER]`` of ``Hnn=Label:<TAB>value`` lines, then ``[MeasurementData]``, a
units line such as ``[mm] [µm]`` (a deviation unit of 2–3 characters ending
in ``m`` that is not m or mm is read as µm: the trolley writes its µ in
various encodings, the bundled files as ``¦Ìm``), then one line per point:
``position<TAB>deviation<TAB>`` with a decimal comma (1 mm steps over one turn).

The outline is r(θ) = R + deviation(s), θ = s/R, with R = circumference/2π
(the circumference is the number of points times the step) unless given.

Worked example (one of the bundled measurements, 2881 points, a 0.20 mm flat):

    >>> m = load_wheel_roughness(bundled_measurement("flat_0p3_01.dat"))
    >>> m.positions.size, round(m.circumference, 3), round(m.flat_depth * 1e3, 3)
    (2881, 2.881, 0.204)
    >>> w = m.to_outline()
    >>> round(w.nominal_radius, 5), round(float(w.radius_at(np.array([0.0]))[0]) - w.nominal_radius, 7)
    (0.45853, -0.0002043)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from sim_core.wheel import TWO_PI, WheelOutline

_UNITS = {"m": 1.0, "mm": 1e-3, "µm": 1e-6, "um": 1e-6, "μm": 1e-6}

DATA_DIR = Path(__file__).resolve().parent / "data"
"""The bundled measurements (see data/README.md for their origin and licence)."""


def bundled_measurement(name: str) -> Path:
    """Path of a bundled export, e.g. ``"flat_0p3_01.dat"``."""
    p = DATA_DIR / name
    if not p.is_file():
        have = sorted(q.name for q in DATA_DIR.glob("*.dat"))
        raise ValueError(f"no bundled measurement {name!r}; available: {have}")
    return p


@dataclass(frozen=True)
class WheelRoughness:
    """One measured turn of a wheel tread.

    Attributes:
        header: the ``[HEADER]`` entries by label (``"Measurement Date"`` → ``"10.08.2023"``).
        positions: circumferential positions s_i (m), strictly increasing.
        deviations: radial deviations at s_i (m), negative into the wheel.
        source: where it was read from (for messages).
    """

    header: dict[str, str]
    positions: NDArray[np.float64]
    deviations: NDArray[np.float64]
    source: str = field(default="<text>", compare=False)

    @classmethod
    def from_text(cls, text: str, source: str = "<text>") -> WheelRoughness:
        """Parse the export's content (e.g. a message payload decoded as Latin-1)."""
        lines = text.splitlines()
        header: dict[str, str] = {}
        i = 0
        n = len(lines)
        while i < n and not lines[i].strip():
            i += 1
        if i >= n or lines[i].strip() != "[HEADER]":
            got = lines[i].strip() if i < n else "end of file"
            raise ValueError(f"{source}: line {i + 1}: expected '[HEADER]', got {got!r}")
        i += 1
        while i < n and lines[i].strip() != "[MeasurementData]":
            raw = lines[i].strip()
            if raw:
                if "=" not in raw:
                    raise ValueError(
                        f"{source}: line {i + 1}: header entry must look like 'H01=Label:<TAB>value', got {raw!r}"
                    )
                _, rest = raw.split("=", 1)
                label, _, value = rest.partition("\t")
                header[label.strip().rstrip(":").strip()] = value.strip()
            i += 1
        if i >= n:
            raise ValueError(f"{source}: no '[MeasurementData]' section found")
        i += 1
        if i >= n:
            raise ValueError(
                f"{source}: line {i + 1}: expected a units line like '[mm] [µm]', got end of file"
            )
        units = lines[i].split()
        names = [u.strip("[]") for u in units]
        if (
            len(names) >= 2
            and names[1] not in _UNITS
            and len(names[1]) in (2, 3)
            and names[1].endswith("m")
        ):
            names[1] = "µm"  # the export's µ arrives in various encodings (e.g. '¦Ìm')
        if len(names) < 2 or names[0] not in _UNITS or names[1] not in _UNITS:
            raise ValueError(
                f"{source}: line {i + 1}: expected a units line like '[mm] [µm]', got {lines[i]!r}"
            )
        s_pos, s_dev = _UNITS[names[0]], _UNITS[names[1]]
        i += 1
        pos: list[float] = []
        dev: list[float] = []
        for lineno in range(i + 1, n + 1):
            raw = lines[lineno - 1]
            if not raw.strip():
                continue
            parts = [p for p in raw.strip().split("\t") if p.strip()]
            try:
                if len(parts) != 2:
                    raise ValueError
                pv = float(parts[0].strip().replace(",", "."))
                dv = float(parts[1].strip().replace(",", "."))
            except ValueError:
                raise ValueError(
                    f"{source}: line {lineno}: expected '<position><TAB><deviation>' with a decimal "
                    f"comma, got {raw!r}"
                ) from None
            if not (math.isfinite(pv) and math.isfinite(dv)):
                raise ValueError(f"{source}: line {lineno}: non-finite value in {raw!r}")
            if pos and pv * s_pos <= pos[-1]:
                raise ValueError(
                    f"{source}: line {lineno}: position {parts[0]!r} does not increase "
                    f"(previous {pos[-1] / s_pos!r})"
                )
            pos.append(pv * s_pos)
            dev.append(dv * s_dev)
        if len(pos) < 3:
            raise ValueError(f"{source}: need at least 3 measurement points, got {len(pos)}")
        declared = header.get("Measurement points")
        if declared is not None:
            try:
                nd = int(declared)
            except ValueError:
                raise ValueError(
                    f"{source}: header 'Measurement points' is not an integer: {declared!r}"
                ) from None
            if nd != len(pos):
                raise ValueError(
                    f"{source}: header declares {nd} measurement points but the data has {len(pos)} "
                    f"(truncated file?)"
                )
        return cls(header, np.array(pos), np.array(dev), source)

    @classmethod
    def load(cls, path: str | Path) -> WheelRoughness:
        """Read an export file (Latin-1)."""
        p = Path(path)
        return cls.from_text(p.read_bytes().decode("latin-1"), source=str(p))

    # -- derived ------------------------------------------------------------------------
    @property
    def step(self) -> float:
        """The median spacing of the positions (m)."""
        return float(np.median(np.diff(self.positions)))

    @property
    def circumference(self) -> float:
        """The measured turn's length (m): last - first position plus one step."""
        return float(self.positions[-1] - self.positions[0]) + self.step

    @property
    def flat_depth(self) -> float:
        """Depth of the deepest dip (m): -min(deviation)."""
        return float(-self.deviations.min())

    def to_outline(
        self, nominal_radius: float | None = None, centre_flat: bool = True
    ) -> WheelOutline:
        """The sampled outline r(θ) = R + deviation(s), θ = s/R.

        ``nominal_radius`` defaults to circumference/2π. With ``centre_flat``
        the deepest point (the flat) is turned to θ = 0 (MODEL.md's convention:
        φ = 0 puts the flat on the rail).
        """
        C = self.circumference
        R = C / TWO_PI if nominal_radius is None else float(nominal_radius)
        if not (math.isfinite(R) and R > 0):
            raise ValueError(
                f"wheel roughness: nominal_radius must be positive (m), got {nominal_radius!r}"
            )
        s = self.positions - self.positions[0]
        if centre_flat:
            s0 = s[int(np.argmin(self.deviations))]
            s = np.mod(s - s0 + 0.5 * C, C) - 0.5 * C
        order = np.argsort(s, kind="mergesort")
        theta = s[order] / R
        return WheelOutline.sampled(theta, R + self.deviations[order], nominal_radius=R)


def load_wheel_roughness(path: str | Path) -> WheelRoughness:
    """:meth:`WheelRoughness.load` as a function."""
    return WheelRoughness.load(path)
