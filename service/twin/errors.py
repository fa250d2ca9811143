"""The twin's answers to what it cannot use: every ``ServiceError`` is built here."""

from __future__ import annotations

import json
from typing import Any

from pydantic import BaseModel, ValidationError

from schemas.diagnosis import MeasuredPassage
from schemas.errors import format_path
from schemas.messages import ErrorKind, FieldProblem, ServiceError, WheelPassage
from service.wire import limits


def service_error(
    site_id: str,
    kind: ErrorKind,
    message: str,
    *,
    received_at: float,
    field: str | None = None,
    passage_id: str | None = None,
    problems: list[FieldProblem] | None = None,
) -> ServiceError:
    """A ``ServiceError`` about an input received at ``received_at`` (UNIX s)."""
    return ServiceError(
        site_id=site_id,
        kind=kind,
        message=message,
        field=field,
        problems=problems or [],
        passage_id=passage_id,
        received_at=received_at,
    )


def service_error_from_validation(
    exc: ValidationError,
    payload: bytes,
    site_id: str,
    received_at: float,
    model: type[BaseModel] = WheelPassage,
) -> ServiceError:
    """A ServiceError naming the offending fields of a payload that is not a ``model``
    (a WheelPassage: kind ``invalid_passage``; a MeasuredPassage: ``invalid_measurement``)."""
    try:
        raw: Any = json.loads(payload)
    except ValueError:
        raw = None
    problems = []
    errors = exc.errors(include_url=False)
    for e in errors[: limits.MAX_PROBLEMS]:  # paths and messages clipped: inputs are not echoed
        path = limits.clip(format_path(tuple(e["loc"]), raw, e.get("ctx")))
        ctx = e.get("ctx") or {}
        custom = e["type"] == "invalid_field" and "reason" in ctx
        message = limits.clip(str(ctx["reason"]) if custom else e["msg"])
        problems.append(FieldProblem(field=path, message=message, type=e["type"]))
    invalid_json = any(p.type == "json_invalid" for p in problems)
    first = problems[0] if problems else None
    field_name = first.field if first is not None and first.field else None
    head = "not JSON" if invalid_json else f"not a valid {model.__name__}"
    detail = f"{first.field or '(whole message)'}: {first.message}" if first else ""
    more = f" (+{len(errors) - 1} more)" if len(errors) > 1 else ""
    passage_id = raw.get("passage_id") if isinstance(raw, dict) else None
    measurement = model is MeasuredPassage
    invalid: ErrorKind = "invalid_measurement" if measurement else "invalid_passage"
    what = "measurement" if measurement else "passage"
    return service_error(
        site_id,
        "invalid_json" if invalid_json else invalid,
        f"{what} rejected, {head}: {detail}{more}",
        received_at=received_at,
        field=field_name,
        problems=problems,
        passage_id=limits.valid_id(passage_id),
    )
