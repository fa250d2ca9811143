"""A passage whose identity is misplaced (``vehicle_id`` at the top level instead of inside
``wheel``) is still simulated, but the twin says so: a warning naming the unknown fields, once
per field and sender, and the passages without a wheel counted in its health.

The twin runs in-process on a recording stand-in for the session and the stub physics.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable
from types import SimpleNamespace
from typing import Any

import pytest

from schemas.messages import Health
from service.physics.local import LocalPhysics
from service.physics.stub import StubPhysics
from service.twin.inbound import Inbound
from service.twin.intake import sender_of
from service.twin.twin import Twin
from service.twin.unknown_fields import unknown_fields
from tests.test_fuzz_inputs import GOOD_PASSAGE, SITE, RecordingSession

KEY = "railtwin/fuzz/passage"
WHEEL = {"vehicle_id": "31-80-4751-123-4", "wheelset": 2, "side": "left"}


@pytest.fixture
def twin() -> Twin:
    return Twin(SITE, RecordingSession(), LocalPhysics(StubPhysics(SITE)))  # type: ignore[arg-type]


@pytest.fixture
def log(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> Callable[[], list[str]]:
    """The twin's warnings so far (whatever an earlier test made of the ``railtwin``
    loggers)."""
    monkeypatch.setattr(logging.getLogger("railtwin"), "propagate", True)
    caplog.set_level(logging.WARNING, logger="railtwin.twin")
    return lambda: [
        r.getMessage()
        for r in caplog.records
        if r.name == "railtwin.twin" and r.levelname == "WARNING"
    ]


def passage(pid: str, **fields: Any) -> bytes:
    return json.dumps({**GOOD_PASSAGE, "passage_id": pid, **fields}).encode()


def serve(twin: Twin, payload: bytes, sender: str | None = None) -> None:
    twin.serve(Inbound(KEY, payload, time.time_ns(), time.monotonic(), sender=sender))


def results(twin: Twin) -> list[str]:
    session: RecordingSession = twin.session  # type: ignore[assignment]
    return [k.rsplit("/", 1)[-1] for k, _ in session.puts if "/result/" in k]


def test_a_misplaced_identity_is_simulated_warned_once_and_counted(
    twin: Twin, log: Callable[[], list[str]]
) -> None:
    serve(twin, passage("p1", vehicle_id=WHEEL["vehicle_id"], wheelset=2))
    serve(twin, passage("p2", vehicle_id=WHEEL["vehicle_id"], wheelset=2))
    assert results(twin) == ["p1", "p2"]  # accepted: unknown fields are ignored, as always
    (message,) = log()
    assert "passage p1" in message and "vehicle_id, wheelset" in message
    assert 'inside "wheel"' in message  # it says where the identity goes
    health = twin.health()
    assert (health.passages_done, health.passages_without_wheel) == (2, 2)


def test_once_per_field_and_sender(twin: Twin, log: Callable[[], list[str]]) -> None:
    serve(twin, passage("p1", vehicle_id="V1"), sender="a")
    serve(twin, passage("p2", vehicle_id="V1"), sender="a")  # said before to a
    serve(twin, passage("p3", vehicle_id="V1", colour="red"), sender="a")  # a new field
    serve(twin, passage("p4", vehicle_id="V1"), sender="b")  # another sender
    said = log()
    assert len(said) == 3, said
    assert "passage p1 from a: unknown fields ignored: vehicle_id" in said[0]
    assert "passage p3 from a: unknown fields ignored: colour;" in said[1]
    assert "passage p4 from b: unknown fields ignored: vehicle_id" in said[2]


def test_a_wheel_in_its_place_is_neither_warned_nor_counted(
    twin: Twin, log: Callable[[], list[str]]
) -> None:
    serve(twin, passage("p1", wheel=WHEEL, direction="end2_leading"))
    serve(twin, passage("p2"))  # no wheel at all (a site without a tag reader): counted only
    assert results(twin) == ["p1", "p2"]
    assert log() == []
    assert twin.health().passages_without_wheel == 1


def test_invalid_and_duplicate_passages_are_not_counted(twin: Twin) -> None:
    serve(twin, passage("p1", speed=-1.0, vehicle_id="V1"))  # refused: an error, no count
    serve(twin, passage("p2"))
    serve(twin, passage("p2"))  # the same id again: refused
    assert twin.health().passages_without_wheel == 1


def test_unknown_fields_inside_the_wheel_are_named_with_their_path() -> None:
    data = {**GOOD_PASSAGE, "wheel": {**WHEEL, "wheel_set": 2}, "Speed": 1.0}
    assert unknown_fields(data) == ["wheel.wheel_set", "Speed"]
    assert unknown_fields(GOOD_PASSAGE) == []


def test_the_health_carries_the_count_and_reads_without_it() -> None:
    health = Health(
        site_id="s",
        started_at=1.0,
        uptime=0.0,
        passages_received=3,
        passages_done=3,
        passages_without_wheel=2,
        errors=0,
        queue_depth=0,
        queue_capacity=1,
    )
    doc = json.loads(health.model_dump_json())
    assert doc["passages_without_wheel"] == 2
    del doc["passages_without_wheel"]  # a twin of before the field
    assert Health.model_validate(doc).passages_without_wheel == 0


def test_the_sender_is_the_publishing_session_when_it_says() -> None:
    said = SimpleNamespace(source_info=SimpleNamespace(source_id=SimpleNamespace(zid="42ab")))
    assert sender_of(said) == "42ab"  # type: ignore[arg-type]
    assert sender_of(SimpleNamespace(source_info=None)) is None  # type: ignore[arg-type]
