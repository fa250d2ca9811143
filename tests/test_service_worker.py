"""Never deaf (issue 8, item 2): the physics runs in a worker process.

- A plastic site's rail survives a worker killed for overrunning its budget.
- During a long passage the service answers health queries at once, aborts the
  passage at its wall-time budget with ``simulation_failed`` naming the budget,
  serves the next passage, and stops on SIGTERM within the budget.
"""

from __future__ import annotations

import json
import math
import statistics
import threading
import time
from pathlib import Path
from typing import Any

import pytest
import zenoh

from schemas.messages import Health, PassageResult, ServiceError, WheelPassage
from schemas.scenario import FlatOutline
from schemas.site import SiteConfig
from service.cli.service_process import ServiceProcess
from service.clients.feeder import declare_passage_publisher, wait_matching
from service.physics.worker import BudgetExceededError, ProcessPhysics
from service.wire.keyspace import SiteKeys
from service.wire.limits import passage_samples
from service.wire.zenoh_session import build_config, free_tcp_endpoint

PLASTIC = SiteConfig.model_validate(
    {
        "site_id": "plastic",
        "length": 3.0,
        "output_sample_rate": 5000.0,
        "contact": "hertz_plastic",
        "rtol": 1e-8,
        "rail": {"kind": "cosine", "amplitude": 2e-6, "wavelength": 0.06},
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3, "yield_stress": 6e8},
    }
)
WHEEL = WheelPassage(
    passage_id="w0",
    train_id="t1",
    axle_index=0,
    side="right",
    timestamp=1.7e9,
    speed=44.4,
    load=60e3,
    mass=500.0,
    radius=0.46,
)
BUDGET = 2.0
START_TIMEOUT = 300.0
"""s a service may take to start: its workers compile when numba's cache is cold."""
SLOW_SITE = """
site_id = "slow"
length = 60.0
output_sample_rate = 1000.0
contact = "hertz"
[rail]
kind = "file"
path = "rail.csv"
[material]
youngs_modulus = 2.14e11
poisson_ratio = 0.3
"""


def test_plastic_rail_survives_a_worker_killed_for_its_budget() -> None:
    flat = WHEEL.model_copy(
        update={
            "passage_id": "flat",
            "outline": FlatOutline(kind="flat", length=0.05),
            "phase": (-0.8 / WHEEL.radius) % math.tau,
        }
    )
    physics = ProcessPhysics(PLASTIC, budget=60.0, warm_up=False)
    physics.start()
    try:
        dented = physics.simulate(flat)
        assert dented.summary.max_dent > 0.0
        state = physics.rail_state()
        assert state.revision == 1 and state.passages_done == 1
        first_pid = physics.pid
        physics.budget = 1e-4
        with pytest.raises(BudgetExceededError, match=r"budget of 0\.0001 s"):
            physics.simulate(WHEEL)
        physics.budget = 60.0
        assert physics.rail_state().revision == 1  # answered while the worker is down
        again = physics.simulate(WHEEL.model_copy(update={"passage_id": "w1"}))
        assert physics.pid != first_pid and physics.restarts == 1
        assert again.rail_revision == 1  # the new worker rolls on the dented rail
        assert physics.rail_state().max_dent >= state.max_dent
    finally:
        physics.close()


def write_slow_site(directory: Path) -> Path:
    """A 60 m site on a measured (sampled, 1 mm) rail: no fast constraint sweep applies."""
    n = 60_201
    rows = [
        f"{-0.1 + i * 1e-3:.4f},{2e-6 * math.cos(2 * math.pi * i * 1e-3 / 0.06) + 1e-7 * ((i * 7919) % 13 - 6) / 6:.4e}"
        for i in range(n)
    ]
    (directory / "rail.csv").write_text("x,y\n" + "\n".join(rows) + "\n")
    site = directory / "slow.toml"
    site.write_text(SLOW_SITE)
    return site


def slow_wheel(pid: str) -> dict[str, Any]:
    """A wheel with a 4 096-point measured outline: seconds over the slow site (tabulation)."""
    n = 4096
    theta = [2 * math.pi * i / n for i in range(n)]
    radius = [0.46 + 1e-5 * math.sin(5 * t) for t in theta]
    return {
        **json.loads(WHEEL.model_dump_json()),
        "passage_id": pid,
        "outline": {"kind": "sampled", "theta": theta, "radius": radius},
    }


class Prober:
    """Queries the site's health every 20 ms, keeping each answer's latency."""

    def __init__(self, session: zenoh.Session, key: str) -> None:
        self.session, self.key = session, key
        self.latencies: list[float] = []
        self.missed = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> Prober:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while not self._stop.is_set():
            start = time.monotonic()
            ok = [r for r in self.session.get(self.key, timeout=2.0) if r.ok is not None]
            if ok:
                Health.model_validate_json(ok[0].ok.payload.to_bytes())  # type: ignore[union-attr]
                self.latencies.append(time.monotonic() - start)
            else:
                self.missed += 1
            time.sleep(0.02)


