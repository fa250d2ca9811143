"""End to end: the twin in its own process, a publisher here, over loopback Zenoh.

One module-scoped run feeds good and bad passages to a fresh service, stops it
with SIGTERM and keeps its MCAP log and .rrd; a second fresh service is fed a
replay of that log (by ``service.cli.replay`` in a third process) and must
publish the very same numbers.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh

from schemas.messages import (
    Health,
    PassageResult,
    PassageSeries,
    RailState,
    TrainFile,
    WheelPassage,
    encoding_schema,
)
from schemas.scenario import FlatOutline
from service.cli.service_process import ServiceProcess
from service.clients.feeder import Collector, declare_passage_publisher, query_health, wait_matching
from service.recording.mcap_log import LoggedMessage, decode, model_for_schema, read_log
from service.recording.rerun_recording import entities
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config, free_tcp_endpoint
from tests.test_service_rerun import of_passage, passage_indexes, rrd_columns, rrd_entities

ROOT = Path(__file__).resolve().parents[1]
SITE_ID = "e2e"
KEYS = SiteKeys(SITE_ID)
SITE_TOML = """
site_id = "e2e"
length = 3.0
output_sample_rate = 5000.0
contact = "hertz_plastic"
rtol = 1e-8
[rail]
kind = "cosine"
amplitude = 2.0e-6
wavelength = 0.06
[material]
youngs_modulus = 2.14e11
poisson_ratio = 0.3
yield_stress = 6.0e8
"""
TIMEOUT = 60.0


def passages() -> list[WheelPassage]:
    """Three round wheels of the sample train, then one with a 50 mm flat (it dents the rail).

    The flat hits the rail 0.8 m into the site.
    """
    train = TrainFile.model_validate_json(
        (ROOT / "recordings/samples/train_160kmh.json").read_bytes()
    )
    round_ = train.wheels[0].passage
    flat = round_.model_copy(
        update={
            "passage_id": "flat",
            "outline": FlatOutline(kind="flat", length=0.05),
            "phase": (-0.8 / round_.radius) % math.tau,
        }
    )
    return [
        round_.model_copy(update={"passage_id": "w0"}),
        round_.model_copy(update={"passage_id": "w1", "load": 56000.0}),
        round_.model_copy(update={"passage_id": "w2", "radius": 0.445}),
        flat,
    ]


def bad_inputs() -> list[tuple[bytes, str, str | None]]:
    """(payload, error kind, field named)."""
    good = json.loads(passages()[0].model_dump_json())
    return [
        (b'{"passage_id": "broken", ', "invalid_json", None),
        (
            json.dumps({**good, "passage_id": "b1", "speed": "fast"}).encode(),
            "invalid_passage",
            "speed",
        ),
        (
            json.dumps({**good, "passage_id": "b2", "mass": math.nan}).encode(),
            "invalid_passage",
            "mass",
        ),
        (
            json.dumps({**good, "passage_id": "b3", "mass": -600.0}).encode(),
            "invalid_passage",
            "mass",
        ),
        # the first passage again: a passage id is never applied twice
        (passages()[0].model_dump_json().encode(), "invalid_passage", "passage_id"),
    ]


@dataclass
class Run:
    collector: Collector
    health: list[Health]
    rail: RailState | None
    service: ServiceProcess
    logged: list[LoggedMessage]


def session_to(endpoint: str) -> zenoh.Session:
    return zenoh.open(build_config(connect=[endpoint]))


def feed(
    endpoint: str, sends: list[bytes | WheelPassage]
) -> tuple[Collector, list[Health], RailState | None]:
    """Publish ``sends`` in order (a small gap each), wait for every answer."""
    expected_results = sum(isinstance(s, WheelPassage) for s in sends)
    expected_errors = len(sends) - expected_results
    with session_to(endpoint) as session:
        collector = Collector(KEYS)
        sub = session.declare_subscriber(KEYS.all_outputs, collector)
        pub = declare_passage_publisher(session, KEYS)
        assert wait_matching(pub, 20.0), "the service's subscriber never matched"
        for s in sends:
            if isinstance(s, WheelPassage):
                collector.expect(s.passage_id, time.monotonic())
                pub.put(s.model_dump_json())
            else:
                pub.put(s)
            time.sleep(0.02)
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            done = sum(o.result is not None for o in collector.outcomes.values())
            if done >= expected_results and len(collector.errors) >= expected_errors:
                break
            time.sleep(0.05)
        health = query_health(session)
        alive = [r.ok is not None for r in session.liveliness().get(KEYS.alive, timeout=5.0)]
        assert alive == [True], "the twin's liveliness token is missing"
        rail = None
        for reply in session.get(KEYS.rail, timeout=5.0):
            assert reply.ok is not None
            assert str(reply.ok.encoding) == f"application/json;{encoding_schema(RailState)}"
            rail = RailState.model_validate_json(reply.ok.payload.to_bytes())
        sub.undeclare()
        pub.undeclare()
    return collector, health, rail


def serve(tmp: Path, name: str) -> ServiceProcess:
    site = tmp / "site.toml"
    site.write_text(SITE_TOML)
    return ServiceProcess(site, listen=free_tcp_endpoint(), recordings=tmp / name)


def endpoint_of(svc: ServiceProcess) -> str:
    return svc.args[svc.args.index("--listen") + 1]


@pytest.fixture(scope="module")
def first_run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    tmp = tmp_path_factory.mktemp("e2e")
    ps = passages()
    sends: list[bytes | WheelPassage] = [ps[0], *(b for b, _, _ in bad_inputs()), *ps[1:]]
    svc = serve(tmp, "first")
    with svc:
        collector, health, rail = feed(endpoint_of(svc), sends)
    assert svc.returncode == 0, svc.output
    return Run(collector, health, rail, svc, list(read_log(svc.mcap_files)))


@pytest.fixture(scope="module")
def replayed_run(first_run: Run, tmp_path_factory: pytest.TempPathFactory) -> Run:
    tmp = tmp_path_factory.mktemp("replay")
    svc = serve(tmp, "second")
    with svc, session_to(endpoint_of(svc)) as session:
        collector = Collector(KEYS)
        sub = session.declare_subscriber(KEYS.all_outputs, collector)
        replay = subprocess.run(
            [
                sys.executable,
                "-m",
                "service.cli.replay",
                *map(str, first_run.service.mcap_files),
                "--connect",
                endpoint_of(svc),
                "--rate",
                "4",
                "--include-rejected",
            ],
            capture_output=True,
            text=True,
            timeout=TIMEOUT,
            cwd=ROOT,
        )
        assert replay.returncode == 0, replay.stderr
        deadline = time.monotonic() + TIMEOUT
        while time.monotonic() < deadline:
            if (
                sum(o.result is not None for o in collector.outcomes.values()) >= 4
                and len(collector.errors) >= 4
            ):
                break
            time.sleep(0.05)
        sub.undeclare()
    assert svc.returncode == 0, svc.output
    return Run(collector, [], None, svc, list(read_log(svc.mcap_files)))


def test_good_passages_are_served(first_run: Run) -> None:
    outcomes = first_run.collector.outcomes
    for p in passages():
        o = outcomes[p.passage_id]
        assert o.result is not None, f"no result for {p.passage_id}"
        assert o.force_at is not None
        r = o.result
        n = len(r.x)
        assert n == math.floor(3.0 / p.speed * 5000.0 * (1 + 1e-12)) + 1
        assert r.x[0] == 0.0 and 3.0 - p.speed / 5000.0 < r.x[-1] <= 3.0
        assert all(math.isfinite(f) for f in r.force)
        assert 0.5 * p.load < r.summary.peak_force
    flat = outcomes["flat"].result
    w0 = outcomes["w0"].result
    assert flat is not None and w0 is not None
    assert flat.summary.peak_force > 1.2 * w0.summary.peak_force, "the flat's impact is missing"
    assert flat.summary.contact_losses > 0
    assert flat.summary.max_dent > 0.0


def test_bad_input_gets_an_error_naming_the_field(first_run: Run) -> None:
    errors = first_run.collector.errors
    assert [(e.kind, e.field) for e in errors] == [(k, f) for _, k, f in bad_inputs()]
    for e in errors:
        if e.field:
            assert e.field in e.message
    # the good passages after the bad ones were still served
    assert first_run.collector.outcomes["flat"].result is not None


def test_health_and_rail_queryables(first_run: Run) -> None:
    (h,) = [h for h in first_run.health if h.site_id == SITE_ID]
    assert h.passages_done == 4
    assert h.errors == len(bad_inputs())
    assert h.passages_received == 4 + len(bad_inputs())
    assert h.last_error is not None and h.last_error.field == bad_inputs()[-1][2]
    rail = first_run.rail
    assert rail is not None
    flat = first_run.collector.outcomes["flat"].result
    assert flat is not None
    assert rail.passages_done == 4
    assert rail.revision == 1
    assert rail.max_dent == pytest.approx(flat.summary.max_dent, rel=1e-3)
    assert len(rail.x) == len(rail.y) == len(rail.dent)


def test_mcap_holds_every_message_and_validates(first_run: Run) -> None:
    logged = first_run.logged
    topics = Counter(m.topic for m in logged)
    p = KEYS.prefix
    assert topics == {
        # the duplicate is logged as a valid passage (it is one), then refused
        f"{p}/passage": 5,
        f"{p}/passage/rejected": 4,
        f"{p}/force": 4,
        f"{p}/indentation": 4,
        f"{p}/result": 4,
        f"{p}/error": 5,
        f"{p}/log": 5,  # each error again as a foxglove.Log, for Foxglove's Log panel
        # every sample of every result, one message each (Foxglove plots them against time)
        f"{p}/samples": sum(
            len(o.result.x) for o in first_run.collector.outcomes.values() if o.result is not None
        ),
    }
    for m in logged:
        decode(m)  # validates against the channel's schema
        assert model_for_schema(m.schema_name).__name__ in m.schema_name
    force = [decode(m) for m in logged if m.topic == f"{p}/force"]
    assert all(isinstance(f, PassageSeries) and f.quantity == "force" for f in force)
    results = {r.passage_id: r for r in (decode(m) for m in logged if m.topic == f"{p}/result")}
    for pid, o in first_run.collector.outcomes.items():
        assert o.result == results[pid]  # what went over Zenoh is what was logged
    for pid, r in results.items():  # each sample at its own time: the passage's + x/speed
        got = [
            (m.log_time_ns, decode(m))
            for m in logged
            if m.topic == f"{p}/samples" and decode(m).passage_id == pid
        ]
        np.testing.assert_allclose([s.force for _, s in got], r.force, rtol=1e-6, atol=0)
        assert [t for t, _ in got] == [round((r.timestamp + x / r.speed) * 1e9) for x in r.x]
    logged_inputs = [m for m in logged if m.topic.startswith(f"{p}/passage")]
    assert logged_inputs == sorted(logged_inputs, key=lambda m: m.log_time_ns)


def test_rrd_has_every_passage(first_run: Run) -> None:
    rrd = first_run.service.rrd_file
    assert rrd is not None and rrd.is_file()
    cols = rrd_columns(rrd)
    e = entities(SITE_ID)
    index = passage_indexes(rrd, SITE_ID)
    assert sorted(index.values()) == list(range(len(index)))
    for pid, o in first_run.collector.outcomes.items():
        r = o.result
        assert r is not None
        for role, values in (
            ("force", np.asarray(r.force)),  # SI: N and m
            ("indentation", np.asarray(r.indentation)),
            ("y_c", np.asarray(r.y_c)),
            ("y_ck", np.asarray(r.y_ck)),
        ):
            np.testing.assert_array_equal(of_passage(cols[e[role]], index[pid])["values"], values)
    assert e["profile"] in cols
    assert rrd_entities(rrd) <= set(e.values())  # a fixed set, whatever the passages


def comparable(m: LoggedMessage) -> Any:
    """A logged message without what legitimately differs between runs (clocks)."""
    data = json.loads(m.data)
    for key in ("wall_time", "received_at"):
        data.pop(key, None)
    if m.topic.endswith("/log"):  # a foxglove.Log is stamped when it is logged
        data.pop("timestamp", None)
    return m.topic, data


def test_replay_reproduces_the_outputs_exactly(first_run: Run, replayed_run: Run) -> None:
    first = [comparable(m) for m in first_run.logged]
    second = [comparable(m) for m in replayed_run.logged]
    # inputs: the same bytes, in the same order
    assert [m.data for m in first_run.logged if "/passage" in m.topic] == [
        m.data for m in replayed_run.logged if "/passage" in m.topic
    ]
    # outputs: the same numbers
    assert Counter(t for t, _ in first) == Counter(t for t, _ in second)
    key = lambda item: (item[0], json.dumps(item[1], sort_keys=True))  # noqa: E731
    assert sorted(first, key=key) == sorted(second, key=key)
    for pid, o in first_run.collector.outcomes.items():
        again = replayed_run.collector.outcomes[pid].result
        assert isinstance(again, PassageResult) and o.result is not None
        assert again.force == o.result.force
        assert again.summary == o.result.summary


def test_each_mcap_file_says_which_site_file_and_version_wrote_it(first_run: Run) -> None:
    from mcap.reader import make_reader

    for path in first_run.service.mcap_files:
        with path.open("rb") as f:
            records = [m for m in make_reader(f).iter_metadata() if m.name == "railtwin"]
        assert len(records) == 1
        meta = records[0].metadata
        assert json.loads(meta["site"])["site_id"] == SITE_ID
        assert meta["railtwin_version"] and meta["site_file"].endswith("site.toml")


def test_inputs_and_results_are_logged_with_the_passage_time_as_publish_time(
    first_run: Run,
) -> None:
    from mcap.reader import make_reader

    p = KEYS.prefix
    stamps = {}
    for path in first_run.service.mcap_files:
        with path.open("rb") as f:
            for _, channel, m in make_reader(f).iter_messages():
                if channel.topic in (f"{p}/passage", f"{p}/result"):
                    pid = json.loads(m.data)["passage_id"]
                    stamps.setdefault(pid, set()).add((channel.topic, m.publish_time))
    for pid, o in first_run.collector.outcomes.items():
        assert o.result is not None
        at = round(o.result.timestamp * 1e9)
        assert (f"{p}/result", at) in stamps[pid]
        assert (f"{p}/passage", at) in stamps[pid]
