"""A network of sites (issue 16, items 1, 4, 6, 7 twin side): the wheel's identity from
passage to result and diagnosis, queryables that reply on their own concrete key (two
twins, one wildcard get), the twin's catch-up queryable, and twins and clients joined
through a ``railtwin router`` process.

Twins run in this process with the closed-form stub physics (and a stand-in diagnoser,
the fit itself is tested elsewhere) over loopback Zenoh; the router test starts
``railtwin router`` and ``railtwin serve --connect`` as processes.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import zenoh

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import Health, PassageResult, RailState, WheelPassage, WheelRef
from schemas.site import SiteConfig
from service.cli.service_process import ServiceProcess
from service.physics.local import LocalPhysics
from service.physics.port import DiagnosisOutcome
from service.physics.stub import StubPhysics
from service.twin.diagnoses import DiagnosisStore
from service.twin.twin import Twin
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config, free_tcp_endpoint

ROOT = Path(__file__).resolve().parents[1]


def site(site_id: str) -> SiteConfig:
    return SiteConfig.model_validate(
        {
            "site_id": site_id,
            "length": 3.0,
            "output_sample_rate": 2000.0,
            "contact": "hertz",
            "rail": {"kind": "flat"},
            "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
        }
    )


WHEEL = WheelRef.parse("31-80-4751-123-4/2/left")


def passage(pid: str, timestamp: float, wheel: WheelRef | None = WHEEL) -> WheelPassage:
    direction = "end1_leading"
    return WheelPassage.model_validate(
        {
            "passage_id": pid,
            "train_id": "t1",
            "axle_index": 3,
            "timestamp": timestamp,
            "speed": 40.0,
            "load": 60e3,
            "mass": 500.0,
            "radius": 0.46,
            "side": wheel.rail_side(direction) if wheel else "left",
            "wheel": wheel.model_dump() if wheel else None,
            "direction": direction if wheel else None,
        }
    )


def measured(pid: str) -> MeasuredPassage:
    return MeasuredPassage(
        passage_id=pid,
        sample_rate=1e4,
        t_start=0.0,
        force=[6e4 + 100.0 * (i % 5) for i in range(32)],
    )


def stand_in_diagnoser(site_id: str, p: WheelPassage, m: MeasuredPassage) -> DiagnosisOutcome:
    """A diagnosis as the real diagnoser makes it: without the wheel and the timestamp."""
    d = Diagnosis(
        site_id=site_id,
        passage_id=p.passage_id,
        flat=None,
        verdict="ok",
        reasons=[],
        peak_force_measured=max(m.force),
        peak_force_fit=max(m.force),
        fit_rms=1.0,
        peak_force_at_line_speed=None,
        wall_time=0.0,
    )
    return DiagnosisOutcome(d, [0.0], [0.0], [0.0], [0.0], [])


class Site:
    """A twin of site ``site_id`` on its own peer session, listening on ``endpoint``."""

    def __init__(self, site_id: str, store: DiagnosisStore | None = None) -> None:
        self.endpoint = free_tcp_endpoint()
        self.config = site(site_id)
        self.session = zenoh.open(build_config(listen=[self.endpoint]))
        physics = LocalPhysics(
            StubPhysics(self.config), diagnose=lambda p, m: stand_in_diagnoser(site_id, p, m)
        )
        self.twin = Twin(self.config, self.session, physics, diagnoses=store)
        self.twin.start()

    def close(self) -> None:
        self.twin.stop()
        self.session.close()


@pytest.fixture
def two_sites() -> Iterator[tuple[Site, Site, zenoh.Session]]:
    a, b = Site("km12"), Site("km47")
    client = zenoh.open(build_config(connect=[a.endpoint, b.endpoint]))
    try:
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and len(healths(client)) < 2:
            time.sleep(0.1)
        yield a, b, client
    finally:
        client.close()
        a.close()
        b.close()


def healths(client: zenoh.Session, key: str = "railtwin/*/health") -> dict[str, Health]:
    out = {}
    for reply in client.get(key, timeout=5.0):
        if reply.ok is not None:
            out[str(reply.ok.key_expr)] = Health.model_validate_json(reply.ok.payload.to_bytes())
    return out


def put(client: zenoh.Session, key: str, model: WheelPassage | MeasuredPassage) -> None:
    client.put(key, model.model_dump_json(), encoding=json_encoding(type(model)))


def wait_for(predicate: Any, timeout: float = 20.0) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


# --- concrete keys -------------------------------------------------------------------------


def test_a_wildcard_query_gets_one_reply_per_twin(
    two_sites: tuple[Site, Site, zenoh.Session],
) -> None:
    _, _, client = two_sites
    got = healths(client)
    assert set(got) == {"railtwin/km12/health", "railtwin/km47/health"}
    assert {k: h.site_id for k, h in got.items()} == {
        "railtwin/km12/health": "km12",
        "railtwin/km47/health": "km47",
    }
    rails = [
        RailState.model_validate_json(r.ok.payload.to_bytes())
        for r in client.get("railtwin/*/rail", timeout=5.0)
        if r.ok is not None
    ]
    assert sorted(r.site_id for r in rails) == ["km12", "km47"]
    # the legacy railtwin/health answers on its own key too (not the query's)
    legacy = [
        str(r.ok.key_expr) for r in client.get("railtwin/**", timeout=5.0) if r.ok is not None
    ]
    assert set(legacy) == {
        "railtwin/health",
        "railtwin/km12/health",
        "railtwin/km12/rail",
        "railtwin/km47/health",
        "railtwin/km47/rail",
    }


# --- the wheel from passage to result and diagnosis -----------------------------------------


def test_the_wheel_and_time_go_through_to_result_and_diagnosis(
    two_sites: tuple[Site, Site, zenoh.Session],
) -> None:
    _, _, client = two_sites
    keys = SiteKeys("km12")
    got: dict[str, bytes] = {}
    subs = [
        client.declare_subscriber(
            k, lambda s: got.__setitem__(str(s.key_expr), s.payload.to_bytes())
        )
        for k in (keys.result("p1"), keys.diagnosis("p1"), keys.error)
    ]
    time.sleep(0.3)
    put(client, keys.passage, passage("p1", 1.75e9))
    put(client, keys.measured, measured("p1"))
    wait_for(lambda: keys.diagnosis("p1") in got or keys.error in got)
    assert keys.error not in got, got.get(keys.error)
    wait_for(lambda: keys.result("p1") in got)
    result = PassageResult.model_validate_json(got[keys.result("p1")])
    diag = Diagnosis.model_validate_json(got[keys.diagnosis("p1")])
    assert result.wheel == diag.wheel == WHEEL
    assert (result.side, result.axle_index) == ("right", 3)  # end 1 leading: rail side swapped
    assert (diag.site_id, diag.timestamp, result.timestamp) == ("km12", 1.75e9, 1.75e9)
    assert diag.schema_version == "1.5"
    for s in subs:
        s.undeclare()


# --- catch-up --------------------------------------------------------------------------------


def catch_up(
    client: zenoh.Session, selector: str, accept_any: bool = True
) -> tuple[dict[str, Diagnosis], list[str]]:
    ok: dict[str, Diagnosis] = {}
    errors: list[str] = []
    kwargs: dict[str, Any] = {"accept_replies": zenoh.ReplyKeyExpr.ANY} if accept_any else {}
    for reply in client.get(selector, timeout=5.0, **kwargs):
        if reply.ok is not None:
            key = str(reply.ok.key_expr)
            assert key not in ok, f"{key} twice"
            ok[key] = Diagnosis.model_validate_json(reply.ok.payload.to_bytes())
        elif reply.err is not None:
            errors.append(reply.err.payload.to_string())
    return ok, errors


def test_catch_up_returns_each_diagnosis_since_a_time_on_its_own_key(
    two_sites: tuple[Site, Site, zenoh.Session],
) -> None:
    a, b, client = two_sites
    t0 = time.time()
    for s, pid, ts in ((a, "a1", t0 - 86400.0), (a, "a2", t0 + 5.0), (b, "b1", t0 - 7200.0)):
        keys = s.twin.keys
        put(client, keys.passage, passage(pid, ts))
        put(client, keys.measured, measured(pid))
    wait_for(lambda: a.twin.diagnoses_done == 2 and b.twin.diagnoses_done == 1)
    got, errors = catch_up(client, f"railtwin/*/diagnoses?since={t0 - 60.0}")
    assert errors == []
    assert set(got) == {
        "railtwin/km12/diagnosis/a1",
        "railtwin/km12/diagnosis/a2",
        "railtwin/km47/diagnosis/b1",
    }  # made since then, whatever their passage
    assert all(d.wheel == WHEEL and d.timestamp is not None for d in got.values())
    # after the time they were made: only a passage whose own timestamp is later
    got, _ = catch_up(client, f"railtwin/*/diagnoses?since={time.time() + 1.0}")
    assert set(got) == {"railtwin/km12/diagnosis/a2"}
    got, _ = catch_up(client, "railtwin/km47/diagnoses?_anyke", accept_any=False)  # everything
    assert set(got) == {"railtwin/km47/diagnosis/b1"}
    # a query that would drop the replies, or a bad since, gets a clear error
    got, errors = catch_up(client, "railtwin/km12/diagnoses?since=0", accept_any=False)
    assert got == {} and len(errors) == 1 and "ReplyKeyExpr.ANY" in errors[0]
    got, errors = catch_up(client, "railtwin/km12/diagnoses?since=yesterday")
    assert got == {} and "since='yesterday'" in errors[0]
    got, errors = catch_up(client, "railtwin/km12/diagnoses?since=nan")
    assert got == {} and "finite" in errors[0]


def test_a_catch_up_answer_too_long_is_cut_and_says_so(
    two_sites: tuple[Site, Site, zenoh.Session], monkeypatch: pytest.MonkeyPatch
) -> None:
    import service.twin.twin

    monkeypatch.setattr(service.twin.twin, "MAX_REPLIES", 2)
    a, _, client = two_sites
    for i in range(3):
        a.twin.diagnoses.add(
            f"c{i}",
            made_at=100.0 + i,
            timestamp=None,
            data=b'{"site_id": "km12", "passage_id": "c%d"}' % i,
        )
    replies = list(
        client.get(
            "railtwin/km12/diagnoses?since=0", timeout=5.0, accept_replies=zenoh.ReplyKeyExpr.ANY
        )
    )
    assert sorted(str(r.ok.key_expr) for r in replies if r.ok is not None) == [
        "railtwin/km12/diagnosis/c0",
        "railtwin/km12/diagnosis/c1",
    ]  # the oldest made
    (err,) = [r.err.payload.to_string() for r in replies if r.err is not None]
    assert "cut at 2" in err and "later since" in err


def test_catch_up_survives_a_restart_of_the_twin(tmp_path: Path) -> None:
    path = tmp_path / "km12-diagnoses.sqlite"
    first = Site("km12", DiagnosisStore(path))
    client = zenoh.open(build_config(connect=[first.endpoint]))
    try:
        wait_for(lambda: len(healths(client, "railtwin/km12/health")) == 1)
        put(client, first.twin.keys.passage, passage("r1", 1.7e9))
        put(client, first.twin.keys.measured, measured("r1"))
        wait_for(lambda: first.twin.diagnoses_done == 1)
    finally:
        client.close()
        first.close()
        first.twin.diagnoses.close()
    second = Site("km12", DiagnosisStore(path))
    client = zenoh.open(build_config(connect=[second.endpoint]))
    try:
        wait_for(lambda: len(healths(client, "railtwin/km12/health")) == 1)
        got, errors = catch_up(client, "railtwin/km12/diagnoses?since=1.6e9")
        assert errors == [] and list(got) == ["railtwin/km12/diagnosis/r1"]
        assert got["railtwin/km12/diagnosis/r1"].wheel == WHEEL
    finally:
        client.close()
        second.close()


def test_the_store_prunes_by_age_and_count() -> None:
    """Pruned at every 1000th addition: older than keep_seconds, beyond max_rows."""
    by_age = DiagnosisStore(None, keep_seconds=100.0)
    by_count = DiagnosisStore(None, max_rows=500)
    for i in range(2000):
        for store in (by_age, by_count):
            store.add(f"p{i}", made_at=float(i), timestamp=None, data=b"{}")
    assert [pid for pid, _ in by_age.since(-1.0)] == [f"p{i}" for i in range(1899, 2000)]
    assert [pid for pid, _ in by_count.since(-1.0)] == [f"p{i}" for i in range(1500, 2000)]


# --- through a router ---------------------------------------------------------------------------


class Router:
    def __init__(self, endpoint: str) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "service.cli.router", "--listen", endpoint],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            cwd=ROOT,
        )
        assert self.proc.stdout is not None
        self.lines = []
        for line in self.proc.stdout:
            self.lines.append(line)
            if line.startswith("railtwin router: ready"):
                return
        raise AssertionError("router did not start:\n" + "".join(self.lines))

    def close(self) -> str:
        self.proc.terminate()
        out, _ = self.proc.communicate(timeout=30)
        return "".join(self.lines) + out


def test_a_twin_and_a_client_joined_through_a_router(tmp_path: Path) -> None:
    router_endpoint = free_tcp_endpoint()
    site_file = tmp_path / "site.toml"
    site_file.write_text(
        'site_id = "km99"\nlength = 3.0\noutput_sample_rate = 2000.0\n'
        'contact = "hertz"\nrail = { kind = "flat" }\n[material]\n'
        "youngs_modulus = 2.14e11\npoisson_ratio = 0.3\n"
    )
    router = Router(router_endpoint)
    try:
        twin = ServiceProcess(
            site_file,
            listen=None,
            recordings=tmp_path / "rec",
            extra_args=(
                "--connect",
                router_endpoint,
                "--mode",
                "client",
                "--physics",
                "stub",
                "--in-process",
                "--no-rerun",
            ),
        )
        with twin, zenoh.open(build_config(mode="client", connect=[router_endpoint])) as client:
            keys = SiteKeys("km99")
            wait_for(lambda: len(healths(client)) == 1)
            results: list[PassageResult] = []
            sub = client.declare_subscriber(
                keys.result("via-router"),
                lambda s: results.append(PassageResult.model_validate_json(s.payload.to_bytes())),
            )
            time.sleep(0.3)
            put(client, keys.passage, passage("via-router", 1.7e9))
            wait_for(lambda: len(results) == 1)
            assert results[0].wheel == WHEEL and results[0].site_id == "km99"
            assert healths(client)["railtwin/km99/health"].passages_done == 1
            sub.undeclare()
        assert twin.returncode == 0, twin.output
    finally:
        out = router.close()
    assert "railtwin router: routing on " + router_endpoint in out
    assert "railtwin router: stopped" in out


def test_router_refuses_a_bad_endpoint() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "service.cli.router", "--listen", "nonsense"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
        check=False,
    )
    assert out.returncode != 0
    assert "railtwin router:" in out.stderr and "nonsense" in out.stderr


def test_railtwin_router_is_a_command() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "service.cli.main", "router", "--help"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=60,
        check=False,
    )
    assert out.returncode == 0 and "--listen" in out.stdout and "--connect" in out.stdout


@pytest.mark.parametrize("name", ["service.twin.diagnoses", "service.wire.keyspace"])
def test_worked_examples(name: str) -> None:
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(name))
    assert result.attempted > 0 and result.failed == 0


def test_the_measured_feeder_names_the_wheel_of_each_diagnosis() -> None:
    from service.clients.measured_feeder import describe

    d = stand_in_diagnoser("km12", passage("p9", 1.7e9), measured("p9")).diagnosis
    assert "(wheel" not in describe(d, 0.1)
    named = describe(d.model_copy(update={"wheel": WHEEL}), 0.1)
    assert named.startswith("diagnosis p9 (wheel 31-80-4751-123-4/2/left): OK")
