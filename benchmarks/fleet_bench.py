"""``make fleet-bench``: the fleet service at scale, on SQLite and on PostgreSQL.

    .venv/bin/python -m benchmarks.fleet_bench [--sites 100] [--diagnoses 20000]
        [--rows 1000000] [--wheels 10000] [--skip-postgres] [--out benchmarks/fleet_results.json]

1. Ingest: a Zenoh router (router mode, its own process), the fleet service (``railtwin
   fleet serve --mode client --connect ROUTER --db ...``, its own process) and ``--sites``
   simulated sites (one client session each, in this process) publishing ``--diagnoses``
   Diagnosis messages between them as fast as the router takes them (congestion control
   BLOCK: nothing dropped). Measured: diagnoses stored per second, from the first put to
   the moment the database holds them all (polled every 0.1 s); the fleet's resident
   memory (VmRSS, and its peak VmHWM) after.
2. Query: a database holding ``--rows`` diagnoses of ``--wheels`` wheels (bulk-imported),
   then the history of one wheel: (a) the store's query alone, (b) the whole document
   (history + trends, what the queryable answers), (c) end to end through Zenoh from a
   client to a fleet service serving that database. p50/p99 over random wheels; memory of
   that fleet service.

PostgreSQL comes from the ``pgserver`` wheel (started in a temporary directory). The
figures are wall times on whatever machine runs this (the load average is recorded).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
T0 = 1_790_000_000.0


def _diagnosis(site: str, pid: str, wheel: str, t: float, flat_mm: float | None) -> str:
    v, ws, side = wheel.split("/")
    flat = (
        None
        if flat_mm is None
        else {
            "kind": "flat",
            "length": flat_mm * 1e-3,
            "depth": (flat_mm * 1e-3) ** 2 / 7.36,
            "phase": 1.0,
            "length_low": (flat_mm - 2) * 1e-3,
            "length_high": (flat_mm + 2) * 1e-3,
        }
    )
    verdict = "ok" if flat_mm is None or flat_mm < 30 else "watch" if flat_mm < 40 else "inspect"
    return json.dumps(
        {
            "schema_version": "1.1",
            "site_id": site,
            "passage_id": pid,
            "timestamp": t,
            "wheel": {"vehicle_id": v, "wheelset": int(ws), "side": side},
            "flat": flat,
            "verdict": verdict,
            "reasons": [],
            "peak_force_measured": 152345.6,
            "peak_force_fit": 151234.5,
            "fit_rms": 2345.6,
            "peak_force_at_line_speed": 254321.0,
            "wall_time": 0.8,
        }
    )


def _wheel(k: int) -> str:
    return f"V{k // 8:05d}/{1 + (k % 8) // 2}/{('left', 'right')[k % 2]}"


def _flat(k: int, n: int) -> float | None:
    """Every 50th wheel has a flat growing with its n-th diagnosis."""
    return 20.0 + 0.2 * n if k % 50 == 0 else None


def wait_listening(endpoint: str) -> None:
    from service.cli.fleet_demo import wait_listening as wait

    wait(endpoint)


def _rss(pid: int) -> dict[str, float]:
    out = {}
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(("VmRSS", "VmHWM")):
            out[line.split(":")[0]] = int(line.split()[1]) / 1024.0
    return out


def _pct(xs: list[float], q: float) -> float:
    s = sorted(xs)
    return s[min(len(s) - 1, round(q * (len(s) - 1)))]


@contextmanager
def _proc(
    args: list[str], log: Path, ready: str | None = None, timeout: float = 120.0
) -> Iterator[subprocess.Popen[bytes]]:
    f = log.open("wb")
    p = subprocess.Popen([sys.executable, *args], cwd=ROOT, stdout=f, stderr=subprocess.STDOUT)
    try:
        if ready is not None:
            deadline = time.monotonic() + timeout
            while ready not in log.read_text(errors="replace"):
                if p.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"{args[:3]} not ready:\n{log.read_text()[-3000:]}")
                time.sleep(0.1)
        yield p
    finally:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
        f.close()


@contextmanager
def _wait_router(endpoint: str) -> Iterator[None]:
    wait_listening(endpoint)
    yield


@contextmanager
def _postgres(tmp: Path) -> Iterator[Callable[[], str]]:
    import pgserver
    import psycopg

    server = pgserver.get_server(str(tmp / "pg"), cleanup_mode="stop")
    admin = server.get_uri()
    n = [0]

    def fresh() -> str:
        n[0] += 1
        with psycopg.connect(admin, autocommit=True) as c:
            c.execute(f"CREATE DATABASE bench{n[0]}")
        return str(admin.replace("/postgres?", f"/bench{n[0]}?", 1))

    try:
        yield fresh
    finally:
        server.cleanup()


def bench_ingest(db: str, sites: int, diagnoses: int, tmp: Path, label: str) -> dict[str, Any]:
    import zenoh

    from service.cli.fleet_demo import router_command
    from service.fleet.store import open_store
    from service.wire.zenoh_session import build_config, free_tcp_endpoint

    router = free_tcp_endpoint()
    payloads: list[tuple[int, str, str]] = []
    per_site = diagnoses // sites
    for j in range(per_site):
        for i in range(sites):
            k = (i * 997 + j * 31) % 20_000
            pid = f"p{j:06d}"
            site = f"s{i:03d}"
            payloads.append(
                (
                    i,
                    f"railtwin/{site}/diagnosis/{pid}",
                    _diagnosis(site, pid, _wheel(k), T0 + j * 600.0 + i, _flat(k, j)),
                )
            )
    n = len(payloads)
    with (
        _proc(router_command(router), tmp / f"router-{label}.log"),
        _wait_router(router),
        _proc(
            [
                "-m",
                "service.cli.fleet",
                "serve",
                "--mode",
                "client",
                "--connect",
                router,
                "--db",
                db,
                "--no-catch-up",
            ],
            tmp / f"fleet-{label}.log",
            ready="fleet: ready",
        ) as fleet,
    ):
        sessions = [zenoh.open(build_config(connect=[router], mode="client")) for _ in range(sites)]
        try:
            pubs: dict[str, Any] = {}
            for i, key, _ in payloads[:sites]:  # one per site, to see the fleet matched
                pubs[key] = sessions[i].declare_publisher(key)
            deadline = time.monotonic() + 30
            while not all(p.matching_status.matching for p in pubs.values()):
                if time.monotonic() > deadline:
                    raise RuntimeError("the fleet's subscriber is not matched")
                time.sleep(0.05)
            reader = open_store(db, migrate=False)
            t0 = time.perf_counter()
            for i, key, text in payloads:
                sessions[i].put(key, text, congestion_control=zenoh.CongestionControl.BLOCK)
            t_pub = time.perf_counter() - t0
            count = 0
            deadline = time.monotonic() + 600
            while count < n and time.monotonic() < deadline:
                time.sleep(0.1)
                count = reader.count()
            elapsed = time.perf_counter() - t0
            mem = _rss(fleet.pid)
            reader.close()
        finally:
            for s in sessions:
                s.close()
    return {
        "db": label,
        "sites": sites,
        "diagnoses": n,
        "stored": count,
        "published_per_s": n / t_pub,
        "stored_per_s": count / elapsed,
        "seconds": elapsed,
        "fleet_rss_mb": mem.get("VmRSS"),
        "fleet_peak_rss_mb": mem.get("VmHWM"),
    }


def bench_query(
    db: str, rows: int, wheels: int, tmp: Path, label: str, samples: int = 500
) -> dict[str, Any]:
    import zenoh

    from service.fleet.entry import entry_from_payload
    from service.fleet.history import wheel_document
    from service.fleet.limits import FleetLimits
    from service.fleet.store import open_store
    from service.wire.zenoh_session import build_config, free_tcp_endpoint

    store = open_store(db)
    per_wheel = rows // wheels
    t_load = time.perf_counter()
    chunk = 50_000
    template = entry_from_payload(_diagnosis("s000", "x", _wheel(0), T0, 25.0), T0)
    made = 0
    while made < rows:
        batch = []
        for r in range(made, min(rows, made + chunk)):
            k, n = r % wheels, r // wheels
            flat = _flat(k, n)
            w = _wheel(k)
            v, ws, side = w.split("/")
            batch.append(
                template.__class__(
                    f"s{k % 100:03d}",
                    f"p{r:08d}",
                    w,
                    v,
                    int(ws),
                    side,
                    T0 + n * 3600.0 + k,
                    "ok" if flat is None else "watch",
                    None if flat is None else "flat",
                    None if flat is None else flat * 1e-3,
                    None if flat is None else (flat - 2) * 1e-3,
                    None if flat is None else (flat + 2) * 1e-3,
                    152345.6,
                    254321.0,
                    30.0,
                    None,
                    T0,
                    template.body,
                )
            )
        store.bulk_insert(batch)
        made += len(batch)
    t_load = time.perf_counter() - t_load
    assert store.count() == rows
    rng = random.Random(1)
    limits = FleetLimits.defaults()
    hist_t, doc_t = [], []
    for _ in range(samples):
        w = _wheel(rng.randrange(wheels))
        t = time.perf_counter()
        h = store.history(w)
        hist_t.append(time.perf_counter() - t)
        assert len(h) == per_wheel
        t = time.perf_counter()
        wheel_document(w, store.history(w), limits)
        doc_t.append(time.perf_counter() - t)
    flat_wheel = _wheel(0)  # a wheel with a flat: its trend is fitted
    store.close()
    router = free_tcp_endpoint()
    zen_t: list[float] = []
    with (
        _proc(
            ["-m", "service.cli.fleet", "serve", "--listen", router, "--db", db, "--no-catch-up"],
            tmp / f"fleet-query-{label}.log",
            ready="fleet: ready",
        ) as fleet,
        zenoh.open(build_config(connect=[router])) as client,
    ):
        for i in range(samples + 20):
            w = flat_wheel if i % 10 == 0 else _wheel(rng.randrange(wheels))
            t = time.perf_counter()
            replies = [
                r for r in client.get(f"railtwin/fleet/wheel/{w}", timeout=10.0) if r.ok is not None
            ]
            dt = time.perf_counter() - t
            assert len(replies) == 1, w
            if i >= 20:  # the first ones warm the route up
                zen_t.append(dt)
        mem = _rss(fleet.pid)
    ms = 1e3
    return {
        "db": label,
        "rows": rows,
        "wheels": wheels,
        "per_wheel": per_wheel,
        "load_seconds": t_load,
        "history_p50_ms": _pct(hist_t, 0.5) * ms,
        "history_p99_ms": _pct(hist_t, 0.99) * ms,
        "document_p50_ms": _pct(doc_t, 0.5) * ms,
        "document_p99_ms": _pct(doc_t, 0.99) * ms,
        "zenoh_p50_ms": _pct(zen_t, 0.5) * ms,
        "zenoh_p99_ms": _pct(zen_t, 0.99) * ms,
        "fleet_rss_mb": mem.get("VmRSS"),
        "fleet_peak_rss_mb": mem.get("VmHWM"),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.fleet_bench", description=__doc__.split("\n")[0]
    )
    p.add_argument("--sites", type=int, default=100)
    p.add_argument("--diagnoses", type=int, default=20_000)
    p.add_argument("--rows", type=int, default=1_000_000)
    p.add_argument("--wheels", type=int, default=10_000)
    p.add_argument("--skip-postgres", action="store_true")
    p.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "fleet_results.json")
    a = p.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="railtwin-fleet-bench-"))
    results: dict[str, Any] = {"load_before": os.getloadavg(), "ingest": [], "query": []}
    try:
        kinds: list[tuple[str, Callable[[], str]]] = [
            ("sqlite", lambda: str(tmp / f"fleet-{time.monotonic_ns()}.sqlite"))
        ]
        with _postgres(tmp) if not a.skip_postgres else _nullpg() as fresh_pg:
            if fresh_pg is not None:
                kinds.append(("postgresql", fresh_pg))
            for label, make in kinds:
                r = bench_ingest(make(), a.sites, a.diagnoses, tmp, label)
                results["ingest"].append(r)
                print(
                    f"ingest  {label:<10} {r['stored']}/{r['diagnoses']} diagnoses from "
                    f"{r['sites']} sites: {r['stored_per_s']:.0f} stored/s (published "
                    f"{r['published_per_s']:.0f}/s); fleet RSS {r['fleet_rss_mb']:.0f} MB "
                    f"(peak {r['fleet_peak_rss_mb']:.0f})",
                    flush=True,
                )
            for label, make in kinds:
                q = bench_query(make(), a.rows, a.wheels, tmp, label)
                results["query"].append(q)
                print(
                    f"query   {label:<10} {q['rows']} rows, {q['per_wheel']} per wheel (loaded "
                    f"in {q['load_seconds']:.0f} s): history p50 {q['history_p50_ms']:.2f} ms "
                    f"p99 {q['history_p99_ms']:.2f} ms; document p99 "
                    f"{q['document_p99_ms']:.2f} ms; through Zenoh p50 "
                    f"{q['zenoh_p50_ms']:.2f} ms p99 {q['zenoh_p99_ms']:.2f} ms; fleet RSS "
                    f"{q['fleet_rss_mb']:.0f} MB",
                    flush=True,
                )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    results["load_after"] = os.getloadavg()
    a.out.write_text(json.dumps(results, indent=1), encoding="utf-8")
    print(f"wrote {a.out}")
    return 0


@contextmanager
def _nullpg() -> Iterator[None]:
    yield None


if __name__ == "__main__":
    sys.exit(main())
