"""A region's router with mutual TLS and access control, as shipped (``deploy/zenoh/
router.json5``, ``twin-via-router.json5``; docs/deployment.md).

``railtwin router --zenoh-config router.json5`` runs as a process; the twin joins it as
``railtwin serve --mode client --zenoh-config twin-via-router.json5`` (stub physics); the
site publisher, a consumer and an intruder (a certificate of the same CA, another CN)
join it as clients. Checked: the site's passage reaches the twin and its result the
consumer, through the router only; the intruder's passage is dropped by the router (no
result, not counted by the twin) and so is a result it forges.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from service.cli.service_process import ServiceProcess
from service.clients.feeder import Collector, declare_passage_publisher, wait_matching
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config
from tests.test_zenoh_security import (
    DROP_WINDOW,
    ROOT,
    a_passage,
    free_port,
    load_make_certs,
    shipped_config,
    wait_until,
)

pytestmark = pytest.mark.skipif(
    shutil.which("openssl") is None, reason="openssl is not installed: no certificates can be made"
)

SITE_ID = "km12"
KEYS = SiteKeys(SITE_ID)


def client_config(certs: Path, name: str, router: str) -> zenoh.Config:
    """A client of the router with the certificate ``name`` (its CN)."""
    cfg = build_config(mode="client", connect=[router])
    for key, value in (
        ("root_ca_certificate", "ca.pem"),
        ("connect_private_key", f"{name}.key"),
        ("connect_certificate", f"{name}.pem"),
    ):
        cfg.insert_json5(f"transport/link/tls/{key}", f'"{certs}/{value}"')
    cfg.insert_json5("transport/link/tls/enable_mtls", "true")
    return cfg


def healths(session: zenoh.Session) -> list[str]:
    return [
        str(r.ok.key_expr)
        for r in session.get("railtwin/*/health", timeout=2.0)
        if r.ok is not None
    ]


class Router:
    def __init__(self, config: Path, endpoint: str) -> None:
        self.proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "service.cli.router",
                "--zenoh-config",
                str(config),
                "--listen",
                endpoint,
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=ROOT,
        )
        assert self.proc.stdout is not None
        self.lines: list[str] = []
        for line in self.proc.stdout:
            self.lines.append(line)
            if line.startswith("railtwin router: ready"):
                return
        raise AssertionError("router did not start:\n" + "".join(self.lines))

    def close(self) -> int:
        self.proc.terminate()
        self.proc.communicate(timeout=30)
        return self.proc.returncode


@pytest.fixture(scope="module")
def region(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, str, ServiceProcess]]:
    tmp = tmp_path_factory.mktemp("router-security")
    certs = tmp / "certs"
    made = load_make_certs().make_certs(certs, site=SITE_ID)
    assert {"router", "fleet"} <= set(made)
    site_file = tmp / "site.toml"
    site_file.write_text(
        (ROOT / "examples/site_compliant.toml")
        .read_text()
        .replace('site_id = "demo"', f'site_id = "{SITE_ID}"')
    )
    endpoint = f"tls/localhost:{free_port()}"
    router = Router(shipped_config("router.json5", certs, tmp), endpoint)
    try:
        twin = ServiceProcess(
            site_file,
            listen=None,
            recordings=tmp / "recordings",
            extra_args=(
                "--mode",
                "client",
                "--connect",
                endpoint,
                "--zenoh-config",
                str(shipped_config("twin-via-router.json5", certs, tmp)),
                "--physics",
                "stub",
                "--in-process",
                "--no-rerun",
            ),
        )
        with twin:
            yield certs, endpoint, twin
        assert twin.returncode == 0, twin.output
    finally:
        assert router.close() == 0


def test_through_the_router_the_site_reaches_the_twin_and_the_consumer_its_result(
    region: tuple[Path, str, ServiceProcess],
) -> None:
    certs, endpoint, twin = region
    with (
        zenoh.open(client_config(certs, f"site-{SITE_ID}", endpoint)) as site,
        zenoh.open(client_config(certs, "consumer", endpoint)) as consumer,
    ):
        assert wait_until(lambda: healths(consumer) == [KEYS.health], 20.0), twin.output
        collector = Collector(KEYS)
        sub = consumer.declare_subscriber(KEYS.all_outputs, collector)
        pub = declare_passage_publisher(site, KEYS)
        assert wait_matching(pub, 20.0), "the twin's subscriber never reached the site"
        passage = a_passage("via-router-1")
        collector.expect(passage.passage_id, time.monotonic())
        pub.put(passage.model_dump_json())
        assert collector.wait([passage.passage_id], 30.0), twin.output
        outcome = collector.outcomes[passage.passage_id]
        assert outcome.result is not None and outcome.result.wheel == passage.wheel
        pub.undeclare()
        sub.undeclare()


def test_the_router_drops_an_intruder_of_the_same_ca(
    region: tuple[Path, str, ServiceProcess],
) -> None:
    certs, endpoint, twin = region
    with (
        zenoh.open(client_config(certs, "consumer", endpoint)) as consumer,
        zenoh.open(client_config(certs, "intruder", endpoint)) as intruder,
    ):
        assert wait_until(lambda: healths(consumer) == [KEYS.health], 20.0), twin.output
        before = consumer.get(KEYS.health, timeout=2.0)
        received = [r.ok.payload.to_string() for r in before if r.ok is not None]
        seen: list[str] = []
        sub = consumer.declare_subscriber(KEYS.all_outputs, lambda s: seen.append(str(s.key_expr)))
        # TLS let it in (same CA): it has a session with the router ...
        assert wait_until(lambda: len(list(intruder.info.routers_zid())) == 1, 10.0)
        # ... but its query is not let through, nor what it puts
        assert healths(intruder) == []
        intruder.put(KEYS.passage, a_passage("intruder-1").model_dump_json())
        intruder.put(KEYS.result("forged-1"), b'{"passage_id": "forged-1"}')
        time.sleep(DROP_WINDOW)
        sub.undeclare()
        assert seen == []
        after = [
            r.ok.payload.to_string()
            for r in consumer.get(KEYS.health, timeout=2.0)
            if r.ok is not None
        ]
        assert len(received) == len(after) == 1
        assert '"passages_received":' in after[0]
        assert (
            json.loads(after[0])["passages_received"]
            == json.loads(received[0])["passages_received"]
        )
