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
| ``railtwin/health`` | queryable | ``Health`` |

Series share one time base: sample ``i`` is at ``t = t_start + i / sample_rate``
and ``x = speed · t`` (the wheel centre's position along the site, 0 at the
site's start).

    >>> p = WheelPassage.model_validate_json(
    ...     '{"passage_id": "t1-a3-r", "train_id": "t1", "axle_index": 3, "side": "right",'
    ...     ' "timestamp": 1.7e9, "speed": 44.4, "load": 39240, "mass": 400, "radius": 0.46}')
    >>> p.outline.kind, p.schema_version
    ('round', '1.0')
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Any, Literal

from pydantic import BaseModel, Field, field_validator, model_validator

from schemas._base import Finite, NonNegative, Positive, StrictModel, field_error
from schemas.result import Summary, Transition
from schemas.scenario import TWO_PI, Outline, RoundOutline, check_outline_fits

MESSAGE_SCHEMA_VERSION: Literal["1.0"] = "1.0"
"""Version of the service's messages; a consumer accepts the same major version."""

Version = Literal["1.0"]

MAX_ID_LENGTH = 96
"""Longest passage, train or site id (characters)."""

KEY_CHUNK = r"^[A-Za-z0-9_.\-]{1,96}$"
"""An identifier that is safe as one chunk of a Zenoh key (no ``/ * $ ? #``), 1 to 96 long."""

MAX_PASSAGE_SAMPLES = 150_000
"""Cap on the samples of one passage, length/speed·output_sample_rate + 1 (``service.wire.limits``)."""

OUTPUT_BYTES_PER_SAMPLE = 225
"""Bytes of JSON a passage publishes per sample, at most: nine series of ≤ 25 characters."""

MAX_PASSAGE_OUTPUT_BYTES = 48 << 20
"""Cap on the bytes one passage publishes (estimated as samples × OUTPUT_BYTES_PER_SAMPLE)."""

Identifier = Annotated[str, Field(pattern=KEY_CHUNK)]


def encoding_schema(model: type[BaseModel]) -> str:
    """The schema name carried in the Zenoh encoding: ``railtwin.WheelPassage/1.0``."""
    return f"railtwin.{model.__name__}/{MESSAGE_SCHEMA_VERSION}"


# --- in ------------------------------------------------------------------------------------


class WheelPassage(StrictModel):
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
    side: Literal["left", "right"] = Field(description="which rail/wheel of the axle")
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
        default=0.0, description="rotation φ0 at the site's start, rad; any finite angle, taken modulo 2π"
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


# --- out -----------------------------------------------------------------------------------


class PassageSeries(StrictModel):
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


class PassageResult(StrictModel):
    """Everything the twin computed for one passage."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    passage_id: Identifier
    train_id: Identifier
    axle_index: int = Field(ge=0)
    side: Literal["left", "right"]
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
        return self


class FieldProblem(StrictModel):
    """One problem with one field of a rejected input."""

    field: str = Field(description="dotted path, e.g. mass or outline.length; '' for the whole")
    message: str
    type: str = Field(description="pydantic error type, e.g. greater_than, json_invalid")


ErrorKind = Literal[
    "invalid_json", "invalid_passage", "simulation_failed", "overloaded",
    "invalid_measurement", "unpaired",
]


class ServiceError(StrictModel):
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


class RailState(StrictModel):
    """The site's rail now: its profile with the dents left by every wheel so far."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    revision: int = Field(ge=0, description="number of passages that dented the rail")
    passages_done: int = Field(ge=0)
    x: list[Finite] = Field(description="positions along the site, m")
    y: list[Finite] = Field(description="rail height y_r(x) with dents, m")
    dent: list[Finite] = Field(description="accumulated permanent dent depth at x (>= 0), m")
    max_dent: NonNegative = Field(description="deepest accumulated dent, m")


class Health(StrictModel):
    """How the service is doing."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    started_at: Finite = Field(description="UNIX s")
    uptime: NonNegative = Field(description="s")
    passages_received: int = Field(ge=0, description="messages received on the passage key")
    passages_done: int = Field(ge=0, description="passages simulated and published")
    errors: int = Field(ge=0, description="ServiceErrors published")
    queue_depth: int = Field(ge=0, description="passages waiting to be simulated")
    queue_capacity: int = Field(ge=1)
    last_error: ServiceError | None = None
    mcap_path: str | None = Field(default=None, description="current MCAP log file")
    rrd_path: str | None = Field(default=None, description="this run's Rerun recording")


class RejectedInput(StrictModel):
    """An input that could not be read as a WheelPassage (MCAP log only), kept verbatim."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    key: str = Field(description="the Zenoh key it arrived on")
    payload_base64: str = Field(description="the payload's bytes, base64")
    payload_text: str = Field(description="the payload decoded as UTF-8 (errors replaced)")
    payload_bytes: int | None = Field(
        default=None, ge=0,
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

            models = {**_MESSAGE_MODELS, "MeasuredPassage": MeasuredPassage,
                      "Diagnosis": Diagnosis}
            globals()["MESSAGE_MODELS"] = models
            return models
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
