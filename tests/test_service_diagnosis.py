"""End to end: wheel-flat diagnosis by the twin in its own process, over loopback Zenoh.

One module-scoped run of a fresh service at the example site (with a 1 s pairing
timeout) is fed passages and measured passages (``sim_core.diagnosis.synthetic``: a
50 mm fresh flat at 30 m/s, with noise and rail roughness the site does not know), in
both orders of arrival, plus bad, duplicate and unpaired measurements, and a plain
passage afterwards. It is then stopped with SIGTERM and its MCAP log and .rrd read back.
"""

from __future__ import annotations

import json
import math
import re
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
import zenoh

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import PassageResult, ServiceError, WheelPassage, encoding_schema
from service.cli.service_process import ServiceProcess
from service.clients.feeder import declare_passage_publisher, wait_matching
from service.physics.diagnosis import Diagnoser
from service.physics.site_physics import SitePhysics
from service.recording import foxglove
from service.recording.mcap_log import LoggedMessage, decode, read_log
from service.recording.rerun_recording import entities
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.site import load_site
from service.wire.zenoh_session import build_config, free_tcp_endpoint
from sim_core.diagnosis.forward import Flat
from sim_core.diagnosis.synthetic import Perturbations, synthetic_measurement
from tests.test_service_rerun import of_passage, passage_indexes, rrd_columns, rrd_texts

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE_SITE = ROOT / "examples/site_compliant.toml"
PAIRING_TIMEOUT = 1.0
TIMEOUT = 30.0
SPEED = 30.0
RADIUS = 0.46
FLAT_LENGTH = 0.05


def site_toml() -> str:
    """examples/site_compliant.toml with ``[diagnosis] pairing_timeout = 1.0`` (its table kept if any)."""
    lines = [
        ln
        for ln in EXAMPLE_SITE.read_text().splitlines()
        if not re.match(r"\s*pairing_timeout\s*=", ln)
    ]
    setting = f"pairing_timeout = {PAIRING_TIMEOUT}"
    for i, ln in enumerate(lines):
        if re.match(r"\s*\[diagnosis\]", ln):
            lines.insert(i + 1, setting)
            break
    else:
        lines += ["", "[diagnosis]", setting]
    return "\n".join(lines) + "\n"


def wheel(pid: str) -> WheelPassage:
    return WheelPassage(
        passage_id=pid,
        train_id="t1",
        axle_index=0,
        side="right",
        timestamp=1.7e9,
        speed=SPEED,
        load=60e3,
        mass=500.0,
        radius=RADIUS,
    )


@dataclass
class Outputs:
    """Everything the service publishes for the site, as it arrives."""

    keys: SiteKeys
    diagnoses: dict[str, tuple[float, Diagnosis]] = field(default_factory=dict)
    results: dict[str, float] = field(default_factory=dict)
    errors: list[ServiceError] = field(default_factory=list)
    encodings: dict[str, str] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def __call__(self, sample: zenoh.Sample) -> None:
        now = time.monotonic()
        key = str(sample.key_expr)
        kind = self.keys.kind_of(key)
        data = sample.payload.to_bytes()
        with self.lock:
            self.encodings[kind or key] = str(sample.encoding)
            if kind == "diagnosis":
                self.diagnoses[key.rsplit("/", 1)[-1]] = (now, Diagnosis.model_validate_json(data))
            elif kind == "result":
                self.results[PassageResult.model_validate_json(data).passage_id] = now
            elif kind == "error":
                self.errors.append(ServiceError.model_validate_json(data))

    def wait(self, done: object, timeout: float = TIMEOUT) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.lock:
                if callable(done) and done():
                    return True
            time.sleep(0.01)
        return False

    def error_for(self, pid: str, kind: str) -> ServiceError | None:
        return next((e for e in self.errors if e.passage_id == pid and e.kind == kind), None)


@dataclass
class Run:
    out: Outputs
    sent: dict[str, float]
    service: ServiceProcess
    logged: list[LoggedMessage]


