"""The streaming twin's messages on Zenoh (and in its MCAP log), as pydantic v2 models.

Every message is JSON with a ``schema_version``; a message's Zenoh encoding is
``application/json;railtwin.<Name>/<version>`` (``encoding_schema``). Key space
(``service.wire.keyspace``), for a site ``<site>``:

| key | direction | model |
|---|---|---|
| ``railtwin/<site>/passage`` | in | ``WheelPassage`` |
| ``railtwin/<site>/force/<passage>`` | out | ``PassageSeries`` (quantity ``force``) |
| ``railtwin/<site>/indentation/<passage>`` | out | ``PassageSeries`` (``indentation``) |
| ``railtwin/<site>/result/<passage>`` | out | ``PassageResult`` |
| ``railtwin/<site>/error`` | out | ``ServiceError`` |
| ``railtwin/<site>/rail`` | queryable | ``RailState`` |
| ``railtwin/<site>/health`` | queryable | ``Health`` |

A wheel is named as railways name it (``WheelRef``, docs/wheel-identity.md): the vehicle
as the site's tag reader reads it, the wheelset counted from the vehicle's end 1 and the
side relative to the vehicle, so ``"V/2/left"`` is the same wheel whichever way it runs.

Versions: a consumer reads every message of its major version (``1.x``) and ignores the
fields it does not know (a newer minor version adds fields, never renames or drops
one); a message of another major version is refused with a clear error.

Series share one time base: sample ``i`` is at ``t = t_start + i / sample_rate``
and ``x = speed · t`` (the wheel centre's position along the site, 0 at the
site's start).

    >>> p = WheelPassage.model_validate_json(
    ...     '{"passage_id": "t1-a3-r", "train_id": "t1", "axle_index": 3, "side": "right",'
    ...     ' "timestamp": 1.7e9, "speed": 44.4, "load": 39240, "mass": 400, "radius": 0.46}')
    >>> p.outline.kind, p.schema_version, p.wheel
    ('round', '1.5', None)
    >>> WheelRef.parse("31-80-4751-123-4/2/left").id
    '31-80-4751-123-4/2/left'
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal

from pydantic import (
    AfterValidator,
    BaseModel,
    Field,
    ValidationError,
    WithJsonSchema,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from schemas._base import KEY_CHUNK as KEY_CHUNK
from schemas._base import MAX_ID_LENGTH as MAX_ID_LENGTH
from schemas._base import (
    Finite,
    Identifier,
    MessageModel,
    NonNegative,
    Positive,
    StrictModel,
    field_error,
)
from schemas.result import Summary, Transition
from schemas.scenario import TWO_PI, Outline, RoundOutline, check_outline_fits

MESSAGE_SCHEMA_VERSION: Final = "1.5"
"""Version of the service's messages that this build writes; it reads any ``1.x``.

1.1 (issue 16): ``WheelRef``; ``WheelPassage.wheel``/``direction``;
``PassageResult.wheel``; ``Diagnosis.wheel``/``timestamp``; unknown fields ignored.
1.2: the site file's ``discrete``/``slab`` foundations and ``detector``;
``PassageResult.channels``.
1.3 (issue 27): ``Diagnosis.model_version`` (re-analysis keyed on it);
``Health.passages_without_wheel``.
1.4 (issue 26): ``MeasuredPassage.channels`` (a detector's crib channels instead of the
contact force; ``force`` becomes optional, exactly one of the two is given).
1.5 (issue 26): ``Diagnosis.calibration``; the site file's ``[calibration]`` table."""

MESSAGE_MAJOR: Final = 1
"""The major version this build reads."""

VERSION_PATTERN: Final = r"^1\.(0|[1-9][0-9]{0,3})$"
"""What a readable ``schema_version`` looks like (published in the JSON Schemas)."""

_VERSION_SHAPE = re.compile(r"(0|[1-9][0-9]{0,3})\.(0|[1-9][0-9]{0,3})")


def version_problem(version: str) -> str | None:
    """Why this build cannot read a message of ``version``, or None if it can (``1.x``)."""
    shape = _VERSION_SHAPE.fullmatch(version)
    if shape is None:
        return (
            f"{version[:40]!r} is not a schema version <major>.<minor> (this build "
            f"writes {MESSAGE_SCHEMA_VERSION})"
        )
    if int(shape.group(1)) != MESSAGE_MAJOR:
        return (
            f"schema version {version} is not supported: this build reads "
            f"{MESSAGE_MAJOR}.x messages (it writes {MESSAGE_SCHEMA_VERSION}); another "
            "major version may change what fields mean, so the reader must be upgraded"
        )
    return None


