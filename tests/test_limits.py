"""Every limit of the twin at its edge: just inside is served, just outside is refused
with the field that broke it (issue 8, item 1).

The schema limits are checked on the models; the service's own ones on a Twin with the
closed-form stub physics over a loopback Zenoh session in this process (fast).
"""

from __future__ import annotations

import json
import math
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
import zenoh
from pydantic import ValidationError

from schemas.diagnosis import MAX_MEASURED_SAMPLES, MeasuredPassage
from schemas.messages import Health, PassageResult, ServiceError, WheelPassage
from schemas.scenario import MAX_OUTLINE_POINTS
from schemas.site import MAX_RAIL_POINTS, SiteConfig
from service.physics.local import LocalPhysics
from service.physics.stub import StubPhysics
from service.twin.twin import Twin
from service.wire import limits
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config, free_tcp_endpoint

SITE = SiteConfig.model_validate(
    {
        "site_id": "lim",
        "length": 6.0,
        "output_sample_rate": 10_000.0,
        "contact": "hertz",
        "rail": {"kind": "flat"},
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
    }
)
KEYS = SiteKeys(SITE.site_id)
BASE: dict[str, Any] = {
    "passage_id": "p0",
    "train_id": "t1",
    "axle_index": 0,
    "side": "right",
    "timestamp": 1.7e9,
    "speed": 40.0,
    "load": 60e3,
    "mass": 500.0,
    "radius": 0.46,
}


def first_field(exc: ValidationError) -> str:
    from schemas.errors import format_path

    e = exc.errors()[0]
    return format_path(tuple(e["loc"]), None, e.get("ctx"))


def sampled(n: int) -> dict[str, Any]:
    theta = [2 * math.pi * i / n for i in range(n)]
    return {"kind": "sampled", "theta": theta, "radius": [0.46] * n}


# --- schema limits -----------------------------------------------------------------------


def test_outline_points_edge() -> None:
    WheelPassage.model_validate({**BASE, "outline": sampled(MAX_OUTLINE_POINTS)})
    with pytest.raises(ValidationError) as exc:
        WheelPassage.model_validate({**BASE, "outline": sampled(MAX_OUTLINE_POINTS + 1)})
    assert first_field(exc.value) == "outline.theta"


def test_flat_must_fit_the_passage_wheel() -> None:
    r = BASE["radius"]
    WheelPassage.model_validate({**BASE, "outline": {"kind": "flat", "length": 2 * r * 0.999}})
    with pytest.raises(ValidationError) as exc:
        WheelPassage.model_validate({**BASE, "outline": {"kind": "flat", "length": 2 * r}})
    assert first_field(exc.value) == "outline.length"
    with pytest.raises(ValidationError) as exc:
        WheelPassage.model_validate(
            {**BASE, "outline": {"kind": "rounded_flat", "length": 0.05, "depth": r}}
        )
    assert first_field(exc.value) == "outline.depth"
    bad = sampled(64)
    bad["radius"][5] = 0.6
    with pytest.raises(ValidationError) as exc:
        WheelPassage.model_validate({**BASE, "outline": bad})
    assert first_field(exc.value) == "outline.radius[5]"


def test_id_length_edge() -> None:
    WheelPassage.model_validate({**BASE, "passage_id": "a" * limits.MAX_ID_LENGTH})
    for name in ("passage_id", "train_id"):
        with pytest.raises(ValidationError) as exc:
            WheelPassage.model_validate({**BASE, name: "a" * (limits.MAX_ID_LENGTH + 1)})
        assert first_field(exc.value) == name


def test_rail_points_edge() -> None:
    raw = json.loads(SITE.model_dump_json())

    def rail(n: int) -> dict[str, Any]:
        x = [6.2 * i / (n - 1) - 0.1 for i in range(n)]
        return {"kind": "sampled", "x": x, "y": [0.0] * n}

    SiteConfig.model_validate({**raw, "rail": rail(MAX_RAIL_POINTS)})
    with pytest.raises(ValidationError) as exc:
        SiteConfig.model_validate({**raw, "rail": rail(MAX_RAIL_POINTS + 1)})
    assert first_field(exc.value) == "rail.x"
    # a file rail is resolved after validation: serve checks it again
    big = SITE.model_copy(update={"rail": SITE.rail})
    assert limits.site_problem(big) is None


