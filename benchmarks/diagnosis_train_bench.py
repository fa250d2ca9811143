"""Benchmark the diagnosis in the service: a 100-wheel train with 5 flat wheels.

    .venv/bin/python benchmarks/diagnosis_train_bench.py [--wheels 100] [--workers 2]
        [--kmh 120] [--site examples/site_compliant.toml]

Generates the site's measurement of every wheel first (the project's generator: 2 % noise,
3 µm unknown roughness, foundation damping ratio 0.15; 5 wheels carry flats of both kinds,
30-80 mm), then starts ``railtwin serve --workers N --no-mcap --no-rerun`` and drives it
over loopback Zenoh as a site would: each ``WheelPassage`` when its axle reaches the site,
each ``MeasuredPassage`` when its wheel leaves it (cars of 26.4 m, bogies of 2.5 m, both
wheels of an axle). Reports the time from the LAST measurement sent to the last verdict
received (the issue's target: within 10 s with 2 workers), and each wheel's time from its
measurement to its verdict (round and flat wheels apart). Asserts nothing (timings depend on
the machine and its load).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import zenoh  # noqa: E402

from schemas.diagnosis import Diagnosis, MeasuredPassage  # noqa: E402
from schemas.messages import ServiceError, WheelPassage  # noqa: E402
from service.cli.service_process import ServiceProcess  # noqa: E402
from service.clients.feeder import (  # noqa: E402
    Collector,
    declare_passage_publisher,
    send_train,
    wait_matching,
)
from service.clients.synthesize import measure  # noqa: E402
from service.physics.diagnosis import Diagnoser  # noqa: E402
from service.wire.encoding import json_encoding  # noqa: E402
from service.wire.keyspace import SiteKeys  # noqa: E402
from service.wire.site import load_site  # noqa: E402
from service.wire.zenoh_session import build_config, free_tcp_endpoint, open_session  # noqa: E402
from sim_core.diagnosis.forward import Flat  # noqa: E402

AXLES_IN_CAR = (3.7, 6.2, 22.7, 25.2)
CAR_LENGTH = 26.4
FLATS = {
    7: ("flat", 0.04),
    29: ("rounded_flat", 0.07),
    48: ("flat", 0.08),
    66: ("rounded_flat", 0.03),
    91: ("flat", 0.06),
}
"""Wheel index → the flat it carries (the others are round)."""


def train(n: int, speed: float, prefix: str) -> list[tuple[float, WheelPassage]]:
    """``n`` wheels (both of each axle) with the offsets (s) at which their axle arrives."""
    out = []
    for i in range(n):
        axle, side = divmod(i, 2)
        car, j = divmod(axle, len(AXLES_IN_CAR))
        x = car * CAR_LENGTH + AXLES_IN_CAR[j] - AXLES_IN_CAR[0]
        out.append(
            (
                x / speed,
                WheelPassage(
                    passage_id=f"{prefix}-a{axle:03d}-{'lr'[side]}",
                    train_id=prefix,
                    axle_index=axle,
                    side=("left", "right")[side],
                    timestamp=0.0,
                    speed=speed,
                    load=60000.0 + 2000.0 * ((i * 7) % 5),
                    mass=600.0,
                    radius=0.46,
                ),
            )
        )
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--wheels", type=int, default=100)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--kmh", type=float, default=120.0)
    p.add_argument("--site", type=Path, default=ROOT / "examples/site_compliant.toml")
    p.add_argument("--timeout", type=float, default=300.0)
    a = p.parse_args(argv)
    site = load_site(a.site)
    keys = SiteKeys(site.site_id)
    speed = a.kmh / 3.6
    wheels = train(a.wheels, speed, "bench")
    warm = train(2, speed, "warm")
    d = Diagnoser(site)
    t0 = time.monotonic()
    measured: dict[str, MeasuredPassage] = {}
    for i, (_, w) in enumerate(warm + wheels):
        idx = i - len(warm)
        tread = None
        if idx in FLATS:
            kind, ln = FLATS[idx]
            tread = (
                Flat.ideal(w.radius, ln, 1.0 + idx)
                if kind == "flat"
                else Flat.rounded(w.radius, ln, None, 1.0 + idx)
            )
        m = measure(
            site,
            w,
            tread,
            seed=500 + i,
            noise=0.02,
            roughness=3e-6,
            damping_ratio=0.15,
            diagnoser=d,
        )
        measured[w.passage_id] = MeasuredPassage(
            passage_id=w.passage_id,
            sample_rate=m.sample_rate,
            t_start=m.t_start,
            force=m.force.tolist(),
            speed=w.speed,
        )
    print(
        f"generated {len(measured)} measurements in {time.monotonic() - t0:.0f} s", file=sys.stderr
    )
    got: dict[str, tuple[float, Diagnosis | None]] = {}
    lock = threading.Lock()
    all_in = threading.Event()

    def on_output(sample: zenoh.Sample) -> None:
        kind = keys.kind_of(str(sample.key_expr))
        data = sample.payload.to_bytes()
        now = time.monotonic()
        with lock:
            if kind == "diagnosis":
                dg = Diagnosis.model_validate_json(data)
                got.setdefault(dg.passage_id, (now, dg))
            elif kind == "error":
                e = ServiceError.model_validate_json(data)
                if e.passage_id is not None and e.passage_id in measured:
                    print(f"error {e.passage_id}: {e.kind}: {e.message}", file=sys.stderr)
                    got.setdefault(e.passage_id, (now, None))
            if all(w.passage_id in got for _, w in wheels):
                all_in.set()

    def run(ws: list[tuple[float, WheelPassage]]) -> tuple[dict[str, float], float]:
        with open_session(build_config(connect=[endpoint])) as session:
            collector = Collector(keys)
            sub_results = session.declare_subscriber(keys.all_outputs, collector)
            sub = session.declare_subscriber(keys.all_outputs, on_output)
            ppub = declare_passage_publisher(session, keys)
            mpub = session.declare_publisher(
                keys.measured,
                encoding=json_encoding(MeasuredPassage),
                congestion_control=zenoh.CongestionControl.BLOCK,
            )
            if not wait_matching(ppub, 20.0) or not wait_matching(mpub, 20.0):
                raise SystemExit(f"no service at {endpoint}")
            sent: dict[str, float] = {}
            feeder = threading.Thread(target=send_train, args=(ppub, collector, ws), daemon=True)
            start = time.monotonic()
            feeder.start()
            for offset, w in sorted(ws, key=lambda ow: ow[0]):
                delay = start + offset + site.length / w.speed - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
                sent[w.passage_id] = time.monotonic()
                mpub.put(measured[w.passage_id].model_dump_json().encode())
            last_sent = time.monotonic()
            feeder.join()
            ids = [w.passage_id for _, w in ws]
            deadline = time.monotonic() + a.timeout
            while time.monotonic() < deadline and not all(i in got for i in ids):
                time.sleep(0.01)
            sub.undeclare()
            sub_results.undeclare()
        return sent, last_sent

    with tempfile.TemporaryDirectory(prefix="railtwin-diag-bench-") as tmp:
        endpoint = free_tcp_endpoint()
        with ServiceProcess(
            a.site,
            listen=endpoint,
            recordings=Path(tmp) / "rec",
            extra_args=("--workers", str(a.workers), "--no-mcap", "--no-rerun"),
        ):
            run(warm)  # compile caches and tables in the workers
            with lock:
                got.clear()
            sent, last_sent = run(wheels)
    missing = [w.passage_id for _, w in wheels if w.passage_id not in got]
    lat_round, lat_flat = [], []
    for i, (_, w) in enumerate(wheels):
        if w.passage_id in got:
            dt = got[w.passage_id][0] - sent[w.passage_id]
            (lat_flat if i in FLATS else lat_round).append(dt)
    last_verdict = max(t for t, _ in got.values()) if got else last_sent
    print(
        f"\ndiagnosis train benchmark: {a.wheels} wheels ({len(FLATS)} flat) at "
        f"{a.kmh:g} km/h, {a.workers} workers, site {site.site_id!r}\n"
    )
    print(
        f"- last verdict {last_verdict - last_sent:.2f} s after the last measurement "
        f"(target <= 10 s); train {max(sent.values()) - min(sent.values()):.1f} s long"
    )
    if lat_round:
        print(
            f"- round wheels: measurement -> verdict median {statistics.median(lat_round):.2f} s,"
            f" max {max(lat_round):.2f} s"
        )
    if lat_flat:
        print(
            f"- flat wheels: measurement -> verdict median {statistics.median(lat_flat):.2f} s,"
            f" max {max(lat_flat):.2f} s"
        )
    for i in sorted(FLATS):
        if i < len(wheels):
            pid = wheels[i][1].passage_id
            dg = got.get(pid, (0.0, None))[1]
            if dg is not None:
                print(
                    f"  {pid}: true {FLATS[i][0]} {FLATS[i][1] * 1e3:.0f} mm -> "
                    f"{dg.flat.kind if dg.flat else 'none'} "
                    f"{dg.flat.length * 1e3 if dg.flat else 0:.1f} mm, {dg.verdict}, "
                    f"diagnosis wall {dg.wall_time:.2f} s"
                )
    if missing:
        print(f"- missing verdicts: {len(missing)} ({missing[:5]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