def check_message_version(version: str) -> str:
    """``version`` if this build reads it (``1.x``), else a clear validation error."""
    problem = version_problem(version)
    if problem is not None:
        raise PydanticCustomError("schema_version_unsupported", "{reason}", {"reason": problem})
    return version


Version = Annotated[
    str,
    AfterValidator(check_message_version),
    WithJsonSchema(
        {
            "type": "string",
            "pattern": VERSION_PATTERN,
            "description": "message schema version; readers accept any 1.x",
        }
    ),
]
"""A message's ``schema_version``: any ``1.x`` is read; kept as received."""

MAX_PASSAGE_SAMPLES = 150_000
"""Cap on the samples of one passage, length/speed·output_sample_rate + 1 (``service.wire.limits``)."""

OUTPUT_BYTES_PER_SAMPLE = 225
"""Bytes of JSON a passage publishes per sample, at most: nine series of ≤ 25 characters."""

MAX_PASSAGE_OUTPUT_BYTES = 48 << 20
"""Cap on the bytes one passage publishes (estimated as samples × OUTPUT_BYTES_PER_SAMPLE)."""


def encoding_schema(model: type[BaseModel]) -> str:
    """The schema name carried in the Zenoh encoding: ``railtwin.WheelPassage/1.4``."""
    return f"railtwin.{model.__name__}/{MESSAGE_SCHEMA_VERSION}"


def parse_encoding_schema(schema: str) -> tuple[str, str] | None:
    """(model name, version) of ``railtwin.<Name>/<version>``, or None if not one."""
    if not schema.startswith("railtwin."):
        return None
    name, sep, version = schema.removeprefix("railtwin.").partition("/")
    if not sep or not name:
        return None
    return name, version


def is_encoding_of(schema: str, model: type[BaseModel]) -> bool:
    """Whether ``schema`` names ``model`` at a version this build reads (any ``1.x``).

    >>> is_encoding_of("railtwin.WheelPassage/1.0", WheelPassage)
    True
    >>> is_encoding_of("railtwin.WheelPassage/2.0", WheelPassage)
    False
    """
    parsed = parse_encoding_schema(schema)
    if parsed is None or parsed[0] != model.__name__:
        return False
    try:
        check_message_version(parsed[1])
    except PydanticCustomError:
        return False
    return True


class VersionedMessage(MessageModel):
    """A top-level message: its ``schema_version`` is checked first, so a message of
    another major version gets that one clear error rather than one per changed field."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION

    @model_validator(mode="before")
    @classmethod
    def _major_first(cls, data: Any) -> Any:
        version = data.get("schema_version") if isinstance(data, dict) else None
        if isinstance(version, str):
            problem = version_problem(version)
            if problem is not None:
                raise field_error("schema_version", problem)
        return data


# --- wheel identity ------------------------------------------------------------------------

Side = Literal["left", "right"]
Direction = Literal["end1_leading", "end2_leading"]


class WheelIdError(ValueError):
    """A text that is not a wheel id ``<vehicle_id>/<wheelset>/<side>``."""


class WheelRef(MessageModel):
    """One wheel of the fleet, named as railways name it (docs/wheel-identity.md).

    ``vehicle_id`` is the vehicle as the site's tag reader (RFID/AEI) reads it;
    ``wheelset`` counts from the vehicle's end 1 (1 = the wheelset nearest end 1);
    ``side`` is relative to the vehicle: as seen standing off end 1, facing the vehicle
    (towards end 2). A wheel keeps its id whichever way the vehicle runs.
    """

    vehicle_id: Identifier = Field(
        description="the vehicle, as the site's RFID/AEI tag reader reads it; a Zenoh key chunk"
    )
    wheelset: int = Field(
        ge=1, description="wheelset number counted from the vehicle's end 1, 1-based"
    )
    side: Side = Field(
        description="relative to the vehicle: as seen standing off end 1, "
        "facing the vehicle (towards end 2); not the direction of travel"
    )

    @property
    def id(self) -> str:
        """``<vehicle_id>/<wheelset>/<side>``: the wheel's id (also its Zenoh key suffix)."""
        return f"{self.vehicle_id}/{self.wheelset}/{self.side}"

    @classmethod
    def parse(cls, text: str) -> WheelRef:
        """The wheel of an id ``"V/2/left"``; ``WheelIdError`` (a ValueError) saying why not."""
        parts = text.split("/")
        if len(parts) != 3:
            raise WheelIdError(
                f"wheel id {text[:200]!r} is not <vehicle_id>/<wheelset>/<side>, "
                "e.g. 31-80-4751-123-4/2/left"
            )
        vehicle, wheelset, side = parts
        if not wheelset.isascii() or not wheelset.isdigit():
            raise WheelIdError(
                f"wheel id {text[:200]!r}: wheelset {wheelset[:20]!r} is not a "
                "number (1 = the wheelset nearest the vehicle's end 1)"
            )
        try:
            return cls(vehicle_id=vehicle, wheelset=int(wheelset), side=side)  # type: ignore[arg-type]
        except ValidationError as exc:
            e = exc.errors(include_url=False)[0]
            raise WheelIdError(f"wheel id {text[:200]!r}: {e['loc'][0]}: {e['msg']}") from None

    def rail_side(self, direction: Direction) -> Side:
        """The rail this wheel runs on, left or right in the direction of travel.

        With end 2 leading, the observer of the convention (off end 1, facing end 2)
        looks the way the vehicle travels: vehicle sides are travel sides. With end 1
        leading they are swapped.
        """
        if direction == "end2_leading":
            return self.side
        return "right" if self.side == "left" else "left"