def test_measured_samples_edge() -> None:
    force = [6e4 + (i % 7) for i in range(MAX_MEASURED_SAMPLES)]
    MeasuredPassage(passage_id="m", sample_rate=1e4, t_start=0.0, force=force)
    with pytest.raises(ValidationError) as exc:
        MeasuredPassage(passage_id="m", sample_rate=1e4, t_start=0.0, force=[*force, 6e4])
    assert first_field(exc.value) == "force"
    # the payload cap leaves room for the largest measurement
    worst = len(
        json.dumps({"passage_id": "m" * 96, "sample_rate": 1e4, "t_start": 0.0})
    ) + MAX_MEASURED_SAMPLES * len("-1.2345678901234567e-05, ")
    assert worst < limits.MAX_MEASURED_PAYLOAD_BYTES


def test_payload_caps() -> None:
    for measured in (False, True):
        cap = limits.MAX_MEASURED_PAYLOAD_BYTES if measured else limits.MAX_PASSAGE_PAYLOAD_BYTES
        assert limits.payload_problem(cap, measured) is None
        assert limits.payload_problem(cap + 1, measured) is not None


def test_nesting_edge() -> None:
    assert not limits.nesting_too_deep(b"[" * limits.MAX_NESTING + b"]" * limits.MAX_NESTING)
    assert limits.nesting_too_deep(b"[" * (limits.MAX_NESTING + 1))
    assert not limits.nesting_too_deep(b'{"a": "' + b"[" * 100 + b'"}')
    assert not limits.nesting_too_deep(b'{"a": "\\"[[[[[[[[[[[[["}')
    # a truncated text with many shallow brackets is left to the parser
    cut = b'{"a":[1],"b":[2],"c":[3],"d":[4],"e":[5],"f":[6],"g":[7],"h":[8],"i":[9'
    assert limits.structure_problem(cut) is None
    deep = b"[" * 9 + b"]" * 9
    assert limits.structure_problem(deep) == ("json_too_deep", "JSON nested deeper than 8 levels")
    # a payload larger than any passage (a measurement) must have one object and one array
    large = b'{"force": [' + b"1, " * (limits.MAX_PASSAGE_PAYLOAD_BYTES // 3) + b"1]}"
    assert limits.structure_problem(large) is None
    problem = limits.structure_problem(large[:-2] + b", [], [], [], [], [], [], [], []]}")
    assert problem is not None and problem[0] == "too_many_brackets"


def test_lowest_speed_edge() -> None:
    v = limits.lowest_speed(SITE.length, SITE.output_sample_rate)
    assert v == pytest.approx(6.0 * 10_000.0 / limits.MAX_PASSAGE_SAMPLES) == 0.4
    ok = WheelPassage.model_validate({**BASE, "speed": v * (1 + 1e-9)})
    assert limits.passage_problem(SITE, ok) is None
    assert limits.passage_samples(6.0, 1e4, ok.speed) <= limits.MAX_PASSAGE_SAMPLES
    for speed in (v, v * (1 - 1e-9), 2.2250738585072014e-308):  # the last: count overflows
        slow = WheelPassage.model_validate({**BASE, "speed": speed})
        problem = limits.passage_problem(SITE, slow)
        assert problem is not None and problem[0] == "speed"
        assert f"above {v:.6g} m/s" in problem[1]
    # the output bytes cap is not tighter than the sample cap (both hold at the edge)
    assert (
        limits.MAX_PASSAGE_SAMPLES * limits.OUTPUT_BYTES_PER_SAMPLE
        <= limits.MAX_PASSAGE_OUTPUT_BYTES
    )


def test_crib_channels_raise_the_lowest_speed_by_the_bytes_they_publish() -> None:
    """Each crib channel is one more float a sample in the published result: with 32 the
    output bytes cap binds before the sample cap, and the error says the floor."""
    cribs = [{"id": f"c{i}", "x_a": 0.4 + 0.6 * i, "x_b": 0.8 + 0.6 * i} for i in range(32)]
    site = SiteConfig.model_validate(
        SITE.model_dump()
        | {
            "length": 20.0,
            "foundation": {
                "kind": "slab",
                "sleeper_spacing": 0.6,
                "first_sleeper": 0.3,
                "pad": {"stiffness": 2e8},
            },
            "detector": {"cribs": cribs},
        }
    )
    assert limits.site_cribs(site) == 32
    v = limits.lowest_speed(site.length, site.output_sample_rate, 32)
    assert v > limits.lowest_speed(site.length, site.output_sample_rate)
    n = limits.max_samples(32)
    per = limits.bytes_per_sample(32)
    assert n * per <= limits.MAX_PASSAGE_OUTPUT_BYTES < (n + 1) * per
    ok = WheelPassage.model_validate({**BASE, "speed": v * (1 + 1e-9)})
    assert limits.passage_problem(site, ok) is None
    slow = WheelPassage.model_validate({**BASE, "speed": v * (1 - 1e-6)})
    problem = limits.passage_problem(site, slow)
    assert problem is not None and problem[0] == "speed"
    assert "32 crib channels" in problem[1] and f"above {v:.6g} m/s" in problem[1]


# --- the service's limits, on a twin with the stub physics ---------------------------------


PROBE_ID = "rig-probe"
"""Passage id of the rig's readiness probes (answered with an error that ``Out`` sets aside)."""


@dataclass
class Out:
    results: dict[str, PassageResult] = field(default_factory=dict)
    errors: list[tuple[ServiceError, int]] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    probed: threading.Event = field(default_factory=threading.Event)

    def __call__(self, sample: zenoh.Sample) -> None:
        kind = KEYS.kind_of(str(sample.key_expr))
        data = sample.payload.to_bytes()
        with self.lock:
            if kind == "result":
                r = PassageResult.model_validate_json(data)
                self.results[r.passage_id] = r
            elif kind == "error":
                err = ServiceError.model_validate_json(data)
                if err.passage_id == PROBE_ID:
                    self.probed.set()
                else:
                    self.errors.append((err, len(data)))

    def wait(self, n_results: int, n_errors: int, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if len(self.results) >= n_results and len(self.errors) >= n_errors:
                    return
            time.sleep(0.01)
        raise AssertionError(f"timed out: {len(self.results)} results, {self.errors}")


@dataclass
class Rig:
    twin: Twin
    client: zenoh.Session
    passages: zenoh.Publisher
    measured: zenoh.Publisher
    out: Out


class SlowStub(StubPhysics):
    delay = 0.0

    def simulate(self, passage: WheelPassage) -> PassageResult:
        time.sleep(self.delay)
        return super().simulate(passage)


@pytest.fixture
def rig(request: pytest.FixtureRequest) -> Iterator[Rig]:
    capacity = getattr(request, "param", 1000)
    endpoint = free_tcp_endpoint()
    with (
        zenoh.open(build_config(listen=[endpoint])) as server,
        zenoh.open(build_config(connect=[endpoint])) as client,
    ):
        twin = Twin(SITE, server, LocalPhysics(SlowStub(SITE)), queue_capacity=capacity)
        twin.start()
        out = Out()
        sub = client.declare_subscriber(KEYS.all_outputs, out)
        pub = client.declare_publisher(
            KEYS.passage,
            encoding=json_encoding(WheelPassage),
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        mpub = client.declare_publisher(
            KEYS.measured,
            encoding=json_encoding(MeasuredPassage),
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        deadline = time.monotonic() + 20
        while not (pub.matching_status.matching and mpub.matching_status.matching):
            assert time.monotonic() < deadline
            time.sleep(0.02)
        # The publisher matching says the twin hears us, not that the twin's answers reach
        # our subscriber yet (declarations travel each way on their own): probe until one
        # answer has come back.
        while not out.probed.wait(0.2):
            assert time.monotonic() < deadline, "the twin's answers never reached the rig"
            pub.put(json.dumps({"passage_id": PROBE_ID}))
        try:
            yield Rig(twin, client, pub, mpub, out)
        finally:
            sub.undeclare()
            pub.undeclare()
            mpub.undeclare()
            twin.stop()


def test_service_speed_edge(rig: Rig) -> None:
    v = limits.lowest_speed(SITE.length, SITE.output_sample_rate)
    rig.passages.put(json.dumps({**BASE, "passage_id": "slow-ok", "speed": v * (1 + 1e-9)}))
    rig.passages.put(json.dumps({**BASE, "passage_id": "too-slow", "speed": v}))
    rig.passages.put(json.dumps({**BASE, "passage_id": "crawl", "speed": 0.001}))
    rig.out.wait(1, 2, timeout=60)
    assert len(rig.out.results["slow-ok"].x) <= limits.MAX_PASSAGE_SAMPLES
    for (err, _), pid in zip(rig.out.errors, ("too-slow", "crawl"), strict=True):
        assert (err.kind, err.field, err.passage_id) == ("invalid_passage", "speed", pid)
        assert "speed must be above 0.4 m/s" in err.message


def test_service_payload_cap_and_no_echo(rig: Rig) -> None:
    body = json.dumps({**BASE, "passage_id": "pad"})
    pad = limits.MAX_PASSAGE_PAYLOAD_BYTES - len(body)
    at_cap = body[:-1] + " " * pad + "}"
    assert len(at_cap) == limits.MAX_PASSAGE_PAYLOAD_BYTES
    rig.passages.put(at_cap)
    rig.passages.put(body[:-1] + " " * (pad + 1) + "}")
    huge = json.dumps({**BASE, "passage_id": "x" * 50_000_000})
    rig.passages.put(huge)
    rig.out.wait(1, 2, timeout=60)
    assert "pad" in rig.out.results
    (over, _), (big, big_len) = rig.out.errors
    assert over.kind == "invalid_passage" and over.problems[0].type == "payload_too_large"
    assert over.passage_id == "pad"  # readable from its start
    assert big.passage_id is None and big_len < 2000, big_len  # not echoed
    assert str(limits.MAX_PASSAGE_PAYLOAD_BYTES) in big.message


def test_service_nesting_and_ids(rig: Rig) -> None:
    n = limits.MAX_NESTING
    deep = json.dumps({**BASE, "passage_id": "deep", "outline": "X"}).replace(
        '"X"', "[" * (n + 1) + "]" * (n + 1)
    )
    at_limit = json.dumps({**BASE, "passage_id": "limit", "outline": "X"}).replace(
        '"X"', "[" * (n - 1) + "]" * (n - 1)
    )
    rig.passages.put(deep)
    rig.passages.put(at_limit)
    rig.passages.put(json.dumps({**BASE, "passage_id": "i" * limits.MAX_ID_LENGTH}))
    rig.passages.put(json.dumps({**BASE, "passage_id": "i" * (limits.MAX_ID_LENGTH + 1)}))
    rig.passages.put(
        json.dumps({**BASE, "passage_id": "geo", "outline": {"kind": "flat", "length": 1.0}})
    )
    rig.out.wait(1, 4)
    errs = [e for e, _ in rig.out.errors]
    assert (errs[0].kind, errs[0].passage_id) == ("invalid_json", "deep")
    assert errs[0].problems[0].type == "json_too_deep"
    assert errs[1].kind == "invalid_passage" and errs[1].field == "outline"  # pydantic saw it
    assert "i" * limits.MAX_ID_LENGTH in rig.out.results
    assert (errs[2].field, errs[2].passage_id) == ("passage_id", None)
    assert (errs[3].kind, errs[3].field) == ("invalid_passage", "outline.length")


def test_measured_nesting_and_unknown_key_not_echoed(rig: Rig) -> None:
    deep = b'{"passage_id": "m", "force": ' + b"[" * 20 + b"]" * 20 + b"}"
    rig.measured.put(deep)
    rig.measured.put(json.dumps({"passage_id": "m", "k" * 100_000: 1}))
    rig.out.wait(0, 2)
    (e1, _), (e2, n2) = rig.out.errors
    assert e1.kind == "invalid_json"
    assert e2.kind == "invalid_measurement" and n2 < 20_000


@pytest.mark.parametrize("rig", [2], indirect=True)
def test_overloaded_carries_the_passage_id_and_site_health(rig: Rig) -> None:
    port = rig.twin.physics
    assert isinstance(port, LocalPhysics)
    physics = port.model
    assert isinstance(physics, SlowStub)
    physics.delay = 0.3
    for i in range(6):
        rig.passages.put(json.dumps({**BASE, "passage_id": f"o{i}"}))
    rig.out.wait(0, 1)
    err, _ = rig.out.errors[0]
    assert err.kind == "overloaded" and err.passage_id is not None
    assert err.passage_id.startswith("o")
    replies = list(rig.client.get(KEYS.health, timeout=5.0))
    healths = [Health.model_validate_json(r.ok.payload.to_bytes()) for r in replies if r.ok]
    assert [h.site_id for h in healths] == ["lim"]
    physics.delay = 0.0
