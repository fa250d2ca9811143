"""Fields of a passage that the twin does not know, said once per field and sender.

A message ignores the fields it does not know (a newer minor version may add some:
``schemas._base.MessageModel``), so a field in the wrong place is dropped without a word:
a passage with ``vehicle_id`` at its top level instead of inside ``wheel`` is simulated and
diagnosed as a wheel without an identity, and the fleet files its diagnosis under no wheel.
``UnknownFields`` logs a warning naming such fields, the first time each comes from a sender
(the Zenoh source of the sample when its publisher gives one, else every sender alike), so
that a misconfigured adapter is told once, not once a wheel.

    >>> check = UnknownFields()
    >>> payload = b'{"passage_id": "p1", "vehicle_id": "V1", "wheel": {"side": "left", "x": 1}}'
    >>> check.warn("p1", payload, None)  # logged: vehicle_id, wheel.x (and where identity goes)
    ['vehicle_id', 'wheel.x']
    >>> check.warn("p2", payload, None)  # said before
    []
"""

from __future__ import annotations

import json
import logging
import threading
import types
import typing
from typing import Any

from pydantic import BaseModel

from schemas.messages import WheelPassage, WheelRef

log = logging.getLogger("railtwin.twin")

MAX_SENDERS = 1024
"""Senders remembered; beyond them the memory starts again (a warning may come again)."""


def unknown_fields(data: Any, model: type[BaseModel] = WheelPassage, prefix: str = "") -> list[str]:
    """The keys of ``data`` that ``model`` has no field for, and those of its fields that are
    one model (such as ``wheel``), as dotted paths."""
    if not isinstance(data, dict):
        return []
    found: list[str] = []
    for key, value in data.items():
        info = model.model_fields.get(key)
        if info is None:
            found.append(f"{prefix}{key}")
            continue
        inner = _one_model(info.annotation)
        if inner is not None:
            found += unknown_fields(value, inner, f"{prefix}{key}.")
    return found


def _one_model(annotation: Any) -> type[BaseModel] | None:
    """The model of a field typed ``Model`` or ``Model | None`` (not a union of models)."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        annotation = args[0] if len(args) == 1 else None
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return None


class UnknownFields:
    """Warns of the unknown fields of valid passages, once per field and sender."""

    def __init__(self) -> None:
        self._said: dict[str | None, set[str]] = {}
        self._lock = threading.Lock()

    def warn(self, passage_id: str, payload: bytes, sender: str | None) -> list[str]:
        """Log the fields of ``payload`` not said before for ``sender``; returns them."""
        try:
            fields = unknown_fields(json.loads(payload))
        except ValueError:  # validated before: cannot happen, and is no reason to fail
            return []
        if not fields:
            return []
        with self._lock:
            if sender not in self._said and len(self._said) >= MAX_SENDERS:
                self._said.clear()
            said = self._said.setdefault(sender, set())
            new = [f for f in fields if f not in said]
            said.update(new)
        if new:
            hint = ""
            if any(f in WheelRef.model_fields for f in new):
                names = ", ".join(f'"{f}"' for f in WheelRef.model_fields)
                hint = f' (a wheel\'s identity goes inside "wheel": {{{names}}})'
            source = "" if sender is None else f" from {sender}"
            log.warning(
                f"passage {passage_id}{source}: unknown fields ignored: {', '.join(new)}{hint}; "
                "said once per field and sender"
            )
        return new