# --- in ------------------------------------------------------------------------------------


class WheelPassage(VersionedMessage):
    """One wheel passing the measuring site, as the wayside equipment reports it.

    The wheel's centre enters the site (x_C = 0) at ``timestamp`` and rolls at
    constant ``speed`` to the site's end. ``outline`` describes the tread when
    it was measured (e.g. by a wheel-roughness trolley), else it is taken as
    round; ``phase`` is the wheel's rotation φ0 at the site's start
    (CONTRACT.md ``wheel.phase``).
    """

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    passage_id: Identifier = Field(description="unique id of this passage; a Zenoh key chunk")
    train_id: Identifier = Field(description="train the wheel belongs to")
    axle_index: int = Field(ge=0, description="axle number from the front of the train, 0-based")
    side: Side = Field(
        description="which rail/wheel of the axle, left or right in the direction of travel"
    )
    wheel: WheelRef | None = Field(
        default=None,
        description="the wheel's identity, as the site reads it (its tag reader); "
        "null when the site cannot identify the vehicle",
    )
    direction: Direction | None = Field(
        default=None,
        description="which end of the vehicle leads; with wheel, wheel.side must "
        "match side (end2_leading: the same; end1_leading: swapped)",
    )
    timestamp: Finite = Field(description="when the wheel centre entered the site, UNIX s (UTC)")
    speed: Positive = Field(
        le=150.0,
        description="rolling speed V, m/s. A site refuses (invalid_passage, field speed) a speed "
        "at which the passage would have more than MAX_PASSAGE_SAMPLES = 150 000 samples "
        "(floor(length/speed·output_sample_rate) + 1) or publish more than 48 MiB: the speed "
        "must be above length·output_sample_rate/150 000, e.g. 0.4 m/s on a 6 m site at 10 kHz",
    )
    load: Positive = Field(description="vertical wheel load P (includes the unsprung weight), N")
    mass: Positive = Field(description="unsprung mass m per wheel, kg")
    radius: Positive = Field(le=2.0, description="nominal wheel radius R, m")
    outline: Outline = Field(
        default_factory=lambda: RoundOutline(kind="round"),
        description="wheel outline r(θ); round when not measured",
    )
    phase: Finite = Field(
        default=0.0,
        description="rotation φ0 at the site's start, rad; any finite angle, taken modulo 2π",
    )

    @field_validator("phase")
    @classmethod
    def _wrap_phase(cls, v: float) -> float:
        return v % TWO_PI  # CONTRACT.md: any finite φ0, taken modulo 2π

    @model_validator(mode="after")
    def _check_geometry(self) -> WheelPassage:
        """The outline must fit this wheel (else it validates but cannot be simulated)."""
        check_outline_fits(self.outline, self.radius)
        return self

    @model_validator(mode="after")
    def _check_sides(self) -> WheelPassage:
        """Vehicle side, direction and rail side must agree (a tag fitted the wrong way)."""
        if self.wheel is not None and self.direction is not None:
            expected = self.wheel.rail_side(self.direction)
            if expected != self.side:
                raise field_error(
                    "side",
                    f"is {self.side!r} but wheel {self.wheel.id} runs on the {expected} rail "
                    f"with {self.direction} (wheel.side is relative to the vehicle, seen "
                    "from off its end 1: the same as side with end2_leading, swapped with "
                    "end1_leading)",
                )
        return self


