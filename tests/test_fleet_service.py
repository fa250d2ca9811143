"""The fleet service over Zenoh: diagnoses in, history and alarms out, queries answered
on their own keys, catch-up from a twin's queryable, the CLI's ``fleet wheel``."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
import zenoh

from service.cli import fleet as fleet_cli
from service.fleet.service import FleetService
from service.fleet.store import open_store
from service.wire.zenoh_session import build_config, free_tcp_endpoint
from tests.fleet_support import FakeTwin, diagnosis_json, wait_for


def _listen_for_alarms(
    client: zenoh.Session, fleet: zenoh.Session
) -> tuple[list[zenoh.Sample], zenoh.Subscriber[None]]:
    """The client's subscriber to every alarm (and the list it fills), once the fleet's
    session knows of it (else the first alarms could be published to nobody)."""
    got: list[zenoh.Sample] = []
    sub = client.declare_subscriber("railtwin/fleet/alarm/**", got.append)
    probe = fleet.declare_publisher("railtwin/fleet/alarm/V1/1/left")
    wait_for(lambda: probe.matching_status.matching, what="the alarm subscriber known")
    probe.undeclare()
    return got, sub


@pytest.fixture
def net(db_url: str) -> Iterator[dict[str, Any]]:
    """Two fake twins on one listening session, a fleet service (on SQLite, then on
    PostgreSQL) and a client connected."""
    endpoint = free_tcp_endpoint()
    twin_s = zenoh.open(build_config(listen=[endpoint]))
    fleet_s = zenoh.open(build_config(connect=[endpoint]))
    client_s = zenoh.open(build_config(connect=[endpoint]))
    store = open_store(db_url)
    a, b = FakeTwin(twin_s, "km12"), FakeTwin(twin_s, "km48")
    # one diagnosis made before the fleet starts: it must come by catch-up
    a.diagnose(
        "early",
        diagnosis_json("km12", "early", "V7/1/right", day=-1, verdict="ok", length=None),
        publish=False,
    )
    svc = FleetService(fleet_s, store, horizon=30 * 86400.0)
    alarms, sub = _listen_for_alarms(client_s, fleet_s)
    svc.start()
    try:
        yield {
            "endpoint": endpoint,
            "svc": svc,
            "store": store,
            "a": a,
            "b": b,
            "client": client_s,
            "alarms": alarms,
        }
    finally:
        sub.undeclare()
        svc.stop()
        a.close()
        b.close()
        for s in (client_s, fleet_s, twin_s):
            s.close()
        store.close()


def _publish_growing_flat(net: dict[str, Any]) -> None:
    a, b = net["a"], net["b"]
    for day, twin, verdict, length in [
        (0, a, "watch", 0.031),
        (1, b, "watch", 0.037),
        (2, a, "inspect", 0.043),
    ]:
        pid = f"t{day}-a1-l"
        twin.diagnose(
            pid,
            diagnosis_json(
                twin.site,
                pid,
                "V1/1/left",
                day=day,
                verdict=verdict,
                length=length,
                half_width=0.001,
            ),
        )
        # the other wheel of the axle: round
        twin.diagnose(
            f"t{day}-a1-r", diagnosis_json(twin.site, f"t{day}-a1-r", "V1/1/right", day=day)
        )
        # days apart: each is stored before the next comes (one batch would hold them all,
        # and a wheel jumping from ok to inspect in one batch raises only the inspect alarm)
        wait_for(
            lambda site=twin.site, pid=pid: net["store"].entry(site, pid) is not None,
            what=f"{pid} stored",
        )


def test_history_alarms_and_queries(net: dict[str, Any]) -> None:
    svc, store, client = net["svc"], net["store"], net["client"]
    wait_for(lambda: store.entry("km12", "early") is not None, what="catch-up of 'early'")
    _publish_growing_flat(net)
    wait_for(lambda: store.count() == 7, what="7 diagnoses stored")
    hist = store.history("V1/1/left")
    assert [(e.site_id, e.verdict) for e in hist] == [
        ("km12", "watch"),
        ("km48", "watch"),
        ("km12", "inspect"),
    ]
    # alarms: watch on day 0; on day 1, 6 mm/day predicts inspect (40 mm) on day 1.5; on
    # day 2 the verdict is inspect, and the trend predicts remove (60 mm) on day ~5
    wait_for(lambda: len(net["alarms"]) >= 4, what="4 alarms published")
    got = [json.loads(s.payload.to_bytes()) for s in net["alarms"]]
    assert {str(s.key_expr) for s in net["alarms"]} == {"railtwin/fleet/alarm/V1/1/left"}
    kinds = [(g["kind"], g["level"]) for g in got]
    assert kinds == [
        ("verdict_escalated", "watch"),
        ("forecast_flat_length", "inspect"),
        ("verdict_escalated", "inspect"),
        ("forecast_flat_length", "remove"),
    ]
    assert got[2]["evidence"] == ["km12/t2-a1-l"] and got[2]["severity"] == "warning"
    assert got[3]["evidence"] == ["km12/t0-a1-l", "km48/t1-a1-l", "km12/t2-a1-l"]
    # the wheel queryable replies on the wheel's own key; a wildcard reaches every wheel
    replies = list(client.get("railtwin/fleet/wheel/V1/1/left", timeout=5.0))
    assert [str(r.ok.key_expr) for r in replies] == ["railtwin/fleet/wheel/V1/1/left"]
    doc = json.loads(replies[0].ok.payload.to_bytes())
    assert doc["wheel_id"] == "V1/1/left" and len(doc["history"]) == 3
    assert doc["history"][2]["flat"]["length"] == pytest.approx(0.043)
    assert {"site_id", "passage_id", "timestamp", "verdict", "flat"} <= set(doc["history"][0])
    tr = doc["trend"]["flat_length"]
    assert tr["slope_per_day"] == pytest.approx(0.006, rel=1e-6)
    keys = sorted(
        str(r.ok.key_expr) for r in client.get("railtwin/fleet/wheel/V1/*/*", timeout=5.0)
    )
    assert keys == ["railtwin/fleet/wheel/V1/1/left", "railtwin/fleet/wheel/V1/1/right"]
    err = list(client.get("railtwin/fleet/wheel/NOPE/1/left", timeout=5.0))
    assert len(err) == 1 and err[0].err is not None
    al = list(client.get("railtwin/fleet/alarms", timeout=5.0))
    assert [str(r.ok.key_expr) for r in al] == ["railtwin/fleet/alarms"]
    assert len(json.loads(al[0].ok.payload.to_bytes())["alarms"]) == 4
    # a wrong payload is refused and counted, nothing stored
    net["client"].put("railtwin/km12/diagnosis/bad", b'{"site_id": "km12"}')
    wait_for(lambda: svc.counters.rejected == 1, what="the bad payload refused")
    assert store.count() == 7


def test_cli_wheel_prints_table_and_json(
    net: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    _publish_growing_flat(net)
    wait_for(lambda: net["store"].count() >= 6, what="diagnoses stored")
    base = ["--connect", net["endpoint"], "--timeout", "5"]
    assert fleet_cli.main(["wheel", "V1/1/left", *base]) == 0
    out = capsys.readouterr().out
    assert "wheel V1/1/left: last verdict inspect, 3 diagnoses at 2 site(s)" in out
    assert "43.0 [42.0-44.0]" in out and "remove 60 mm: predicted" in out
    assert fleet_cli.main(["wheel", "V1/1/left", "--json", *base]) == 0
    assert json.loads(capsys.readouterr().out)["wheel_id"] == "V1/1/left"
    assert fleet_cli.main(["wheel", "V9/1/left", *base]) == fleet_cli.EXIT_UNKNOWN_WHEEL
    assert fleet_cli.main(["wheel", "V1/0/left", *base]) == fleet_cli.EXIT_USAGE
    assert "not a wheel id" in capsys.readouterr().err
    nobody = ["--connect", free_tcp_endpoint(), "--timeout", "0.5"]
    assert fleet_cli.main(["wheel", "V1/1/left", *nobody]) == fleet_cli.EXIT_FAILURE


def test_an_alarm_stored_but_never_published_is_published_on_start(tmp_path: Any) -> None:
    """The alarm table is an outbox: the service was killed after storing an alarm and
    before publishing it; the next start publishes it once, and records that it did."""
    from service.fleet.alarms import apply
    from service.fleet.limits import FleetLimits
    from tests.fleet_support import DAY, T0, make_entry

    store = open_store(str(tmp_path / "fleet.sqlite"))
    store.insert([make_entry("km12", "p0", day=0, verdict="inspect", length=0.045)])
    stored = apply(store, "V1/1/left", FleetLimits.defaults(), horizon=0.5 * DAY, now=T0)
    assert [(a.kind, a.level) for a in stored] == [("verdict_escalated", "inspect")]
    assert len(store.unpublished_alarms()) == 1  # killed here: stored, not published
    endpoint = free_tcp_endpoint()
    with (
        zenoh.open(build_config(listen=[endpoint])) as client_s,
        zenoh.open(build_config(connect=[endpoint])) as fleet_s,
    ):
        got, sub = _listen_for_alarms(client_s, fleet_s)
        for start in range(2):  # the restart, then one more: published once only
            svc = FleetService(fleet_s, store)
            svc.start(catch_up=False)
            try:
                wait_for(
                    lambda s=svc: s.counters.outbox_passes >= 1,  # type: ignore[misc]
                    what="the outbox looked at",
                )
                if start == 0:
                    wait_for(lambda: len(got) == 1, what="the stored alarm published")
                # the put comes before its record in the store: wait for the record, not a
                # moment after the put (a loaded machine showed the gap)
                wait_for(
                    lambda s=svc: (
                        store.unpublished_alarms() == [] and not s.status()["alarms_waiting"]
                    ),  # type: ignore[misc]
                    what="the publication recorded",
                )
                assert store.unpublished_alarms() == []
                status = svc.status()
                assert status["alarms_published_late"] == (1 if start == 0 else 0)
                assert status["alarms_waiting"] is False
            finally:
                svc.stop()
        sub.undeclare()
    doc = json.loads(got[0].payload.to_bytes())
    assert doc["alarm_id"] == stored[0].alarm_id and len(got) == 1
    store.close()


class _FlakyPuts:
    """A session whose first ``fail`` puts fail as a closed Zenoh session's do."""

    def __init__(self, session: zenoh.Session, fail: int) -> None:
        self._session, self.fail, self.tries = session, fail, 0

    def put(self, key: str, payload: str, **kw: Any) -> None:
        self.tries += 1
        if self.tries <= self.fail:
            raise zenoh.ZError("session closed (a test)")
        self._session.put(key, payload, **kw)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._session, name)


