"""Shared building blocks of the JSON contract: the base models and number types.

Every model is strict: ``"2"`` is not a number, ``1.0`` is not an integer and
``1`` is not a boolean. Integers are accepted where a float is expected (JSON
does not tell ``2`` from ``2.0``). NaN and ±infinity are rejected everywhere.

Unknown keys: the files a person writes (a scenario, a site file, a sample
train) are ``StrictModel``s and reject them, so a misspelt key is an error, not
a silently ignored setting. The streaming messages are ``MessageModel``s and
ignore them: a consumer reads every message of its major version, including
one from a newer minor version that added fields (producers write only the
fields they know).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import BaseModel, ConfigDict, Field
from pydantic_core import PydanticCustomError

SCHEMA_VERSION = "1.1"
"""Version of the scenario/result contract (CONTRACT.md). Same major = compatible: this
build reads any 1.x scenario (``Scenario.schema_version`` checks only the major).

1.1: ``discrete`` and ``slab`` foundations, ``detector``, ``series.channels``."""


class StrictModel(BaseModel):
    """Base of every input file's model: unknown fields rejected, no silent coercion."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class MessageModel(BaseModel):
    """Base of every message (and of the parts only messages carry): unknown fields are
    ignored when reading (a newer minor version may have added them), types stay strict."""

    model_config = ConfigDict(extra="ignore", strict=True, frozen=True)


MAX_ID_LENGTH = 96
"""Longest passage, train, site or crib id (characters)."""

KEY_CHUNK = r"^[A-Za-z0-9_.\-]{1,96}$"
"""An identifier that is safe as one chunk of a Zenoh key (no ``/ * $ ? #``), 1 to 96 long."""

Identifier = Annotated[str, Field(pattern=KEY_CHUNK)]
"""An id (site, passage, train, crib): a Zenoh key chunk, so also a safe CSV column name."""

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
