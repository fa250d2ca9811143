"""Hypothesis fuzz of every input the twin takes: raw bytes, arbitrary JSON, and valid
passages and measurements with one field replaced by anything. Each input gets exactly
one answer (a result, a diagnosis or a ServiceError that validates against its schema),
never an internal error, and no answer echoes an input larger than the limits allow.

The twin runs in-process on a recording session stand-in and the stub physics (the
inputs' handling is what is fuzzed, not the physics).
"""

from __future__ import annotations

import json
import time
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from schemas.messages import ServiceError, WheelPassage
from schemas.site import SiteConfig
from service.physics.local import LocalPhysics
from service.physics.stub import StubPhysics
from service.twin.inbound import Inbound
from service.twin.twin import Twin

SITE = SiteConfig.model_validate(
    {
        "site_id": "fuzz",
        "length": 3.0,
        "output_sample_rate": 2000.0,
        "contact": "hertz",
        "rail": {"kind": "flat"},
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
    }
)
GOOD_PASSAGE = json.loads(
    WheelPassage(
        passage_id="p",
        train_id="t",
        axle_index=1,
        side="left",
        timestamp=1.0,
        speed=30.0,
        load=6e4,
        mass=600.0,
        radius=0.46,
    ).model_dump_json()
)
GOOD_MEASURED = {"passage_id": "p", "sample_rate": 1e4, "t_start": 0.0, "force": [6e4] * 20}


class RecordingSession:
    """Stands in for a Zenoh session: keeps what the twin puts."""

    def __init__(self) -> None:
        self.puts: list[tuple[str, bytes]] = []

    def put(self, key: str, data: bytes, **_: Any) -> None:
        self.puts.append((key, data))


def answer_to(payload: bytes, key: str) -> list[tuple[str, bytes]]:
    session = RecordingSession()
    twin = Twin(SITE, session, LocalPhysics(StubPhysics(SITE)))  # type: ignore[arg-type]
    item = Inbound(key, payload, time.time_ns(), time.monotonic())
    twin.serve(item)
    return session.puts


def check_answered(puts: list[tuple[str, bytes]], payload: bytes) -> None:
    errors = [ServiceError.model_validate_json(d) for k, d in puts if k.endswith("/error")]
    results = [k for k, _ in puts if "/result/" in k]
    assert len(errors) + len(results) == 1, puts
    for e in errors:
        assert "internal error" not in e.message, e.message
        assert len(e.model_dump_json()) < 20_000  # an error never echoes a large input


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True) | st.text(max_size=30),
    lambda inner: (
        st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=10), inner, max_size=5)
    ),
    max_leaves=20,
)
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@FUZZ
@given(st.binary(max_size=3000))
def test_raw_bytes_on_the_passage_key(payload: bytes) -> None:
    check_answered(answer_to(payload, "railtwin/fuzz/passage"), payload)


@FUZZ
@given(json_values)
def test_any_json_on_the_passage_key(value: Any) -> None:
    payload = json.dumps(value).encode()
    check_answered(answer_to(payload, "railtwin/fuzz/passage"), payload)


@FUZZ
@given(st.sampled_from(sorted(GOOD_PASSAGE)), json_values)
def test_a_passage_with_one_field_replaced(field: str, value: Any) -> None:
    payload = json.dumps({**GOOD_PASSAGE, field: value}).encode()
    check_answered(answer_to(payload, "railtwin/fuzz/passage"), payload)


@FUZZ
@given(
    st.one_of(
        st.binary(max_size=2000),
        json_values.map(lambda v: json.dumps(v).encode()),
        st.tuples(st.sampled_from(sorted(GOOD_MEASURED)), json_values).map(
            lambda fv: json.dumps({**GOOD_MEASURED, fv[0]: fv[1]}).encode()
        ),
    )
)
def test_anything_on_the_measured_key(payload: bytes) -> None:
    puts = answer_to(payload, "railtwin/fuzz/measured")
    # a valid measurement waits for its passage (no answer yet); anything else is answered
    errors = [ServiceError.model_validate_json(d) for k, d in puts if k.endswith("/error")]
    assert len(puts) == len(errors) <= 1
    for e in errors:
        assert "internal error" not in e.message, e.message