def test_alarms_whose_put_fails_wait_and_go_out_in_order_after_a_backoff(
    tmp_path: Any,
) -> None:
    """Puts fail for a while: the alarms raised meanwhile are stored, tried again after a
    backoff, then published oldest first, each once; nothing is lost or reordered."""
    store = open_store(str(tmp_path / "fleet.sqlite"))
    endpoint = free_tcp_endpoint()
    with (
        zenoh.open(build_config(listen=[endpoint])) as client_s,
        zenoh.open(build_config(connect=[endpoint])) as fleet_s,
    ):
        got, sub = _listen_for_alarms(client_s, fleet_s)
        flaky = _FlakyPuts(fleet_s, fail=2)
        svc = FleetService(flaky, store, horizon=0.0, outbox_retry=0.05)  # type: ignore[arg-type]
        entries = [("watch", 0.032), ("inspect", 0.045), ("remove", 0.065)]
        raised = []
        for day, (verdict, length) in enumerate(entries):  # the ingest thread's calls
            body = diagnosis_json(
                "km12", f"p{day}", "V1/1/left", day=day, verdict=verdict, length=length
            )
            raised += svc.ingest([("diagnosis", body.encode(), 0.0)])
        assert [a.level for a in raised] == ["watch", "inspect", "remove"]
        assert flaky.tries <= 2 and len(store.unpublished_alarms()) >= 2
        assert svc.status()["alarms_waiting"] is True
        svc.start(catch_up=False)  # its ingest thread tries again after the backoff
        try:
            wait_for(lambda: len(got) == 3, what="the waiting alarms published")
            wait_for(lambda: not svc.status()["alarms_waiting"], what="the outbox empty")
        finally:
            svc.stop()
        sub.undeclare()
    levels = [json.loads(g.payload.to_bytes())["level"] for g in got]
    assert levels == ["watch", "inspect", "remove"]  # in the order raised, each once
    assert store.unpublished_alarms() == []
    assert svc.counters.alarms == 3 and svc.counters.published_late >= 2
    store.close()
