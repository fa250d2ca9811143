"""``make fleet-demo``: a router, three site twins, the fleet, and a wheel whose flat grows.

    .venv/bin/python -m service.cli.fleet_demo [--out recordings/fleet-demo] [--linger 60]

Starts, each in its own process, a Zenoh router on a free loopback port, three site
twins (``railtwin serve`` with ``examples/site_compliant.toml`` renamed km12, km48 and km97,
connected to the router) and the fleet service (``railtwin fleet serve --connect ...
--db OUT/fleet.sqlite --http ...``). Then one vehicle passes the three sites on three
successive days: wheelset 2's left wheel has a flat growing 30 → 36 → 42 mm (its axle
mate is round); the site's measured force of each wheel is made by the generator
(``service.clients.synthesize``: unknown roughness and damping, sensor chain, noise). It prints
each diagnosis and each fleet alarm as they come, the wheel's history as
``railtwin fleet wheel`` prints it, and the dashboard's URL (served ``--linger`` s more);
the history stays in OUT/fleet.sqlite.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
SITES = ("km12", "km48", "km97")
SPEEDS = (22.0, 25.0, 20.0)
"""m/s: each site measures the train at its own speed (line speed 44.4 m/s)."""
FLAT_MM = (30.0, 36.0, 42.0)
VEHICLE = "31-80-4751-123-4"
WHEELSET = 2
DAY = 86400.0


def run_router(endpoint: str) -> int:
    """A Zenoh router (router mode) on ``endpoint`` until SIGTERM/SIGINT."""
    import zenoh

    from service.wire.zenoh_session import build_config

    stop = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    with zenoh.open(build_config(listen=[endpoint], mode="router")):
        print(f"router: listening on {endpoint}", flush=True)
        stop.wait()
    return 0


def router_command(endpoint: str) -> list[str]:
    """``railtwin router --listen ENDPOINT`` (issue 16) when this build has it, else this
    module's own router (the same: a Zenoh session in router mode)."""
    import importlib.util

    if importlib.util.find_spec("service.cli.router") is not None:
        return ["-m", "service.cli.router", "--listen", endpoint]
    return ["-m", "service.cli.fleet_demo", "--router", endpoint]


