"""Shared building blocks of the JSON contract: the strict base model and number types.

Every model forbids unknown keys and is strict: ``"2"`` is not a number,
``1.0`` is not an integer and ``1`` is not a boolean. Integers are accepted
where a float is expected (JSON does not tell ``2`` from ``2.0``). NaN and
±infinity are rejected everywhere.
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field
from pydantic_core import PydanticCustomError

SCHEMA_VERSION = "1.0"
"""Version of the scenario/result contract (CONTRACT.md). Same major = compatible."""


class StrictModel(BaseModel):
    """Base of every contract model: unknown fields rejected, no silent coercion."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


Finite = Annotated[float, Field(allow_inf_nan=False)]
"""Any finite float."""
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
"""A finite float > 0."""
NonNegative = Annotated[float, Field(ge=0, allow_inf_nan=False)]
"""A finite float >= 0."""


def field_error(field: str, message: str, **context: Any) -> PydanticCustomError:
    """A cross-field error that names the offending field.

    ``field`` is the dotted path relative to the model raising the error; it is
    kept in the error's ``ctx`` so that ``schemas.errors`` can report the full
    path (``wheel.outline.length``) rather than just the enclosing model.
    """
    ctx = {"field": field, "reason": message, **context}
    return PydanticCustomError("invalid_field", "{field}: {reason}", ctx)