# --- out -----------------------------------------------------------------------------------


class PassageSeries(VersionedMessage):
    """One quantity of one passage (or a chunk of it, with ``--pace realtime``).

    ``values[j]`` is sample ``first_index + j``, at t = t_start + (first_index + j)/sample_rate
    and x = x[j].
    """

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    passage_id: Identifier
    quantity: Literal["force", "indentation"]
    unit: Literal["N", "m"]
    sample_rate: Positive = Field(description="samples per second, Hz")
    t_start: Finite = Field(description="time of sample 0 of the passage, s")
    speed: Positive = Field(description="rolling speed, m/s")
    chunk: int = Field(ge=0, description="chunk number, 0-based")
    chunks: int = Field(ge=1, description="number of chunks of this passage (1 unless paced)")
    first_index: int = Field(ge=0, description="sample index of values[0] within the passage")
    samples: int = Field(ge=0, description="number of samples of the whole passage")
    x: list[Finite] = Field(description="wheel centre position along the site, m")
    values: list[Finite] = Field(description="force F, N, or indentation δ, m (δ < 0: no contact)")


class PassageResult(VersionedMessage):
    """Everything the twin computed for one passage."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    passage_id: Identifier
    train_id: Identifier
    axle_index: int = Field(ge=0)
    side: Side
    wheel: WheelRef | None = Field(default=None, description="the passage's wheel, echoed")
    timestamp: Finite = Field(description="the passage's timestamp, echoed, UNIX s")
    speed: Positive = Field(description="rolling speed, m/s")
    sample_rate: Positive = Field(description="output samples per second, Hz")
    t_start: Finite = Field(description="time of sample 0, s (x = speed·t)")
    site_length: Positive = Field(description="length simulated, m")
    x: list[Finite] = Field(description="wheel centre position along the site, m")
    force: list[Finite] = Field(description="contact force F, N")
    indentation: list[Finite] = Field(description="indentation δ, m (negative: out of contact)")
    y_c: list[Finite] = Field(description="wheel centre displacement from static equilibrium, m")
    y_ck: list[Finite] = Field(description="rigid constraint y_C^k(x_C), m")
    channels: dict[str, list[Finite]] | None = Field(
        default=None,
        description="crib id -> the crib's channel Q(x_a) - Q(x_b), N, at each x (the rail's "
        "own shear difference, before any measuring chain); only at a site with a detector",
    )
    transitions: list[Transition] = Field(description="losses/returns of contact, yield/unyield")
    summary: Summary
    rail_revision: int = Field(
        ge=0, description="dented passages applied to the site's rail before this one"
    )
    wall_time: NonNegative = Field(description="simulation wall time, s")
    steps: int = Field(ge=0, description="accepted integrator steps")

    @model_validator(mode="after")
    def _same_length(self) -> PassageResult:
        n = len(self.x)
        for name in ("force", "indentation", "y_c", "y_ck"):
            if len(getattr(self, name)) != n:
                raise field_error(name, f"has {len(getattr(self, name))} samples but x has {n}")
        for crib, values in (self.channels or {}).items():
            if len(values) != n:
                raise field_error(f"channels.{crib}", f"has {len(values)} samples but x has {n}")
        return self


class FieldProblem(MessageModel):
    """One problem with one field of a rejected input."""

    field: str = Field(description="dotted path, e.g. mass or outline.length; '' for the whole")
    message: str
    type: str = Field(description="pydantic error type, e.g. greater_than, json_invalid")


ErrorKind = Literal[
    "invalid_json",
    "invalid_passage",
    "simulation_failed",
    "overloaded",
    "invalid_measurement",
    "unpaired",
]


class ServiceError(VersionedMessage):
    """Why an input was not served. The service goes on with the next one."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    kind: ErrorKind
    message: str
    field: str | None = Field(description="the first offending field (dotted path), if any")
    problems: list[FieldProblem] = Field(default_factory=list)
    passage_id: str | None = Field(
        default=None,
        description="the input's passage_id, when it is a valid id (never an invalid one echoed)",
    )
    received_at: Finite = Field(description="when the input arrived, UNIX s")


