"""The limits the fleet forecasts against: a site file's ``[diagnosis]`` limits.

A Diagnosis carries its verdict but not the limits its site used, so the fleet is given
one set (``railtwin fleet serve --limits SITE.toml``; default: the defaults of
``schemas.diagnosis.DiagnosisConfig``: 30/40/60 mm, 250/350/400 kN for watch/inspect/
remove). Verdict escalations use each site's own verdict; forecasts use these.

    >>> FleetLimits.defaults().length("remove"), FleetLimits.defaults().force("inspect")
    (0.06, 350000.0)
"""

from __future__ import annotations

import tomllib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from schemas.diagnosis import DiagnosisConfig

LEVELS = ("ok", "watch", "inspect", "remove")
"""Verdict levels, mildest first (as ``sim_core.diagnosis.verdict.LEVELS``)."""


def level_index(verdict: str) -> int:
    return LEVELS.index(verdict)


@dataclass(frozen=True)
class FleetLimits:
    watch_length: float
    inspect_length: float
    remove_length: float
    watch_force: float
    inspect_force: float
    remove_force: float

    @classmethod
    def from_config(cls, d: DiagnosisConfig) -> FleetLimits:
        return cls(
            d.watch_length,
            d.inspect_length,
            d.remove_length,
            d.watch_force,
            d.inspect_force,
            d.remove_force,
        )

    @classmethod
    def defaults(cls) -> FleetLimits:
        return cls.from_config(DiagnosisConfig())

    @classmethod
    def from_site_file(cls, path: Path) -> FleetLimits:
        """The ``[diagnosis]`` limits of a site file (ValueError with the reason)."""
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as exc:
            raise ValueError(f"{path}: cannot read: {exc}") from None
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: not valid TOML: {exc}") from None
        table = data.get("diagnosis", {})
        if not isinstance(table, dict):
            raise ValueError(f"{path}: [diagnosis] must be a table")
        try:
            return cls.from_config(DiagnosisConfig.model_validate(table))
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"])
            raise ValueError(f"{path}: diagnosis.{where}: {first['msg']}") from None

    def length(self, level: str) -> float:
        return float(getattr(self, f"{level}_length"))

    def force(self, level: str) -> float:
        return float(getattr(self, f"{level}_force"))

    def to_json(self) -> dict[str, Any]:
        return asdict(self)
