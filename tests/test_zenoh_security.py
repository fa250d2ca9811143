"""Zenoh mutual TLS and access control with the shipped configs (``deploy/zenoh/``).

Certificates are made in a temporary directory by ``deploy/zenoh/make_certs.py``
(``openssl``). The twin runs as ``railtwin serve --zenoh-config twin.json5`` in its own
process, listening on ``tls/localhost:PORT``; the site publisher and a consumer use
``site-publisher.json5`` and ``consumer.json5``; the intruder has a certificate of the
same CA with another CN and no access control of its own. Checked:

- the site publisher's passage is simulated and its result reaches the consumer;
- the intruder's session is up (TLS accepts its certificate), yet its passage is
  dropped by the twin (no result, no error, not counted as received) and its health
  query is not answered;
- a forged ``result`` the intruder sends straight to the consumer is dropped by the
  consumer (its subscriber matched, so the put was sent);
- a plain ``tcp/`` peer cannot open a link to the TLS port (no health reply).
"""

from __future__ import annotations

import importlib.util
import shutil
import socket
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import pytest
import zenoh

from schemas.messages import TrainFile, WheelPassage
from service.cli.service_process import ServiceProcess
from service.clients.feeder import Collector, declare_passage_publisher, query_health, wait_matching
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config

pytestmark = pytest.mark.skipif(
    shutil.which("openssl") is None, reason="openssl is not installed: no certificates can be made"
)

ROOT = Path(__file__).resolve().parents[1]
DEPLOY = ROOT / "deploy" / "zenoh"
SITE_ID = "km12"  # the site the shipped configs name
KEYS = SiteKeys(SITE_ID)
CERT_DIR_IN_CONFIGS = "/etc/railtwin/zenoh/"
DROP_WINDOW = 3.0  # s to wait for something that must not come