def measurement(pid: str) -> MeasuredPassage:
    """What the example site would measure of ``wheel(pid)`` with a 50 mm fresh flat."""
    site = load_site(EXAMPLE_SITE)
    diagnoser = Diagnoser(site, SitePhysics(site))
    rate = site.diagnosis.sample_rate or 10e3
    m = synthetic_measurement(
        diagnoser.wheel(wheel(pid)),
        SPEED,
        Flat.ideal(RADIUS, FLAT_LENGTH, phase=1.0),
        diagnoser.physics.base_rail,
        site.length,
        rate,
        diagnoser.sensor,
        Perturbations(seed=1),
    )
    return MeasuredPassage(
        passage_id=pid, sample_rate=m.sample_rate, t_start=m.t_start, force=m.force.tolist()
    )


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    tmp = tmp_path_factory.mktemp("diag")
    site_file = tmp / "site.toml"
    site_file.write_text(site_toml())
    site_id = load_site(site_file).site_id
    keys = SiteKeys(site_id)
    good = measurement("m0")
    template = json.loads(good.model_dump_json())
    endpoint = free_tcp_endpoint()
    svc = ServiceProcess(site_file, listen=endpoint, recordings=tmp / "rec")
    out = Outputs(keys)
    sent: dict[str, float] = {}
    with svc, zenoh.open(build_config(connect=[endpoint])) as session:
        sub = session.declare_subscriber(keys.all_outputs, out)
        passages = declare_passage_publisher(session, keys)
        measured = session.declare_publisher(
            keys.measured,
            encoding=json_encoding(MeasuredPassage),
            congestion_control=zenoh.CongestionControl.BLOCK,
            express=True,
        )
        assert wait_matching(passages, 20.0) and wait_matching(measured, 20.0)

        def put_measured(pid: str, **update: object) -> None:
            sent.setdefault(f"measured:{pid}", time.monotonic())
            measured.put(json.dumps({**template, "passage_id": pid, **update}))

        def put_passage(pid: str) -> None:
            sent[f"passage:{pid}"] = time.monotonic()
            passages.put(wheel(pid).model_dump_json())

        # passage first, then its measurement
        put_passage("pm")
        assert out.wait(lambda: "pm" in out.results), svc.output
        put_measured("pm")
        assert out.wait(lambda: "pm" in out.diagnoses), svc.output
        # measurement first, then its passage
        put_measured("mp")
        time.sleep(0.2)
        put_passage("mp")
        assert out.wait(lambda: "mp" in out.diagnoses), svc.output
        # bad, duplicate and unpaired measurements
        put_measured("nan", force=[math.nan, *template["force"][1:]])
        put_measured("empty", force=[])
        measured.put(b'{"passage_id": "broken", ')
        put_measured("pm")  # duplicate
        put_measured("lonely")  # its passage never comes
        assert out.wait(lambda: out.error_for("lonely", "unpaired") is not None), svc.output
        # the service still serves
        put_passage("after")
        assert out.wait(lambda: "after" in out.results), svc.output
        sub.undeclare()
        passages.undeclare()
        measured.undeclare()
    assert svc.returncode == 0, svc.output
    return Run(out, sent, svc, list(read_log(svc.mcap_files)))


def test_diagnosis_finds_the_flat_in_either_order(run: Run) -> None:
    for pid in ("pm", "mp"):
        _, d = run.out.diagnoses[pid]
        assert d.passage_id == pid
        assert d.flat is not None, d
        assert d.verdict != "ok"
        assert abs(d.flat.length - FLAT_LENGTH) <= 0.010, d.flat
        assert d.flat.length_low <= d.flat.length <= d.flat.length_high
    assert run.out.encodings["diagnosis"] == f"application/json;{encoding_schema(Diagnosis)}"
    latency = run.out.diagnoses["pm"][0] - run.sent["measured:pm"]
    print(
        f"\nmeasurement → diagnosis: {latency * 1e3:.0f} ms (passage first); "
        f"passage → diagnosis: "
        f"{(run.out.diagnoses['mp'][0] - run.sent['passage:mp']) * 1e3:.0f} ms "
        "(measurement first, including the passage's simulation)"
    )
    assert latency < 10.0