def wait_listening(endpoint: str, timeout: float = 30.0) -> None:
    """Until something accepts TCP connections at ``tcp/HOST:PORT``."""
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + timeout
    while True:
        try:
            with socket.create_connection((host, int(port)), timeout=1.0):
                return
        except OSError:
            if time.monotonic() > deadline:
                raise RuntimeError(f"nothing listens on {endpoint} after {timeout:g} s") from None
            time.sleep(0.1)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Procs:
    """Child processes, each with its log file; stopped in reverse order."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.procs: list[tuple[str, subprocess.Popen[bytes]]] = []

    def start(self, name: str, args: Sequence[str]) -> subprocess.Popen[bytes]:
        log = (self.out / f"{name}.log").open("wb")
        p = subprocess.Popen(
            [sys.executable, *args], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT
        )
        self.procs.append((name, p))
        return p

    def log(self, name: str) -> str:
        return (self.out / f"{name}.log").read_text(encoding="utf-8", errors="replace")

    def check(self) -> None:
        for name, p in self.procs:
            if p.poll() is not None:
                raise RuntimeError(f"{name} exited ({p.returncode}):\n{self.log(name)[-3000:]}")

    def stop(self) -> None:
        for _, p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for name, p in reversed(self.procs):
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                print(f"demo: {name} did not stop: killed", flush=True)
                p.kill()


def _site_files(out: Path, template: Path) -> list[Path]:
    text = template.read_text(encoding="utf-8")
    files = []
    for site in SITES:
        f = out / f"{site}.toml"
        f.write_text(re.sub(r"(?m)^site_id\s*=.*$", f'site_id = "{site}"', text), encoding="utf-8")
        files.append(f)
    return files


def _wait(what: str, predicate: Any, timeout: float, procs: Procs) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        procs.check()
        if time.monotonic() > deadline:
            raise RuntimeError(f"timed out after {timeout:.0f} s waiting for {what}")
        time.sleep(0.5)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m service.cli.fleet_demo", description=__doc__.split("\n")[0]
    )
    p.add_argument("--out", type=Path, default=ROOT / "recordings/fleet-demo")
    p.add_argument(
        "--site",
        type=Path,
        default=ROOT / "examples/site_compliant.toml",
        help="the site file the three sites are made from",
    )
    p.add_argument(
        "--linger",
        type=float,
        default=60.0,
        help="s to keep the dashboard up at the end (Ctrl-C ends early)",
    )
    p.add_argument("--router", metavar="ENDPOINT", default=None, help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.router:
        return run_router(a.router)
    return run_demo(a.out, a.site, a.linger)


def run_demo(out: Path, template: Path, linger: float) -> int:
    import zenoh

    from schemas.diagnosis import Diagnosis, MeasuredPassage
    from schemas.messages import Direction, WheelPassage, WheelRef
    from service.cli.fleet import wheel_table
    from service.clients.synthesize import measure
    from service.physics.diagnosis import Diagnoser
    from service.wire.site import load_site
    from service.wire.zenoh_session import build_config, free_tcp_endpoint
    from sim_core.diagnosis.forward import Flat

    out.mkdir(parents=True, exist_ok=True)
    db = out / "fleet.sqlite"
    for old in (db, out / "fleet.sqlite-wal", out / "fleet.sqlite-shm"):
        old.unlink(missing_ok=True)
    for site in SITES:
        shutil.rmtree(out / site, ignore_errors=True)
    router = free_tcp_endpoint()
    http = f"127.0.0.1:{_free_port()}"
    procs = Procs(out)
    files = _site_files(out, template)
    print(f"fleet-demo: router on {router}; sites {', '.join(SITES)}; logs in {out}", flush=True)
    procs.start("router", router_command(router))
    for site, f in zip(SITES, files, strict=True):
        procs.start(
            site,
            [
                "-m",
                "service.cli.serve",
                "--site",
                str(f),
                "--connect",
                router,
                "--recordings",
                str(out / site),
                "--state",
                str(out / site / "state"),
                "--no-rerun",
            ],
        )
    procs.start(
        "fleet",
        [
            "-m",
            "service.cli.fleet",
            "serve",
            "--connect",
            router,
            "--db",
            str(db),
            "--http",
            http,
            "--limits",
            str(template),
        ],
    )
    alarms: list[dict[str, Any]] = []
    diagnoses: list[Diagnosis] = []

    def on_alarm(s: zenoh.Sample) -> None:
        a = json.loads(s.payload.to_bytes())
        alarms.append(a)
        print(
            f"\n*** FLEET ALARM [{a['severity']}] {a['wheel_id']}: {a['reason']}\n"
            f"    evidence: {', '.join(a['evidence'])}\n",
            flush=True,
        )

    def on_diagnosis(s: zenoh.Sample) -> None:
        d = Diagnosis.model_validate_json(s.payload.to_bytes())
        diagnoses.append(d)
        flat = "no flat" if d.flat is None else f"flat {d.flat.length * 1e3:.1f} mm"
        fl = (
            ""
            if d.peak_force_at_line_speed is None
            else f", {d.peak_force_at_line_speed / 1e3:.0f} kN at line speed"
        )
        who = d.wheel.id if d.wheel is not None else d.passage_id
        print(f"  {d.site_id}: {who}: {d.verdict.upper()} ({flat}{fl})", flush=True)

    try:
        wait_listening(router)
        with zenoh.open(build_config(connect=[router], mode="client")) as session:
            session.declare_subscriber("railtwin/fleet/alarm/**", on_alarm)
            session.declare_subscriber("railtwin/*/diagnosis/**", on_diagnosis)

            def answers(key: str) -> bool:
                return any(r.ok is not None for r in session.get(key, timeout=1.0))

            print(
                "fleet-demo: waiting for the twins (the first start compiles the physics: "
                "allow a few minutes)",
                flush=True,
            )
            for site in SITES:
                _wait(f"twin {site}", lambda s=site: answers(f"railtwin/{s}/health"), 900, procs)
            _wait("the fleet", lambda: answers("railtwin/fleet/alarms"), 60, procs)
            url = f"http://{http}/"
            print(f"fleet-demo: all up; dashboard at {url}", flush=True)
            site_cfg = load_site(files[0])
            diagnoser = Diagnoser(site_cfg)
            today = time.time() // DAY * DAY + 8 * 3600.0
            for day, (site, speed, flat_mm) in enumerate(zip(SITES, SPEEDS, FLAT_MM, strict=True)):
                direction: Direction = "end1_leading" if day % 2 == 0 else "end2_leading"
                stamp = today - (len(SITES) - 1 - day) * DAY
                print(
                    f"\nfleet-demo: day {day + 1}, {time.strftime('%Y-%m-%d', time.gmtime(stamp))}"
                    f": the train passes {site} at {speed:g} m/s ({direction}); the flat is "
                    f"{flat_mm:g} mm",
                    flush=True,
                )
                pub_p = session.declare_publisher(f"railtwin/{site}/passage")
                pub_m = session.declare_publisher(f"railtwin/{site}/measured")
                sent = []
                for side in ("left", "right"):
                    wheel = WheelRef(vehicle_id=VEHICLE, wheelset=WHEELSET, side=side)
                    pid = f"d{day + 1}-{VEHICLE}-ws{WHEELSET}-{side}"
                    passage = WheelPassage(
                        passage_id=pid,
                        train_id=f"ic802-d{day + 1}",
                        axle_index=WHEELSET - 1,
                        side=wheel.rail_side(direction),
                        timestamp=stamp,
                        speed=speed,
                        load=60e3,
                        mass=600.0,
                        radius=0.46,
                        wheel=wheel,
                        direction=direction,
                    )
                    tread = Flat.ideal(0.46, flat_mm * 1e-3, 1.0) if side == "left" else None
                    m = measure(
                        site_cfg,
                        passage,
                        tread,
                        seed=100 + 2 * day + (side == "left"),
                        diagnoser=diagnoser,
                    )
                    pub_p.put(passage.model_dump_json())
                    pub_m.put(
                        MeasuredPassage(
                            passage_id=pid,
                            sample_rate=m.sample_rate,
                            t_start=m.t_start,
                            force=m.force.tolist(),
                            speed=speed,
                        ).model_dump_json()
                    )
                    sent.append(pid)
                _wait(
                    f"{site}'s diagnoses",
                    lambda sent=sent: {d.passage_id for d in diagnoses} >= set(sent),
                    600,
                    procs,
                )
                pub_p.undeclare()
                pub_m.undeclare()
            flat_wheel = f"{VEHICLE}/{WHEELSET}/left"

            def doc() -> dict[str, Any] | None:
                for r in session.get(f"railtwin/fleet/wheel/{flat_wheel}", timeout=2.0):
                    if r.ok is not None:
                        d: dict[str, Any] = json.loads(r.ok.payload.to_bytes())
                        return d
                return None

            _wait(
                "the fleet's history",
                lambda: (d := doc()) is not None and len(d["history"]) == len(SITES),
                60,
                procs,
            )
            history = doc()
            assert history is not None
            print(
                "\nfleet-demo: the fleet's history of the flat wheel "
                f"(railtwin fleet wheel {flat_wheel} --connect {router}):\n",
                flush=True,
            )
            print(wheel_table(history), flush=True)
            sites_seen = {h["site_id"] for h in history["history"]}
            ok = sites_seen == set(SITES) and any(a["wheel_id"] == flat_wheel for a in alarms)
            print(f"fleet-demo: {len(alarms)} alarm(s); history in {db}", flush=True)
            print(f"fleet-demo: dashboard: {url}wheel/{flat_wheel}", flush=True)
            if linger > 0:
                print(
                    f"fleet-demo: serving the dashboard {linger:g} s more (Ctrl-C to stop)",
                    flush=True,
                )
                with contextlib.suppress(KeyboardInterrupt):
                    time.sleep(linger)
            if not ok:
                print(
                    "fleet-demo: FAILED: the flat wheel's history lacks a site, or no alarm "
                    "was raised",
                    file=sys.stderr,
                )
            return 0 if ok else 1
    except RuntimeError as exc:
        print(f"fleet-demo: {exc}", file=sys.stderr)
        return 1
    finally:
        procs.stop()


if __name__ == "__main__":
    sys.exit(main())
