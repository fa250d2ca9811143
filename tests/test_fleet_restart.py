"""Nothing lost when the fleet is down: kill -9, two wheels diagnosed meanwhile, restart:
both in the history (caught up from the twin), nothing stored twice."""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import zenoh

from service.wire.zenoh_session import build_config, free_tcp_endpoint
from tests.conftest import ROOT
from tests.fleet_support import T0, FakeTwin, diagnosis_json, wait_for


def _start_fleet(endpoint: str, db: Path, log: Path) -> subprocess.Popen[bytes]:
    out = log.open("ab")
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "service.cli.fleet",
            "serve",
            "--connect",
            endpoint,
            "--db",
            str(db),
        ],
        cwd=ROOT,
        stdout=out,
        stderr=subprocess.STDOUT,
    )
    wait_for(
        lambda: b"fleet: ready" in log.read_bytes().split(b"KILLED")[-1] or proc.poll() is not None,
        timeout=60,
        what="the fleet service to be ready",
    )
    assert proc.poll() is None, log.read_text()
    return proc


def _history(client: zenoh.Session, wheel: str) -> list[str]:
    for r in client.get(f"railtwin/fleet/wheel/{wheel}", timeout=3.0):
        if r.ok is not None:
            return [h["passage_id"] for h in json.loads(r.ok.payload.to_bytes())["history"]]
    return []


def test_kill_9_and_restart_loses_nothing(tmp_path: Path) -> None:
    endpoint = free_tcp_endpoint()
    db, log = tmp_path / "fleet.sqlite", tmp_path / "fleet.log"
    with (
        zenoh.open(build_config(listen=[endpoint])) as twin_s,
        zenoh.open(build_config(connect=[endpoint])) as client,
    ):
        twin = FakeTwin(twin_s, "km12")
        fleet = _start_fleet(endpoint, db, log)
        try:
            twin.diagnose(
                "p1",
                diagnosis_json("km12", "p1", "V1/1/left", day=0, verdict="watch", length=0.032),
            )
            wait_for(lambda: _history(client, "V1/1/left") == ["p1"], what="p1 stored")
            fleet.send_signal(signal.SIGKILL)
            fleet.wait(timeout=10)
            with log.open("ab") as f:
                f.write(b"\nKILLED\n")
            # while the fleet is down the site diagnoses two wheels (nobody hears them)
            twin.diagnose(
                "p2",
                diagnosis_json("km12", "p2", "V1/1/left", day=1, verdict="inspect", length=0.041),
            )
            twin.diagnose("p3", diagnosis_json("km12", "p3", "V2/4/right", day=1))
            time.sleep(0.2)
            fleet = _start_fleet(endpoint, db, log)
            wait_for(lambda: _history(client, "V2/4/right") == ["p3"], what="p3 caught up")
            assert _history(client, "V1/1/left") == ["p1", "p2"]
            # after the restart it asked from before p1 (margin): p1 came again, not stored twice
            assert any(0 < q <= T0 for q in twin.queries), twin.queries
        finally:
            fleet.send_signal(signal.SIGTERM)
            assert fleet.wait(timeout=20) == 0, log.read_text()
            twin.close()
    with sqlite3.connect(db) as conn:
        rows = conn.execute("SELECT site_id, passage_id FROM diagnosis ORDER BY passage_id")
        assert rows.fetchall() == [("km12", "p1"), ("km12", "p2"), ("km12", "p3")]
        # each escalation of V1/1/left raised once (inspect after the restart), and the
        # 9 mm/day growth's forecast of the remove limit
        alarms = conn.execute("SELECT wheel_id, kind, level FROM alarm").fetchall()
        assert sorted(alarms) == [
            ("V1/1/left", "forecast_flat_length", "remove"),
            ("V1/1/left", "verdict_escalated", "inspect"),
            ("V1/1/left", "verdict_escalated", "watch"),
        ]
    assert os.path.getsize(db) > 0
