"""Machine-readable error reports (what the CLI prints with ``--format json`` on failure).

A pydantic ``ValidationError`` becomes an ``ErrorReport`` whose items carry a
clean dotted path to the offending field: union tags are dropped
(``wheel.outline.length``, not ``wheel.outline.flat.length``) and cross-field
errors (``schemas._base.field_error``) point at the field they name, not at
the enclosing model.

    >>> from pydantic import ValidationError
    >>> from schemas.scenario import Scenario
    >>> try:
    ...     Scenario.model_validate({"wheel": {}})
    ... except ValidationError as exc:
    ...     report = ErrorReport.from_validation_error(exc, {"wheel": {}})
    >>> report.errors[0].path
    'wheel.mass'
"""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, ValidationError

from schemas._base import StrictModel

ErrorKind = Literal["invalid_input", "invalid_scenario", "runtime_error", "io_error"]


class FieldError(StrictModel):
    """One problem with one field."""

    path: str = Field(description="dotted path to the field, e.g. wheel.outline.length")
    message: str
    type: str = Field(description="pydantic error type, e.g. greater_than, extra_forbidden")


class ErrorReport(StrictModel):
    """Why a command failed."""

    error: ErrorKind
    message: str
    source: str | None = Field(default=None, description="file the input came from")
    errors: list[FieldError] = Field(default_factory=list)

    @classmethod
    def from_validation_error(
        cls, exc: ValidationError, data: Any = None, source: str | None = None
    ) -> ErrorReport:
        """Report of a scenario that failed validation; ``data`` is the raw input, for paths."""
        items = [
            FieldError(
                path=format_path(tuple(e["loc"]), data, e.get("ctx")),
                message=_message(e),
                type=e["type"],
            )
            for e in exc.errors(include_url=False)
        ]
        n = len(items)
        return cls(
            error="invalid_scenario",
            message=f"{n} invalid field{'s' if n != 1 else ''}",
            source=source,
            errors=items,
        )

    def to_text(self) -> str:
        """Human-readable, one line per field."""
        head = self.message if self.source is None else f"{self.source}: {self.message}"
        lines = [head]
        lines += [f"  {e.path or '(top level)'}: {e.message}" for e in self.errors]
        return "\n".join(lines)


def _message(err: Any) -> str:
    ctx = err.get("ctx") or {}
    if err["type"] == "invalid_field" and "reason" in ctx:
        return str(ctx["reason"])
    if err["type"] == "extra_forbidden":
        return "unknown field (not in the contract; check the spelling)"
    if err["type"] == "missing":
        return "required field is missing"
    value = err.get("input")
    if isinstance(value, (int, float, str, bool)) or value is None:
        return f"{err['msg']} (got {value!r})"
    return str(err["msg"])


def format_path(loc: tuple[Any, ...], data: Any = None, ctx: dict[str, Any] | None = None) -> str:
    """Dotted path of a pydantic ``loc``, without discriminator tags.

    Walks ``data`` (the raw input) alongside ``loc``: a loc element that is not a
    key of the current object but equals its ``kind`` is a union tag and is
    skipped. A cross-field error's ``ctx["field"]`` is appended.
    """
    parts: list[str] = []
    cur = data
    for el in loc:
        if isinstance(el, int):
            parts.append(f"[{el}]")
            cur = cur[el] if isinstance(cur, list) and -len(cur) <= el < len(cur) else None
            continue
        if isinstance(cur, dict) and el not in cur and cur.get("kind") == el:
            continue  # discriminated-union tag
        if data is None and el in _UNION_TAGS and parts and parts[-1] in _UNION_FIELDS:
            continue
        parts.append(str(el))
        cur = cur.get(el) if isinstance(cur, dict) else None
    if ctx and ctx.get("field"):
        parts.append(str(ctx["field"]))
    return ".".join(parts).replace(".[", "[")


# Fallback when the raw input is not available: tags of the contract's unions.
_UNION_FIELDS = {"outline", "rail", "foundation"}
_UNION_TAGS = {
    "round",
    "flat",
    "rounded_flat",
    "sampled",
    "cosine",
    "step",
    "rigid",
    "compliant",
    "discrete",
    "slab",
}