def load_make_certs() -> ModuleType:
    spec = importlib.util.spec_from_file_location("make_certs", DEPLOY / "make_certs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
    return port


def shipped_config(name: str, certs: Path, out: Path) -> Path:
    """A shipped config with its certificate paths pointed at ``certs``."""
    text = (DEPLOY / name).read_text()
    assert CERT_DIR_IN_CONFIGS in text
    path = out / name
    path.write_text(text.replace(CERT_DIR_IN_CONFIGS, f"{certs}/"))
    return path


def intruder_config(certs: Path, connect: list[str]) -> zenoh.Config:
    """A peer with a certificate of the site's CA (CN "intruder") and no access control."""
    cfg = build_config(connect=connect, listen=[])
    cfg.insert_json5("transport/link/tls/root_ca_certificate", f'"{certs}/ca.pem"')
    cfg.insert_json5("transport/link/tls/connect_private_key", f'"{certs}/intruder.key"')
    cfg.insert_json5("transport/link/tls/connect_certificate", f'"{certs}/intruder.pem"')
    cfg.insert_json5("transport/link/tls/enable_mtls", "true")
    return cfg


def a_passage(passage_id: str) -> WheelPassage:
    train = TrainFile.model_validate_json(
        (ROOT / "recordings/samples/train_160kmh.json").read_bytes()
    )
    return train.wheels[0].passage.model_copy(update={"passage_id": passage_id})


def wait_until(check: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if check():
            return True
        time.sleep(0.05)
    return False


@dataclass
class Deployment:
    certs: Path
    twin_endpoint: str
    consumer_endpoint: str
    consumer: zenoh.Session
    collector: Collector
    keys_seen: list[str]
    site: zenoh.Session
    service: ServiceProcess


@pytest.fixture(scope="module")
def deployment(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Deployment]:
    tmp = tmp_path_factory.mktemp("zenoh-security")
    certs = tmp / "certs"
    made = load_make_certs().make_certs(certs, site=SITE_ID)
    assert set(made) >= {"ca", "twin", f"site-{SITE_ID}", "consumer", "intruder"}
    site_file = tmp / "site.toml"
    site_file.write_text(
        (ROOT / "examples/site_compliant.toml")
        .read_text()
        .replace('site_id = "demo"', f'site_id = "{SITE_ID}"')
    )
    twin_endpoint = f"tls/localhost:{free_port()}"
    consumer_endpoint = f"tls/localhost:{free_port()}"
    svc = ServiceProcess(
        site_file,
        listen=twin_endpoint,
        recordings=tmp / "recordings",
        extra_args=("--zenoh-config", str(shipped_config("twin.json5", certs, tmp)), "--no-rerun"),
        start_timeout=180.0,  # ~5 s warm-up, unless numba recompiles on a loaded machine
    )
    with svc:
        consumer_cfg = build_config(
            connect=[twin_endpoint],
            listen=[consumer_endpoint],
            config_file=shipped_config("consumer.json5", certs, tmp),
        )
        site_cfg = build_config(
            connect=[twin_endpoint], config_file=shipped_config("site-publisher.json5", certs, tmp)
        )
        with zenoh.open(consumer_cfg) as consumer, zenoh.open(site_cfg) as site:
            collector = Collector(KEYS)
            keys_seen: list[str] = []  # every sample, even one the Collector cannot decode
            subs = [
                consumer.declare_subscriber(KEYS.all_outputs, collector),
                consumer.declare_subscriber(
                    KEYS.all_outputs, lambda s: keys_seen.append(str(s.key_expr))
                ),
            ]
            yield Deployment(
                certs, twin_endpoint, consumer_endpoint, consumer, collector, keys_seen, site, svc
            )
            for sub in subs:
                sub.undeclare()
    assert svc.returncode == 0, svc.output


def test_the_site_publisher_gets_a_result_to_the_consumer(deployment: Deployment) -> None:
    pub = declare_passage_publisher(deployment.site, KEYS)
    assert wait_matching(pub, 20.0), "the twin's subscriber never matched over TLS"
    passage = a_passage("site-1")
    deployment.collector.expect(passage.passage_id, time.monotonic())
    pub.put(passage.model_dump_json())
    assert deployment.collector.wait([passage.passage_id], 30.0), deployment.service.output
    outcome = deployment.collector.outcomes[passage.passage_id]
    assert outcome.result is not None and outcome.error is None
    assert outcome.result.summary.peak_force > 0.5 * passage.load
    pub.undeclare()
    (health,) = [h for h in query_health(deployment.consumer) if h.site_id == SITE_ID]
    assert health.passages_received == 1


def test_an_intruder_of_the_same_ca_is_dropped(deployment: Deployment) -> None:
    d = deployment
    cfg = intruder_config(d.certs, [d.twin_endpoint, d.consumer_endpoint])
    with zenoh.open(cfg) as intruder:
        # TLS let it in: it has sessions with the twin and the consumer ...
        assert wait_until(lambda: len(list(intruder.info.peers_zid())) >= 2, 10.0)
        # ... but the twin does not declare its subscriber to it, and drops what it puts
        passage = a_passage("intruder-1")
        d.collector.expect(passage.passage_id, time.monotonic())
        intruder.put(KEYS.passage, passage.model_dump_json())
        intruder.put(KEYS.measured, b'{"passage_id": "intruder-1"}')
        # a forged result, straight to the consumer, whose subscriber it sees
        forged = intruder.declare_publisher(KEYS.result("forged-1"))
        assert wait_matching(forged, 10.0), "the consumer's subscriber should be visible"
        forged.put(b'{"passage_id": "forged-1"}')
        intruder.put(KEYS.error, b'{"kind": "overloaded", "message": "forged"}')
        # nor does it answer its health query
        assert query_health(intruder, timeout=2.0) == []
        time.sleep(DROP_WINDOW)
        forged.undeclare()
    outcomes = d.collector.outcomes
    assert outcomes["intruder-1"].result is None and outcomes["intruder-1"].force_at is None
    assert "forged-1" not in outcomes
    assert KEYS.result("forged-1") not in d.keys_seen
    assert [k for k in d.keys_seen if "intruder-1" in k] == []
    assert KEYS.error not in d.keys_seen
    assert d.collector.errors == [], "neither the intruder's input nor its forged error count"
    (health,) = [h for h in query_health(d.consumer) if h.site_id == SITE_ID]
    assert health.passages_received == 1 and health.errors == 0


def test_a_plain_tcp_peer_cannot_connect(deployment: Deployment) -> None:
    plain = "tcp/" + deployment.twin_endpoint.removeprefix("tls/")
    try:
        session = zenoh.open(build_config(connect=[plain], listen=[]))
    except zenoh.ZError:
        return  # refused outright: as good
    with session:
        assert list(session.info.peers_zid()) == []
        assert query_health(session, timeout=2.0) == []