class RailState(VersionedMessage):
    """The site's rail now: its profile with the dents left by every wheel so far."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    revision: int = Field(ge=0, description="number of passages that dented the rail")
    passages_done: int = Field(ge=0)
    x: list[Finite] = Field(description="positions along the site, m")
    y: list[Finite] = Field(description="rail height y_r(x) with dents, m")
    dent: list[Finite] = Field(description="accumulated permanent dent depth at x (>= 0), m")
    max_dent: NonNegative = Field(description="deepest accumulated dent, m")


class Health(VersionedMessage):
    """How the service is doing."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    started_at: Finite = Field(description="UNIX s")
    uptime: NonNegative = Field(description="s")
    passages_received: int = Field(ge=0, description="messages received on the passage key")
    passages_done: int = Field(ge=0, description="passages simulated and published")
    passages_without_wheel: int = Field(
        default=0,
        ge=0,
        description="valid passages taken without a wheel (no wheel, or its fields misplaced, "
        "e.g. vehicle_id at the top level): their diagnoses are filed under no wheel (1.3)",
    )
    errors: int = Field(ge=0, description="ServiceErrors published")
    queue_depth: int = Field(ge=0, description="passages waiting to be simulated")
    queue_capacity: int = Field(ge=1)
    last_error: ServiceError | None = None
    mcap_path: str | None = Field(default=None, description="current MCAP log file")
    rrd_path: str | None = Field(default=None, description="this run's Rerun recording")
    calibration: str | None = Field(
        default=None,
        description="the site's online calibration as the last diagnosis used it: each "
        "track value over the site file's, its change over the last 100 calibration wheels, "
        "and the wheels in all (one line); null until a diagnosis at a site the twin "
        "calibrates online (1.5)",
    )


class RejectedInput(VersionedMessage):
    """An input that could not be read as a WheelPassage (MCAP log only), kept verbatim."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    key: str = Field(description="the Zenoh key it arrived on")
    payload_base64: str = Field(description="the payload's bytes, base64")
    payload_text: str = Field(description="the payload decoded as UTF-8 (errors replaced)")
    payload_bytes: int | None = Field(
        default=None,
        ge=0,
        description="set when the payload was too large to keep: its size in bytes (only its "
        "first bytes are kept)",
    )


# --- files ---------------------------------------------------------------------------------


class TrainWheel(StrictModel):
    """One wheel of a sample train: when it reaches the site, relative to the first wheel."""

    offset: NonNegative = Field(description="s after the first wheel")
    passage: WheelPassage


class TrainFile(StrictModel):
    """A train to stream at a site (``recordings/samples/*.json``)."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    train_id: Identifier
    description: str = ""
    source: str = Field(default="", description="where the measured data came from")
    wheels: list[TrainWheel]


_MESSAGE_MODELS: dict[str, type[BaseModel]] = {
    "WheelPassage": WheelPassage,
    "PassageSeries": PassageSeries,
    "PassageResult": PassageResult,
    "ServiceError": ServiceError,
    "RailState": RailState,
    "Health": Health,
    "RejectedInput": RejectedInput,
    "TrainFile": TrainFile,
}

if TYPE_CHECKING:
    MESSAGE_MODELS: dict[str, type[BaseModel]]
    """The service's top-level models by name (for ``railtwin schema``), with the
    diagnosis's (``MeasuredPassage``, ``Diagnosis``)."""
else:

    def __getattr__(name: str) -> Any:
        # MESSAGE_MODELS is built on first use: schemas.diagnosis imports this module,
        # so it cannot be imported here at load time (whichever is imported first).
        if name == "MESSAGE_MODELS":
            from schemas.diagnosis import Diagnosis, MeasuredPassage

            models = {**_MESSAGE_MODELS, "MeasuredPassage": MeasuredPassage, "Diagnosis": Diagnosis}
            globals()["MESSAGE_MODELS"] = models
            return models
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