def test_never_deaf_budget_and_sigterm(tmp_path: Path) -> None:
    site = write_slow_site(tmp_path)
    keys = SiteKeys("slow")
    endpoint = free_tcp_endpoint()
    results: dict[str, PassageResult] = {}
    errors: list[ServiceError] = []

    def on_output(sample: zenoh.Sample) -> None:
        kind = keys.kind_of(str(sample.key_expr))
        if kind == "result":
            r = PassageResult.model_validate_json(sample.payload.to_bytes())
            results[r.passage_id] = r
        elif kind == "error":
            errors.append(ServiceError.model_validate_json(sample.payload.to_bytes()))

    def wait(cond: Any, timeout: float = 60.0) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not cond():
            time.sleep(0.01)
        return bool(cond())

    svc = ServiceProcess(
        site,
        listen=endpoint,
        recordings=tmp_path / "rec",
        extra_args=("--passage-budget", str(BUDGET), "--no-rerun"),
        start_timeout=START_TIMEOUT,
    )
    with svc, zenoh.open(build_config(connect=[endpoint])) as session:
        sub = session.declare_subscriber(keys.all_outputs, on_output)
        pub = declare_passage_publisher(session, keys)
        assert wait_matching(pub, 20.0)
        with Prober(session, keys.health) as prober:
            time.sleep(0.2)
            sent = time.monotonic()
            pub.put(json.dumps(slow_wheel("runaway")))
            pub.put(WHEEL.model_dump_json())
            assert wait(lambda: "w0" in results), svc.output
            took = time.monotonic() - sent
        (err,) = errors
        assert (err.kind, err.passage_id) == ("simulation_failed", "runaway")
        assert f"budget of {BUDGET:g} s" in err.message
        assert took >= BUDGET
        during = prober.latencies
        print(
            f"\nhealth during a {took:.1f} s runaway passage: {len(during)} answers, "
            f"median {statistics.median(during) * 1e3:.1f} ms, "
            f"max {max(during) * 1e3:.1f} ms, {prober.missed} missed"
        )
        # never deaf: every health query during the runaway passage got its answer (within
        # the query's 2 s), and they kept coming; how fast is printed above, not asserted (a
        # test checks behaviour; a loaded CI machine must not turn speed into a failure)
        assert prober.missed == 0
        assert len(during) >= 20
        # SIGTERM during a long passage: the service stops within the budget
        pub.put(json.dumps(slow_wheel("interrupted")))
        time.sleep(0.5)
        sub.undeclare()
        pub.undeclare()
        start = time.monotonic()
        svc.stop()
        stopped = time.monotonic() - start
    print(f"SIGTERM during a passage: stopped in {stopped:.1f} s (budget {BUDGET:g} s)")
    assert svc.returncode == 0, svc.output
    assert stopped < BUDGET + 5.0, svc.output


def test_port_taken_is_one_line(tmp_path: Path) -> None:
    import socket
    import subprocess
    import sys

    site = write_slow_site(tmp_path)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = subprocess.run(
            [
                sys.executable,
                "-m",
                "service.cli.serve",
                "--site",
                str(site),
                "--listen",
                f"tcp/127.0.0.1:{port}",
                "--physics",
                "stub",
                "--no-mcap",
                "--no-rerun",
            ],
            capture_output=True,
            text=True,
            timeout=120,
            cwd=Path(__file__).resolve().parents[1],
        )
    assert proc.returncode == 1, proc.stderr
    errors = [ln for ln in proc.stderr.strip().splitlines() if " ERROR " in ln]
    assert len(errors) == 1 and "Address already in use" in errors[0], proc.stderr
    assert "Traceback" not in proc.stderr and "/root/" not in errors[0]


@pytest.mark.parametrize("pace", ["fast", "realtime"])
def test_two_workers_publish_in_order(tmp_path: Path, pace: str) -> None:
    """Two workers on an elastic site: results in the passages' order (fast pacing: slow and
    quick wheels alternate, so a later passage is often simulated first)."""
    site = tmp_path / "fast.toml"
    site.write_text(
        SLOW_SITE.replace("length = 60.0", "length = 3.0").replace(
            'kind = "file"\npath = "rail.csv"', 'kind = "flat"'
        )
    )
    keys = SiteKeys("slow")
    endpoint = free_tcp_endpoint()
    order: list[str] = []
    chunks: dict[str, int] = {}
    lock = threading.Lock()

    def on_output(sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        kind = keys.kind_of(key)
        with lock:
            if kind == "result":
                order.append(key.rsplit("/", 1)[-1])
            elif kind == "force":
                pid = key.rsplit("/", 1)[-1]
                chunks[pid] = chunks.get(pid, 0) + 1

    ids = [f"w{i:02d}" for i in range(16)]
    extra: tuple[str, ...] = ("--workers", "2", "--pace", pace, "--no-mcap", "--no-rerun")
    if pace == "realtime":  # the result is due when the wheel leaves: same speed, in order
        extra += ("--physics", "stub", "--chunk-period", "0.02")
    svc = ServiceProcess(
        site,
        listen=endpoint,
        recordings=tmp_path / "rec",
        extra_args=extra,
        start_timeout=START_TIMEOUT,
    )
    with svc, zenoh.open(build_config(connect=[endpoint])) as session:
        assert "worker processes" in svc.output, svc.output
        sub = session.declare_subscriber(keys.all_outputs, on_output)
        pub = declare_passage_publisher(session, keys)
        assert wait_matching(pub, 20.0)
        for i, pid in enumerate(ids):
            speed = 10.0 if (i % 2 == 0 or pace == "realtime") else 80.0
            pub.put(WHEEL.model_copy(update={"passage_id": pid, "speed": speed}).model_dump_json())
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and len(order) < len(ids):
            time.sleep(0.02)
        sub.undeclare()
        pub.undeclare()
    assert order == ids, svc.output
    samples = passage_samples(3.0, 1000.0, 10.0)  # 0.3 s on the site at 1 kHz: 301
    expected_chunks = math.ceil(samples / 20) if pace == "realtime" else 1  # 20 ms chunks
    assert chunks["w00"] == expected_chunks
