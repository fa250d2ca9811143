"""railtwin's JSON contract: pydantic v2 models of every file and message.

The models are the source of truth (CONTRACT.md fixes the field names; the
models may add fields, never rename or drop them). Every model rejects NaN and
infinities and does not coerce strings to numbers; the models of files a person
writes reject unknown fields (``StrictModel``), the streaming messages ignore them
(``MessageModel``: a newer minor version may add fields).

``all_json_schemas()`` gives the JSON Schema of every top-level model, by name
(the scenario contract's and the streaming service's messages and site file);
``railtwin schema`` prints them.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from schemas._base import SCHEMA_VERSION, MessageModel, StrictModel
from schemas.errors import ErrorReport, FieldError
from schemas.result import Derived, RailSamples, Result, RunStats, Series, Summary, Transition
from schemas.scenario import (
    MAX_SAMPLES,
    CompliantFoundation,
    CosineRail,
    FlatOutline,
    FlatRail,
    InitialState,
    Material,
    RigidFoundation,
    RoundedFlatOutline,
    RoundOutline,
    SampledOutline,
    SampledRail,
    Scenario,
    StepRail,
    Wheel,
)
from schemas.track import (
    MAX_CRIBS,
    MAX_TRACK_LENGTH,
    Crib,
    Detector,
    DiscreteFoundation,
    RailBeam,
    SlabFoundation,
    TrackSupport,
)

MODELS: dict[str, type[BaseModel]] = {
    "Scenario": Scenario,
    "Result": Result,
    "ErrorReport": ErrorReport,
}
"""Top-level models by the name ``railtwin schema NAME`` knows them by."""


def all_models() -> dict[str, type[BaseModel]]:
    """Every top-level model: the scenario contract's, the service's (messages, site) and
    the fleet's alarm (versioned on its own, ``schemas.fleet.FLEET_SCHEMA_VERSION``)."""
    from schemas.fleet import FleetAlarm
    from schemas.messages import MESSAGE_MODELS
    from schemas.site import SiteConfig

    return {**MODELS, **MESSAGE_MODELS, "SiteConfig": SiteConfig, "FleetAlarm": FleetAlarm}


def all_json_schemas() -> dict[str, dict[str, Any]]:
    """{name: JSON Schema} of every top-level model (``all_models``)."""
    return {name: model.model_json_schema() for name, model in all_models().items()}


__all__ = [
    "MAX_CRIBS",
    "MAX_SAMPLES",
    "MAX_TRACK_LENGTH",
    "MODELS",
    "SCHEMA_VERSION",
    "CompliantFoundation",
    "CosineRail",
    "Crib",
    "Derived",
    "Detector",
    "DiscreteFoundation",
    "ErrorReport",
    "FieldError",
    "FlatOutline",
    "FlatRail",
    "InitialState",
    "Material",
    "MessageModel",
    "RailBeam",
    "RailSamples",
    "Result",
    "RigidFoundation",
    "RoundOutline",
    "RoundedFlatOutline",
    "RunStats",
    "SampledOutline",
    "SampledRail",
    "Scenario",
    "Series",
    "SlabFoundation",
    "StepRail",
    "StrictModel",
    "Summary",
    "TrackSupport",
    "Transition",
    "Wheel",
    "all_json_schemas",
    "all_models",
]
