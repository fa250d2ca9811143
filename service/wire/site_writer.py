"""A site (``SiteConfig``) written back as a site file (TOML), e.g. by ``railtwin calibrate``.

The standard library reads TOML but does not write it; a site file holds only tables,
strings, numbers, booleans and arrays of them or of small tables, which this writes: the
top-level values first, then one ``[table]`` per nested model (``[foundation]``,
``[foundation.pad]``, ...), lists of models as arrays of inline tables. Every text written
is read back and must validate to the same site (else ``ValueError``: a bug here, not in
the input).

    >>> from schemas.site import SiteConfig
    >>> site = SiteConfig.model_validate({
    ...     "site_id": "km12", "length": 6.0, "output_sample_rate": 10000.0,
    ...     "rail": {"kind": "flat"}, "contact": "hertz",
    ...     "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3}})
    >>> text = dumps_site(site)
    >>> [line for line in text.splitlines() if line.startswith(("site_id", "length", "["))]
    ['site_id = "km12"', 'length = 6.0', '[rail]', '[material]', '[foundation]', '[diagnosis]']
"""

from __future__ import annotations

import json
import math
import re
import tomllib
from typing import Any

from schemas.site import SiteConfig

__all__ = ["dumps_site"]

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE.match(k) else json.dumps(k)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"a site file holds finite numbers only, got {v!r}")
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v, ensure_ascii=False)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + "}"
    raise ValueError(f"cannot write {type(v).__name__} to a site file")


def _table(prefix: str, doc: dict[str, Any], out: list[str]) -> None:
    scalars = {k: v for k, v in doc.items() if not isinstance(v, dict)}
    tables = {k: v for k, v in doc.items() if isinstance(v, dict)}
    if prefix:
        out.append(f"\n[{prefix}]")
    out.extend(f"{_key(k)} = {_value(v)}" for k, v in scalars.items())
    for k, v in tables.items():
        _table(f"{prefix}.{_key(k)}" if prefix else _key(k), v, out)


def dumps_site(site: SiteConfig, header: str = "") -> str:
    """``site`` as site-file TOML, after an optional comment ``header`` (one line a ``#``)."""
    doc = site.model_dump(mode="json", exclude_none=True)
    out = [f"# {line}".rstrip() for line in header.splitlines()] if header else ["# railtwin site"]
    _table("", doc, out)
    text = "\n".join(out) + "\n"
    back = SiteConfig.model_validate(tomllib.loads(text))
    if back != site:
        raise ValueError("the written site file does not read back as the same site")
    return text