def test_bad_measurements_get_errors_naming_the_field(run: Run) -> None:
    errors = run.out.errors
    nan = run.out.error_for("nan", "invalid_measurement")
    assert nan is not None and nan.field is not None and nan.field.startswith("force")
    assert "not a valid MeasuredPassage" in nan.message
    empty = run.out.error_for("empty", "invalid_measurement")
    assert empty is not None and empty.field == "force"
    assert any(e.kind == "invalid_json" and e.passage_id is None for e in errors)
    dup = run.out.error_for("pm", "invalid_measurement")
    assert dup is not None and "duplicate" in dup.message
    lonely = run.out.error_for("lonely", "unpaired")
    assert lonely is not None and f"{PAIRING_TIMEOUT:g} s" in lonely.message
    assert lonely.received_at <= time.time()
    # nothing else went wrong, and the passage after them was served
    assert Counter(e.kind for e in errors) == {
        "invalid_measurement": 3,
        "invalid_json": 1,
        "unpaired": 1,
    }
    assert "after" in run.out.results
    assert "lonely" not in run.out.diagnoses


def test_mcap_logs_measurements_and_diagnoses(run: Run) -> None:
    prefix = run.out.keys.prefix
    topics = Counter(m.topic for m in run.logged)
    assert topics[f"{prefix}/measured"] == 4  # pm, mp, pm again (duplicate), lonely
    assert topics[f"{prefix}/measured/rejected"] == 3
    assert topics[f"{prefix}/diagnosis"] == 2
    for m in run.logged:
        decode(m)
    logged = [decode(m) for m in run.logged if m.topic == f"{prefix}/diagnosis"]
    assert {d.passage_id: d for d in logged} == {
        pid: d for pid, (_, d) in run.out.diagnoses.items()
    }
    assert all(
        isinstance(decode(m), MeasuredPassage)
        for m in run.logged
        if m.topic == f"{prefix}/measured"
    )
    # every verdict and every error again in Foxglove's Log panel, at its verdict's level
    levels = {
        "ok": foxglove.INFO,
        "watch": foxglove.INFO,
        "inspect": foxglove.WARNING,
        "remove": foxglove.ERROR,
    }
    notes = [decode(m) for m in run.logged if m.topic == f"{prefix}/log"]
    assert len(notes) == topics[f"{prefix}/diagnosis"] + topics[f"{prefix}/error"]
    for d in logged:
        (note,) = [n for n in notes if n.message.startswith(f"passage {d.passage_id}: ")]
        assert note.level == levels[d.verdict] and d.verdict in note.message


def test_rrd_draws_the_diagnoses(run: Run) -> None:
    rrd = run.service.rrd_file
    assert rrd is not None and rrd.is_file()
    cols = rrd_columns(rrd)
    e = entities(load_site(EXAMPLE_SITE).site_id)
    for role in ("measured", "fit", "impacts"):
        assert e[role] in cols, sorted(cols)
    n = len(measurement("m0").force)
    measured = cols[e["measured"]]
    assert len(measured["values"]) == 2 * n
    assert sorted(set(measured["diagnosis"])) == [0, 1]
    assert np.all(np.isfinite(cols[e["fit"]]["values"]))
    # each diagnosis is drawn in its wheel's slot too, beside the simulated passage
    index = passage_indexes(rrd, load_site(EXAMPLE_SITE).site_id)
    verdicts = rrd_texts(rrd)[e["verdict"]]
    assert len(verdicts) == 2
    for at, text in verdicts:
        pid = text.split(":", 1)[0]
        assert at == index[pid]
        assert len(of_passage(measured, at)["values"]) == n
