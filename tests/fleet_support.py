"""Helpers and fixtures of the fleet tests: a real PostgreSQL, stores, diagnoses.

PostgreSQL comes from the ``pgserver`` wheel (a test extra: PostgreSQL 16 binaries,
started in a temporary directory), else from the OS's ``initdb``/``pg_ctl`` (not as
root); a test needing it is skipped, saying so, only when neither can be had.
"""

from __future__ import annotations

import glob
import os
import shutil
import subprocess
import tempfile
import time
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from service.fleet.entry import Entry
from service.fleet.store import Store, open_store


def _os_postgres(tmp: Path) -> tuple[str, subprocess.Popen[bytes] | None] | None:
    bins = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    if not bins or os.geteuid() == 0:
        return None
    bindir = Path(bins[-1]).parent
    data = tmp / "data"
    subprocess.run(
        [str(bindir / "initdb"), "-D", str(data), "-U", "postgres", "--auth=trust"],
        check=True,
        capture_output=True,
    )
    sock = tmp / "sock"
    sock.mkdir()
    subprocess.run(
        [
            str(bindir / "pg_ctl"),
            "-D",
            str(data),
            "-w",
            "-o",
            f"-k {sock} -c listen_addresses=''",
            "start",
        ],
        check=True,
        capture_output=True,
    )
    return f"postgresql://postgres@/postgres?host={sock}", None


@pytest.fixture(scope="session")
def pg_admin_uri() -> Iterator[str]:
    """A URI of a PostgreSQL server started for this test session."""
    tmp = Path(tempfile.mkdtemp(prefix="railtwin-pg-"))
    server: Any = None
    uri: str | None = None
    why = ""
    try:
        import pgserver

        server = pgserver.get_server(str(tmp), cleanup_mode="stop")
        uri = server.get_uri()
    except Exception as exc:  # not installed, or cannot run here
        why = f"pgserver: {type(exc).__name__}: {exc}"
        try:
            found = _os_postgres(tmp)
            uri = found[0] if found else None
        except (OSError, subprocess.CalledProcessError) as exc2:
            why += f"; OS PostgreSQL: {exc2}"
    if uri is None:
        pytest.skip(
            "no PostgreSQL server can be had here (pip install pgserver, or the OS "
            f"package postgresql as a non-root user): {why}"
        )
    try:
        yield uri
    finally:
        if server is not None:
            try:  # a throw-away server: stop it at once (a clean stop checkpoints for ~20 s)
                from pgserver._commands import pg_ctl

                pg_ctl(
                    ["-w", "stop", "-m", "immediate"], pgdata=server.pgdata, user=server.system_user
                )
            except Exception:
                pass
            server.cleanup()
        else:
            for pg_ctl in glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"):
                subprocess.run(
                    [pg_ctl, "-D", str(tmp / "data"), "stop"], check=False, capture_output=True
                )
        shutil.rmtree(tmp, ignore_errors=True)


def fresh_pg_database(admin_uri: str) -> str:
    """A new empty database on the server; its URI."""
    import psycopg

    name = "t_" + uuid.uuid4().hex[:12]
    with psycopg.connect(admin_uri, autocommit=True) as conn:
        conn.execute(f"CREATE DATABASE {name}")
    return admin_uri.replace("/postgres?", f"/{name}?", 1)


@pytest.fixture(params=["sqlite", "postgresql"])
def db_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """A fresh database URL of each kind."""
    if request.param == "sqlite":
        return str(tmp_path / "fleet.sqlite")
    return fresh_pg_database(request.getfixturevalue("pg_admin_uri"))


@pytest.fixture
def store(db_url: str) -> Iterator[Store]:
    s = open_store(db_url)
    try:
        yield s
    finally:
        s.close()


DAY = 86400.0
T0 = 1_790_000_000.0  # 2026-09-21


