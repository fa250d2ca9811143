"""Load and validate a site file (``site.toml``) into a ``SiteConfig``.

A rail ``{kind = "file", path = ...}`` is read here (CSV ``x,y`` in metres,
path relative to the site file) and replaced by the sampled rail it holds, so
the returned config is self-contained.
"""

from __future__ import annotations

import csv
import tomllib
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from schemas.errors import format_path
from schemas.scenario import SampledRail
from schemas.site import FileRail, SiteConfig


class SiteFileError(ValueError):
    """A site file that cannot be used; the message names the file and the field."""


def load_site(path: Path) -> SiteConfig:
    """Read, validate and resolve ``path``; raises ``SiteFileError``."""
    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise SiteFileError(f"{path}: cannot read: {exc}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise SiteFileError(f"{path}: not valid TOML: {exc}") from exc
    return site_from_dict(raw, base_dir=path.parent, source=str(path))


def site_from_dict(raw: dict[str, Any], *, base_dir: Path, source: str = "site") -> SiteConfig:
    """Validate a site given as a dict (the parsed TOML)."""
    try:
        site = SiteConfig.model_validate(raw)
    except ValidationError as exc:
        lines = [
            f"  {format_path(tuple(e['loc']), raw, e.get('ctx')) or '(top level)'}: {e['msg']}"
            for e in exc.errors(include_url=False)
        ]
        raise SiteFileError(f"{source}: invalid site\n" + "\n".join(lines)) from exc
    if isinstance(site.rail, FileRail):
        rail_path = (base_dir / site.rail.path).resolve()
        x, y = read_rail_csv(rail_path)
        try:
            rail = SampledRail(kind="sampled", x=x, y=y)
        except ValidationError as exc:
            raise SiteFileError(f"{source}: rail file {rail_path}: {exc}") from exc
        site = site.model_copy(update={"rail": rail})
    return site


def read_rail_csv(path: Path) -> tuple[list[float], list[float]]:
    """Rows ``x,y`` in metres; a first row that is not numeric is a header."""
    xs: list[float] = []
    ys: list[float] = []
    try:
        with path.open(newline="", encoding="utf-8") as f:
            for i, row in enumerate(csv.reader(f)):
                if not row or row[0].lstrip().startswith("#"):
                    continue
                try:
                    x, y = float(row[0]), float(row[1])
                except (ValueError, IndexError) as exc:
                    if i == 0:
                        continue
                    raise SiteFileError(
                        f"{path}:{i + 1}: expected 'x,y' numbers, got {row}"
                    ) from exc
                xs.append(x)
                ys.append(y)
    except OSError as exc:
        raise SiteFileError(f"rail file {path}: cannot read: {exc}") from exc
    return xs, ys
