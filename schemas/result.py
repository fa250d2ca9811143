"""The result of one scenario (CONTRACT.md, "Result").

``series`` holds the samples of the last pass; ``passes_summary`` holds one
summary per pass, in order (its last entry equals ``summary``). Fields beyond
the contract's (allowed: the models may add, never rename): ``series.v_m``,
``transitions[].x``, ``stats``, ``schema_version``. ``series.channels`` (contract 1.1) is
there exactly when the scenario has a detector: one channel a crib, keyed by its id.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from schemas._base import (
    SCHEMA_VERSION,
    Finite,
    MessageModel,
    NonNegative,
    Positive,
    StrictModel,
    field_error,
)
from schemas.scenario import Scenario

TransitionKind = Literal["loss", "contact", "yield", "unyield"]


class Derived(StrictModel):
    """Closed-form quantities of the scenario (MODEL.md §3): C, δ0, f0, F_Y, δ_Y."""

    contact_coefficient: Positive = Field(description="Hertz coefficient C, N/m^1.5")
    static_indentation: Positive = Field(description="δ0 = (P/C)^(2/3), m")
    contact_frequency: Positive = Field(description="linearised contact frequency f0, Hz")
    yield_force: Positive | None = Field(description="F_Y, N; null without a yield stress")
    yield_indentation: Positive | None = Field(description="δ_Y, m; null without a yield stress")


class Series(StrictModel):
    """Samples at ``sample_rate`` over ``duration`` (the last pass)."""

    t: list[Finite] = Field(description="time, s")
    x: list[Finite] = Field(description="wheel centre position x_C = V·t, m")
    y_c: list[Finite] = Field(description="wheel centre displacement from static equilibrium, m")
    v_c: list[Finite] = Field(description="wheel centre velocity, m/s")
    y_ck: list[Finite] = Field(description="rigid constraint y_C^k(x_C), m")
    y_m: list[Finite] = Field(
        description="foundation displacement (0 when rigid; on a discrete or slab track the "
        "rail's displacement w at the wheel centre, up positive), m"
    )
    delta: list[Finite] = Field(description="indentation δ (negative: out of contact), m")
    force: list[Finite] = Field(description="contact force F(δ), N")
    in_contact: list[bool] = Field(description="δ > 0")
    v_m: list[Finite] | None = Field(default=None, description="foundation velocity, m/s")
    channels: dict[str, list[Finite]] | None = Field(
        default=None,
        description="crib id -> the crib's channel Q(x_a) - Q(x_b), N, at sample_rate (the "
        "rail's own shear difference, before any measuring chain); only with a detector",
    )

    @model_validator(mode="after")
    def _same_length(self) -> Series:
        n = len(self.t)
        for name in ("x", "y_c", "v_c", "y_ck", "y_m", "delta", "force", "in_contact", "v_m"):
            values = getattr(self, name)
            if values is not None and len(values) != n:
                raise field_error(name, f"has {len(values)} samples but t has {n}")
        for crib, values in (self.channels or {}).items():
            if len(values) != n:
                raise field_error(f"channels.{crib}", f"has {len(values)} samples but t has {n}")
        return self


class Transition(MessageModel):
    """A located change of contact state, at its exact time (part of messages too: unknown
    fields ignored)."""

    t: Finite = Field(description="time, s")
    kind: TransitionKind
    x: Finite | None = Field(default=None, description="wheel position x_C at that time, m")


class Summary(MessageModel):
    """Scalar outcome of one passage (part of messages too: unknown fields ignored)."""

    peak_force: Finite = Field(description="largest contact force, N")
    min_force: Finite = Field(description="smallest contact force, N (0 if contact was lost)")
    contact_losses: int = Field(ge=0, description="number of losses of contact")
    first_loss_time: Finite | None = Field(description="time of the first loss, s; null if none")
    time_out_of_contact: NonNegative = Field(description="total time with δ < 0, s")
    max_indentation: Finite = Field(description="largest indentation δ, m")
    max_dent: NonNegative = Field(description="deepest permanent dent left on the rail, m")


class RailSamples(StrictModel):
    """A rail profile as samples (linear in between)."""

    x: list[Finite]
    y: list[Finite]

    @model_validator(mode="after")
    def _same_length(self) -> RailSamples:
        if len(self.x) != len(self.y):
            raise field_error("y", f"has {len(self.y)} values but x has {len(self.x)}")
        return self


class RunStats(StrictModel):
    """How the run went (not part of the physics; for benchmarks and diagnosis)."""

    steps: int | None = Field(
        default=None, ge=0, description="accepted integrator steps of the last pass"
    )
    rejected_steps: int | None = Field(default=None, ge=0, description="of the last pass")
    rhs_evaluations: int | None = Field(default=None, ge=0, description="of the last pass")
    wall_time: NonNegative | None = Field(
        default=None, description="seconds for the whole run, all passes"
    )


class Result(StrictModel):
    """Everything one scenario produced (CONTRACT.md)."""

    schema_version: str = SCHEMA_VERSION
    scenario: Scenario = Field(description="echo of the input")
    derived: Derived
    series: Series
    transitions: list[Transition] = Field(description="transitions of the last pass, in time order")
    summary: Summary = Field(description="summary of the last pass")
    rail_after: RailSamples | None = Field(
        description="rail profile after the last pass (only with a plastic law)"
    )
    passes_summary: list[Summary] = Field(description="one summary per pass, in order")
    stats: RunStats | None = None

    @model_validator(mode="after")
    def _channels_of_the_detector(self) -> Result:
        detector = self.scenario.detector
        want = [] if detector is None else [c.id for c in detector.cribs]
        have = list(self.series.channels or {})
        if sorted(have) != sorted(want):
            raise field_error(
                "series.channels",
                f"has channels {have} but the scenario's detector has cribs {want}",
            )
        return self
