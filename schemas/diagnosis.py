"""Wheel-flat diagnosis: the measured passage in, the verdict out, the site's limits.

A wayside site measures every wheel: a contact-force sensor the vertical wheel–rail force
(``MeasuredPassage.force``), a wheel impact load detector one shear-bridge channel per crib
(``MeasuredPassage.channels``, keyed by the site's ``detector.cribs`` ids). The twin pairs each ``MeasuredPassage`` with its ``WheelPassage`` (by
``passage_id``, in either order of arrival), fits the flat that makes its simulation
look like the measurement (``sim_core.diagnosis``) and answers with a ``Diagnosis``.

| key | direction | model |
|---|---|---|
| ``railtwin/<site>/measured`` | in | ``MeasuredPassage`` |
| ``railtwin/<site>/diagnosis/<passage>`` | out | ``Diagnosis`` |

    >>> m = MeasuredPassage.model_validate_json(
    ...     '{"passage_id": "t1-a3-r", "sample_rate": 10000, "t_start": 0.0,'
    ...     ' "force": [60000, 60100, 59900, 60050, 60000, 60100, 59900, 60050,'
    ...     ' 60000, 60100, 59900, 60050, 60000, 60100, 59900, 60050]}')
    >>> m.samples, m.duration
    (16, 0.0015)
    >>> c = MeasuredPassage.model_validate({
    ...     "passage_id": "t1-a3-r", "sample_rate": 10000, "t_start": 0.0,
    ...     "channels": {"ch1": [0.0] * 16, "ch2": [1.0] * 16}})
    >>> c.force is None, c.channel_ids, c.samples
    (True, ('ch1', 'ch2'), 16)
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from schemas._base import Finite, MessageModel, NonNegative, Positive, StrictModel, field_error
from schemas.calibration import CalibrationRef
from schemas.messages import (
    MESSAGE_SCHEMA_VERSION,
    Identifier,
    Version,
    VersionedMessage,
    WheelRef,
)
from schemas.track import MAX_CRIBS

MAX_MEASURED_SAMPLES = 2_000_000
"""Cap on the samples of one measured passage (200 s at 10 kHz): larger is refused."""

MIN_MEASURED_SAMPLES = 16
"""A record needs at least this many samples to be fitted."""

DEFAULT_WATCH_FORCE = 250e3
DEFAULT_INSPECT_FORCE = 350e3
DEFAULT_REMOVE_FORCE = 400e3
DEFAULT_WATCH_LENGTH = 0.03
DEFAULT_INSPECT_LENGTH = 0.04
DEFAULT_REMOVE_LENGTH = 0.06


class MeasuredPassage(VersionedMessage):
    """The site's measurement of one passage: the contact force, or the detector's channels.

    Exactly one of ``force`` (a contact-force sensor) and ``channels`` (schema 1.4: a wheel
    impact load detector, one shear-bridge channel per crib, keyed by crib id) is given.
    Every series has the same samples: sample k was taken at t = t_start + k / sample_rate,
    with t = 0 when the wheel centre was at the site's start (x = 0).
    """

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    passage_id: Identifier = Field(description="the WheelPassage this measurement belongs to")
    sample_rate: Positive = Field(le=1e6, description="samples per second, Hz")
    t_start: Finite = Field(description="time of sample 0, s (t = 0: wheel centre at x = 0)")
    force: (
        Annotated[
            list[Finite], Field(min_length=MIN_MEASURED_SAMPLES, max_length=MAX_MEASURED_SAMPLES)
        ]
        | None
    ) = Field(
        default=None,
        description="measured vertical wheel–rail force, N; 16 to 2 000 000 samples (the whole "
        "payload at most 64 MiB); null when the site measured channels",
    )
    channels: dict[Identifier, list[Finite]] | None = Field(
        default=None,
        description=f"the detector's measured channels (schema 1.4), N: crib id -> series, 1 to "
        f"{MAX_CRIBS} cribs, each of the same 16 or more samples, all together at most "
        f"{MAX_MEASURED_SAMPLES} values; the ids must be the site's detector.cribs ids; null "
        "when the site measured the contact force",
    )
    speed: Positive | None = Field(
        default=None, le=150.0, description="speed as measured by the site, m/s (optional)"
    )

    @model_validator(mode="after")
    def _one_measurement(self) -> MeasuredPassage:
        if (self.force is None) == (self.channels is None):
            raise field_error(
                "force",
                "give exactly one of force (a contact-force sensor) and channels (a detector's "
                "cribs)",
            )
        if self.force is not None:
            return self
        channels = self.channels or {}
        if not 1 <= len(channels) <= MAX_CRIBS:
            raise field_error(
                "channels", f"has {len(channels)} channels; 1 to {MAX_CRIBS} are allowed"
            )
        first, series = next(iter(channels.items()))
        n = len(series)
        for crib, values in channels.items():
            if len(values) != n:
                raise field_error(
                    f"channels.{crib}",
                    f"has {len(values)} samples but channels.{first} has {n}: every channel "
                    "has the same samples",
                )
        if n < MIN_MEASURED_SAMPLES:
            raise field_error(
                f"channels.{first}",
                f"has {n} samples, at least {MIN_MEASURED_SAMPLES} are needed",
            )
        if n * len(channels) > MAX_MEASURED_SAMPLES:
            raise field_error(
                "channels",
                f"{len(channels)} channels of {n} samples: more than {MAX_MEASURED_SAMPLES} "
                "values in all",
            )
        return self

    @property
    def channel_ids(self) -> tuple[str, ...]:
        """The crib ids of the channels, as given (empty for a contact-force measurement)."""
        return tuple(self.channels or ())

    @property
    def samples(self) -> int:
        if self.force is not None:
            return len(self.force)
        return len(next(iter((self.channels or {}).values()), []))

    @property
    def duration(self) -> float:
        """s between the first and the last sample."""
        return (self.samples - 1) / self.sample_rate


FlatKindName = Literal["flat", "rounded_flat"]
Verdict = Literal["ok", "watch", "inspect", "remove"]


class FlatFinding(MessageModel):
    """The flat the fit found."""

    kind: FlatKindName = Field(description="flat = fresh (ideal), rounded_flat = worn (haversine)")
    length: Positive = Field(description="chord (flat) or arc (rounded_flat) length, m")
    depth: Positive = Field(description="depth, m (rounded_flat: fitted, 0.7-1.3 x l²/16R)")
    phase: Finite = Field(description="angular position φ0 at the site's start, rad, [0, 2π)")
    length_low: NonNegative = Field(description="lower end of the length interval, m")
    length_high: Positive = Field(description="upper end of the length interval, m")
    depth_factor: Positive | None = Field(
        default=None,
        description="a worn flat's fitted depth over l²/16R (1 for a fresh flat, whose depth "
        "follows from its chord)",
    )


class ModelVersion(MessageModel):
    """Which model made a diagnosis: the software, the track model and the site file.

    Two diagnoses of one passage with the same ``key`` were made by the same model and
    agree; a re-analysis (``railtwin reanalyse``) is keyed on (site, passage, key)."""

    package: str = Field(
        min_length=1, max_length=64, description="railtwin's version (the package's)"
    )
    track: str = Field(
        min_length=1,
        max_length=32,
        description="the track model: the site's foundation kind (rigid, compliant, "
        "discrete, slab)",
    )
    site: str = Field(
        pattern=r"^[0-9a-f]{16}$",
        description="fingerprint of the site file's physics and calibration (everything but "
        "its description): the first 16 hex digits of the SHA-256 of its canonical JSON",
    )

    @property
    def key(self) -> str:
        """``<package>/<track>/<site>``: the version as one string (a database key)."""
        return f"{self.package}/{self.track}/{self.site}"


class Diagnosis(VersionedMessage):
    """The twin's verdict on one measured passage; in the fleet, (site_id, passage_id) is
    its id."""

    schema_version: Version = MESSAGE_SCHEMA_VERSION
    site_id: Identifier
    passage_id: Identifier
    wheel: WheelRef | None = Field(
        default=None,
        description="the passage's wheel, echoed; null when the site did not identify it",
    )
    timestamp: Finite | None = Field(
        default=None,
        description="the passage's timestamp, echoed, UNIX s; always set by 1.1 "
        "producers, absent only in 1.0 messages",
    )
    flat: FlatFinding | None = Field(description="null when no flat is found")
    verdict: Verdict
    reasons: list[str] = Field(description="each limit that was passed, named, with the values")
    peak_force_measured: Finite = Field(description="largest measured force, N")
    peak_force_fit: Finite = Field(
        description="largest force of the best fit, re-simulated over the record as measured, "
        "N (the static load if that simulation could not be resolved; reasons says so)"
    )
    fit_rms: NonNegative = Field(
        description="rms difference between measured and fitted force over the fitted "
        "windows (approach, dip and first impact of each turn), N"
    )
    peak_force_at_line_speed: Finite | None = Field(
        description="the fitted wheel re-simulated at the site's line_speed on the site's own "
        "damper where the site states one, as the site would measure it, N; null without a "
        "line_speed or if that simulation could not be resolved (reasons says so)"
    )
    peak_force_at_line_speed_low: Finite | None = Field(
        default=None,
        description="lower end of the line-speed forecast: the smallest peak over the length "
        "interval's ends, both kinds and the damping band, N; null without a line_speed or "
        "if none of those simulations could be resolved",
    )
    peak_force_at_line_speed_high: Finite | None = Field(
        default=None,
        description="upper end of the line-speed forecast (as _low, the largest), N",
    )
    peak_channel_at_line_speed: Finite | None = Field(
        default=None,
        description="schema 1.5, channel measurements: the detector's peak at line_speed as "
        "its channels would show it (the largest of the cribs' channels through the site's "
        "chain at its sample instants), of the fitted wheel; peak_force_at_line_speed is "
        "then the contact force's peak, N",
    )
    peak_channel_at_line_speed_low: Finite | None = Field(
        default=None,
        description="schema 1.5: lower end of the detector peak's line-speed band (as "
        "peak_force_at_line_speed_low), N",
    )
    peak_channel_at_line_speed_high: Finite | None = Field(
        default=None,
        description="schema 1.5: upper end of the detector peak's line-speed band, N",
    )
    measured: Literal["force", "channels"] | None = Field(
        default=None,
        description="schema 1.5: what the site measured: the contact force, or the "
        "detector's crib channels (then peak_force_measured is the largest channel value "
        "and peak_force_fit the fitted wheel's contact peak); null in older messages",
    )
    noise_level: NonNegative | None = Field(
        default=None,
        description="σ of the measurement's white noise estimated from the record itself "
        "(its third differences), N",
    )
    fit_residual_ratio: NonNegative | None = Field(
        default=None, description="fit_rms / noise_level: 1 is a fit down to the noise"
    )
    explained: bool | None = Field(
        default=None,
        description="whether the fit explains the measurement (fit_residual_ratio below the "
        "limit the model error of unknown roughness and damping allows); when false the "
        "verdict comes from the measured peaks and the upper end of the length interval "
        "(null only in messages of producers older than schema 1.1)",
    )
    wall_time: NonNegative = Field(description="s spent diagnosing")
    model_version: ModelVersion | None = Field(
        default=None,
        description="the model that made this diagnosis (package, track model, site "
        "fingerprint); null only in messages of producers older than schema 1.3",
    )
    calibration: CalibrationRef | None = Field(
        default=None,
        description="the calibration of the track the diagnosis used (nominal, offline or "
        "online, with its fingerprint); null only in messages of producers older than "
        "schema 1.5",
    )


class DiagnosisConfig(StrictModel):
    """The site file's ``[diagnosis]`` table: the measuring chain and the limits.

    Defaults from practice: 350 kN stop and inspect (Trafikverket), 400 kN ≈ 90 kips
    remove (the North American wheel-impact condemning limit), 60 mm flat remove
    (Trafikverket); ``watch`` levels below them.
    """

    line_speed: Positive | None = Field(
        default=None, le=150.0, description="the line's full speed at the site, m/s"
    )
    sensor_lowpass_hz: Positive | None = Field(
        default=None, description="cut-off of the measuring chain's causal Butterworth low-pass, Hz"
    )
    sensor_lowpass_order: int = Field(default=2, ge=1, le=8, description="its order")
    sample_rate: Positive | None = Field(
        default=None,
        le=1e6,
        description="the site's measuring rate, Hz; a measurement at another rate is refused "
        "(absent: any rate)",
    )
    watch_force: Positive = Field(default=DEFAULT_WATCH_FORCE, description="N")
    inspect_force: Positive = Field(default=DEFAULT_INSPECT_FORCE, description="N (Trafikverket)")
    remove_force: Positive = Field(
        default=DEFAULT_REMOVE_FORCE, description="N (≈ 90 kips, North American condemning limit)"
    )
    watch_length: Positive = Field(default=DEFAULT_WATCH_LENGTH, description="flat length, m")
    inspect_length: Positive = Field(default=DEFAULT_INSPECT_LENGTH, description="flat length, m")
    remove_length: Positive = Field(
        default=DEFAULT_REMOVE_LENGTH, description="flat length, m (Trafikverket)"
    )
    pairing_timeout: Positive = Field(
        default=10.0,
        le=3600.0,
        description="s a measurement (or passage) waits for its partner before a ServiceError",
    )

    @model_validator(mode="after")
    def _ordered(self) -> DiagnosisConfig:
        if not self.watch_force <= self.inspect_force <= self.remove_force:
            raise field_error(
                "inspect_force", "force limits must satisfy watch <= inspect <= remove"
            )
        if not self.watch_length <= self.inspect_length <= self.remove_length:
            raise field_error(
                "inspect_length", "length limits must satisfy watch <= inspect <= remove"
            )
        return self