def make_entry(
    site: str,
    pid: str,
    *,
    wheel: str | None = "V1/1/left",
    day: float = 0.0,
    verdict: str = "ok",
    length: float | None = None,
    half_width: float = 0.002,
    force_line: float | None = None,
) -> Entry:
    """An Entry as a Diagnosis of that wheel would give (no zenoh, no schemas needed)."""
    flat = (
        None
        if length is None
        else {
            "kind": "flat",
            "length": length,
            "depth": length**2 / 16 / 0.46,
            "phase": 1.0,
            "length_low": length - half_width,
            "length_high": length + half_width,
        }
    )
    body = {
        "site_id": site,
        "passage_id": pid,
        "flat": flat,
        "verdict": verdict,
        "reasons": [] if verdict == "ok" else [f"{verdict} reason"],
        "peak_force_measured": 150e3,
        "peak_force_at_line_speed": force_line,
    }
    import json

    vehicle, wheelset, side = wheel.split("/") if wheel else (None, None, None)
    t = T0 + day * DAY
    return Entry(
        site,
        pid,
        wheel,
        vehicle,
        int(wheelset) if wheelset else None,
        side,
        t,
        verdict,
        None if flat is None else "flat",
        length,
        None if flat is None else flat["length_low"],
        None if flat is None else flat["length_high"],
        150e3,
        force_line,
        None,
        None,
        time.time(),
        json.dumps(body),
    )


def diagnosis_json(
    site: str,
    pid: str,
    wheel: str | None,
    *,
    day: float,
    verdict: str = "ok",
    length: float | None = None,
    half_width: float = 0.002,
    force_line: float | None = 250e3,
) -> str:
    """A Diagnosis message (schema 1.1: wheel and timestamp), validated by the model."""
    from schemas.diagnosis import Diagnosis

    flat = (
        None
        if length is None
        else {
            "kind": "flat",
            "length": length,
            "depth": length**2 / 16 / 0.46,
            "phase": 1.0,
            "length_low": max(length - half_width, 0.0),
            "length_high": length + half_width,
        }
    )
    doc: dict[str, Any] = {
        "site_id": site,
        "passage_id": pid,
        "timestamp": T0 + day * DAY,
        "flat": flat,
        "verdict": verdict,
        "reasons": [] if verdict == "ok" else [f"{verdict} by test"],
        "peak_force_measured": 150e3,
        "peak_force_fit": 151e3,
        "fit_rms": 2e3,
        "peak_force_at_line_speed": force_line,
        "wall_time": 0.5,
    }
    if wheel is not None:
        v, ws, side = wheel.split("/")
        doc["wheel"] = {"vehicle_id": v, "wheelset": int(ws), "side": side}
    return Diagnosis.model_validate(doc).model_dump_json()


class FakeTwin:
    """A site twin's fleet-facing side: publishes diagnoses, keeps them in its log and
    answers ``railtwin/<site>/diagnoses?since=T`` (one reply per diagnosis whose passage
    time is >= T, each on its own key), with its liveliness token."""

    def __init__(self, session: Any, site: str) -> None:
        import zenoh

        self.session = session
        self.site = site
        self.log: list[tuple[float, str, str]] = []  # (timestamp, passage_id, json)
        self.queries: list[float] = []
        self._q = session.declare_queryable(f"railtwin/{site}/diagnoses", self._answer)
        self._token = session.liveliness().declare_token(f"railtwin/{site}/alive")
        self._json = zenoh.Encoding.APPLICATION_JSON

    def _answer(self, query: Any) -> None:
        with query:
            since = float(query.parameters.get("since") or 0.0)
            self.queries.append(since)
            for t, pid, text in list(self.log):
                if t >= since:
                    query.reply(f"railtwin/{self.site}/diagnosis/{pid}", text, encoding=self._json)

    def diagnose(self, pid: str, text: str, publish: bool = True) -> None:
        import json

        self.log.append((json.loads(text)["timestamp"], pid, text))
        if publish:
            self.session.put(f"railtwin/{self.site}/diagnosis/{pid}", text, encoding=self._json)

    def close(self) -> None:
        self._token.undeclare()
        self._q.undeclare()


def wait_for(predicate: Any, timeout: float = 20.0, what: str = "condition") -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return
        time.sleep(0.05)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}")
