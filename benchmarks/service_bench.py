"""Benchmark the streaming twin: latency and throughput over loopback Zenoh, recording on.

    .venv/bin/python benchmarks/service_bench.py [--wheels 200] [--site examples/site_compliant.toml]

Starts ``railtwin serve`` in its own process (MCAP and Rerun on, unless
``--no-recording``), then drives it from this process:

1. **train**: a ``--wheels``-wheel train at 160 km/h, each passage sent when
   its axle reaches the site (cars of 26.4 m, bogies of 2.5 m): latency from
   sending a passage to receiving its result (p50/p99/max), and whether every
   result came before the wheel left the site (length / speed);
2. **flood**: the same passages sent at once: sustained passages per second
   (first send to last result) and the latency under that backlog;
3. **flood, no recording**: the same against a second service with
   ``--no-mcap --no-rerun``, to show what recording costs, once per
   ``--workers`` count (default 1 and 2 physics worker processes: an elastic
   site's passages are independent and may be simulated in parallel).

Prints a table; asserts nothing (timings depend on the machine).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from schemas.messages import WheelPassage  # noqa: E402
from service.cli.service_process import ServiceProcess  # noqa: E402
from service.clients.feeder import (  # noqa: E402
    Collector,
    declare_passage_publisher,
    send_train,
    wait_matching,
)
from service.wire.keyspace import SiteKeys  # noqa: E402
from service.wire.site import load_site  # noqa: E402
from service.wire.zenoh_session import build_config, free_tcp_endpoint, open_session  # noqa: E402

SPEED = 160.0 / 3.6
AXLES_IN_CAR = (3.7, 6.2, 22.7, 25.2)
CAR_LENGTH = 26.4
RADII = (0.4585, 0.452, 0.445, 0.438)


def train(n: int, prefix: str) -> list[tuple[float, WheelPassage]]:
    """``n`` round wheels at 160 km/h with their arrival offsets (s)."""
    out = []
    for i in range(n):
        car, j = divmod(i, len(AXLES_IN_CAR))
        x = car * CAR_LENGTH + AXLES_IN_CAR[j] - AXLES_IN_CAR[0]
        out.append(
            (
                x / SPEED,
                WheelPassage(
                    passage_id=f"{prefix}-a{i:03d}",
                    train_id=prefix,
                    axle_index=i,
                    side="right",
                    timestamp=0.0,
                    speed=SPEED,
                    load=52000.0 + 2000.0 * ((i * 7) % 5),
                    mass=600.0,
                    radius=RADII[car % len(RADII)],
                ),
            )
        )
    return out


@dataclass
class Phase:
    name: str
    sent: int
    served: int
    errors: int
    latencies: list[float]
    span: float
    sim_times: list[float]
    on_time: int | None = None

    def row(self) -> str:
        lat = sorted(self.latencies)
        p50 = statistics.median(lat) * 1e3 if lat else float("nan")
        p99 = lat[min(len(lat) - 1, round(0.99 * (len(lat) - 1)))] * 1e3 if lat else float("nan")
        mx = lat[-1] * 1e3 if lat else float("nan")
        rate = self.served / self.span if self.span > 0 else float("nan")
        sim = statistics.median(self.sim_times) * 1e3 if self.sim_times else float("nan")
        on_time = "" if self.on_time is None else f"{self.on_time}/{self.served}"
        return (
            f"| {self.name:<33} | {self.served:>3}/{self.sent:<3} | {p50:8.2f} | {p99:8.2f} | "
            f"{mx:8.2f} | {rate:8.1f} | {sim:6.2f} | {on_time:>9} |"
        )


def run_phase(
    endpoint: str,
    keys: SiteKeys,
    name: str,
    wheels: list[tuple[float, WheelPassage]],
    *,
    flood: bool,
    site_length: float,
    timeout: float,
) -> Phase:
    with open_session(build_config(connect=[endpoint])) as session:
        collector = Collector(keys)
        sub = session.declare_subscriber(keys.all_outputs, collector)
        pub = declare_passage_publisher(session, keys)
        if not wait_matching(pub, 20.0):
            raise SystemExit(f"no service at {endpoint}")
        start = time.monotonic()
        ids = send_train(pub, collector, wheels, flood=flood)
        collector.wait(ids, timeout)
        sub.undeclare()
        pub.undeclare()
    outcomes = [collector.outcomes[i] for i in ids]
    done = [o for o in outcomes if o.result is not None]
    last = max((o.result_at for o in done if o.result_at is not None), default=start)
    on_time = sum(1 for o in done if (o.latency or 0.0) < site_length / SPEED)
    return Phase(
        name=name,
        sent=len(ids),
        served=len(done),
        errors=len(collector.errors),
        latencies=[o.latency for o in done if o.latency is not None],
        span=last - start,
        sim_times=[o.result.wall_time for o in done if o.result is not None],
        on_time=None if flood else on_time,
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--wheels", type=int, default=200)
    p.add_argument("--site", type=Path, default=ROOT / "examples/site_compliant.toml")
    p.add_argument(
        "--physics",
        choices=("sim_core", "stub"),
        default="sim_core",
        help="stub: the service's own overhead, without physics",
    )
    p.add_argument("--skip-train", action="store_true", help="only the flood phases")
    p.add_argument("--timeout", type=float, default=120.0)
    p.add_argument(
        "--workers",
        type=int,
        nargs="+",
        default=[1, 2],
        metavar="N",
        help="physics worker counts of the no-recording flood (default: 1 2)",
    )
    args = p.parse_args(argv)
    if any(n < 1 for n in args.workers):
        p.error("--workers: each count must be >= 1")
    site = load_site(args.site)
    keys = SiteKeys(site.site_id)
    rows: list[Phase] = []
    with tempfile.TemporaryDirectory(prefix="railtwin-bench-") as tmp:
        runs = [(True, 1)] + [(False, n) for n in args.workers]
        for recording, workers in runs:
            endpoint = free_tcp_endpoint()
            extra = ["--physics", args.physics, "--workers", str(workers)]
            if not recording:
                extra += ["--no-mcap", "--no-rerun"]
            with ServiceProcess(
                args.site, listen=endpoint, recordings=Path(tmp) / "rec", extra_args=tuple(extra)
            ) as svc:
                label = (
                    "MCAP+Rerun on"
                    if recording
                    else f"no recording, {workers} worker" + ("s" if workers > 1 else "")
                )
                # warm up: compile caches, the constraint tables of each radius
                run_phase(
                    endpoint,
                    keys,
                    "warm-up",
                    train(8, "warm"),
                    flood=True,
                    site_length=site.length,
                    timeout=args.timeout,
                )
                if recording and not args.skip_train:
                    rows.append(
                        run_phase(
                            endpoint,
                            keys,
                            f"train, real timing, {label}",
                            train(args.wheels, "rt"),
                            flood=False,
                            site_length=site.length,
                            timeout=args.timeout,
                        )
                    )
                rows.append(
                    run_phase(
                        endpoint,
                        keys,
                        f"flood, {label}",
                        train(args.wheels, "fl" + ("r" if recording else f"n{workers}")),
                        flood=True,
                        site_length=site.length,
                        timeout=args.timeout,
                    )
                )
            if svc.returncode != 0:
                print(svc.output, file=sys.stderr)
    print(
        f"\nrailtwin service benchmark: site {site.site_id!r} ({site.length:g} m, "
        f"{site.contact}, "
        f"{site.output_sample_rate:g} Hz output), {args.wheels} wheels at 160 km/h, "
        f"physics {args.physics}; wheel on the site for {site.length / SPEED * 1e3:.0f} ms\n"
    )
    print(
        "| phase                             | served  | p50 [ms] | p99 [ms] | max [ms] | pass./s  "
        "| sim ms | on time   |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(r.row())
    print(
        "\nlatency: passage sent → its result received (same process, monotonic clock); "
        "pass./s: passages served / (first send → last result); sim ms: median simulation "
        "wall time in the service; on time: results received before the wheel left the site."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
