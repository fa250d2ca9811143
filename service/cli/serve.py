"""``railtwin serve``: run the streaming twin of one site until SIGINT/SIGTERM.

    railtwin serve --site examples/site.toml [--listen E]... [--connect E]...
                   [--zenoh-config FILE] [--pace fast|realtime] [--recordings DIR]

Also runnable as ``python -m service.cli.serve ...`` (what the tests do).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import re
import secrets
import signal
import sqlite3
import sys
import threading
import time
from pathlib import Path
from typing import Any

import zenoh

from service.physics.port import PassageSimulator
from service.physics.rail_store import RailStore, StateMismatchError
from service.physics.worker import PhysicsPool
from service.recording.input_journal import InputJournal
from service.recording.mcap_log import DEFAULT_MAX_BYTES, DEFAULT_MAX_SECONDS
from service.recording.recorder_process import ProcessRecorder, RecordingPlan
from service.twin.twin import Twin
from service.wire.limits import DEFAULT_PASSAGE_BUDGET, site_problem
from service.wire.site import SiteFileError, load_site
from service.wire.zenoh_session import DEFAULT_ENDPOINT, build_config, open_session


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--site", type=Path, required=True,
                   help="site file (TOML), e.g. examples/site.toml")
    p.add_argument("--listen", action="append", default=[], metavar="ENDPOINT",
                   help=f"Zenoh endpoint to listen on (repeatable; default {DEFAULT_ENDPOINT} "
                        "unless --zenoh-config or --connect is given)")
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to (repeatable)")
    p.add_argument("--zenoh-config", type=Path, default=None, metavar="FILE",
                   help="Zenoh JSON5 config file; --listen/--connect apply on top of it")
    p.add_argument("--multicast-scouting", action="store_true",
                   help="enable Zenoh multicast scouting (off by default: explicit endpoints)")
    p.add_argument("--pace", choices=("fast", "realtime"), default="fast",
                   help="fast: publish as soon as simulated; realtime: publish series in chunks "
                        "as the wheel advances (for live displays)")
    p.add_argument("--chunk-period", type=float, default=0.02, metavar="S",
                   help="with --pace realtime: seconds of passage per chunk (default 0.02)")
    p.add_argument("--recordings", type=Path, default=Path("recordings"), metavar="DIR",
                   help="where the MCAP log and the .rrd go (default recordings/)")
    p.add_argument("--no-mcap", action="store_true", help="do not write the MCAP log")
    p.add_argument("--no-rerun", action="store_true", help="do not write the Rerun recording")
    p.add_argument("--mcap-max-mb", type=float, default=DEFAULT_MAX_BYTES / 2**20,
                   help="start a new MCAP file past this size (MB)")
    p.add_argument("--keep-gb", type=float, default=50.0, metavar="GB",
                   help="retention: when a log rotates, the oldest railtwin-* recordings in the "
                        "directory are deleted until at most this much remains (default 50; "
                        "0: keep everything)")
    p.add_argument("--mcap-max-seconds", type=float, default=DEFAULT_MAX_SECONDS,
                   help="start a new MCAP file after this many seconds")
    p.add_argument("--queue", type=int, default=10_000,
                   help="passages that may wait (default 10000)")
    p.add_argument("--passage-budget", type=float, default=DEFAULT_PASSAGE_BUDGET, metavar="S",
                   help="wall-time budget of one passage or diagnosis in the physics worker; "
                        f"past it the worker is restarted (default {DEFAULT_PASSAGE_BUDGET:g} s)")
    p.add_argument("--state", type=Path, default=None, metavar="DIR",
                   help="where the site's rail state and applied passage ids persist "
                        "(SQLite <site_id>.sqlite; default RECORDINGS/state, i.e. "
                        "recordings/state)")
    p.add_argument("--no-state", action="store_true",
                   help="keep no state: the rail starts afresh, ids are not remembered")
    p.add_argument("--workers", type=int, default=1, metavar="N",
                   help="physics worker processes (default 1); passages of an elastic site "
                        "(hertz, johnson) are simulated N at a time and published in order; a "
                        "hertz_plastic site always has one")
    p.add_argument("--physics", choices=("sim_core", "stub"), default="sim_core",
                   help=argparse.SUPPRESS)
    p.add_argument("--in-process", action="store_true", help=argparse.SUPPRESS)


def register(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``serve`` to the ``railtwin`` CLI's subparsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "serve", help="run the streaming twin of a site over Zenoh",
        description="Run the streaming twin: wheel passages in over Zenoh, forces and "
                    "indentations out; every message in MCAP, every passage in Rerun.",
    )
    add_arguments(p)
    p.set_defaults(func=run)
    return p


def make_physics(kind: str, site: Any) -> PassageSimulator:
    if kind == "stub":
        from service.physics.stub import StubPhysics

        return StubPhysics(site)
    from service.physics.site_physics import SitePhysics

    return SitePhysics(site)


def one_line(exc: BaseException) -> str:
    """The first sentence of a Zenoh error, without its source locations."""
    text = re.sub(r"\s+at /\S+", "", str(exc)).replace("\n", " ")
    return text[:300]


def package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("railtwin")
    except PackageNotFoundError:
        return "unknown"


def open_state(directory: Path, site: Any) -> RailStore:
    """The site's state store; refuses one written for another site file or version."""
    pkg = package_version()
    digest = hashlib.sha256(site.model_dump_json().encode()).hexdigest()[:16]
    return RailStore(directory, site.site_id, f"railtwin {pkg}, site file {digest}")


def run(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; exit status 0 on a clean stop, 2 on a bad site file,
    1 when the Zenoh session cannot be opened (e.g. the port is taken)."""
    try:
        site = load_site(args.site)
    except SiteFileError as exc:
        print(f"railtwin serve: {exc}", file=sys.stderr)
        return 2
    problem = site_problem(site)
    if problem is not None:
        print(f"railtwin serve: {args.site}: invalid site: {problem}", file=sys.stderr)
        return 2
    if not args.keep_gb >= 0:
        print("railtwin serve: --keep-gb must be >= 0", file=sys.stderr)
        return 2
    if not args.passage_budget > 0:
        print("railtwin serve: --passage-budget must be > 0", file=sys.stderr)
        return 2
    listen = args.listen or ([] if (args.zenoh_config or args.connect) else [DEFAULT_ENDPOINT])
    cfg = build_config(listen=listen, connect=args.connect, config_file=args.zenoh_config,
                       multicast_scouting=args.multicast_scouting)
    if args.workers < 1:
        print("railtwin serve: --workers must be >= 1", file=sys.stderr)
        return 2
    workers = args.workers
    if workers > 1 and site.contact == "hertz_plastic":
        print(f"railtwin serve: one physics worker, not {workers}: on a hertz_plastic site "
              "every wheel rolls on the dents of the ones before", flush=True)
        workers = 1
    worker: PhysicsPool | None = None
    physics: PassageSimulator
    if args.in_process:
        physics = make_physics(args.physics, site)
        warm_up = getattr(physics, "warm_up", None)
        if warm_up is not None:
            print(f"railtwin serve: physics warmed up in {warm_up():.1f} s", flush=True)
    else:  # the compiled physics holds the GIL: it runs in a worker process
        store = None
        if not args.no_state:
            try:
                store = open_state(args.state or args.recordings / "state", site)
            except (StateMismatchError, OSError, sqlite3.Error) as exc:
                print(f"railtwin serve: state: {exc}", file=sys.stderr)
                return 2
            print(f"railtwin serve: state {store.path} ({store.applied_count()} passages "
                  "applied before)", flush=True)
        worker = PhysicsPool(site, args.physics, workers=workers, budget=args.passage_budget,
                             store=store)
        seconds = worker.start()
        physics = worker
        pids = ", ".join(str(p) for p in worker.pids)
        print(f"railtwin serve: physics warmed up in {seconds:.1f} s (worker process"
              f"{'es' if workers > 1 else ''} {pids}, budget {args.passage_budget:g} s a "
              "passage)", flush=True)
    try:
        return _serve(args, site, cfg, listen, physics)
    finally:
        if worker is not None:
            worker.close()


def _serve(args: argparse.Namespace, site: Any, cfg: zenoh.Config, listen: list[str],
           physics: PassageSimulator) -> int:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    # unique per run, not per second: two services started together keep both logs
    stem = f"railtwin-{site.site_id}-{stamp}-{os.getpid()}{secrets.token_hex(2)}"
    recorder: ProcessRecorder | None = None
    if not (args.no_mcap and args.no_rerun):
        # MCAP and Rerun are written by a child process, off this interpreter's GIL
        recorder = ProcessRecorder(RecordingPlan(
            directory=args.recordings, stem=stem, site_id=site.site_id,
            mcap=not args.no_mcap, rerun=not args.no_rerun,
            mcap_max_bytes=int(args.mcap_max_mb * 2**20), mcap_max_seconds=args.mcap_max_seconds,
            keep_bytes=int(args.keep_gb * 2**30) if args.keep_gb > 0 else None,
            metadata=(("railtwin_version", package_version()), ("site", site.model_dump_json()),
                      ("site_file", str(args.site)), ("started_at", stamp)),
        ))

    # every input on disk before it is queued: recover merges it into a cut MCAP
    journal = None if args.no_mcap else InputJournal(args.recordings / f"{stem}-inputs.journal")
    stop = threading.Event()

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        try:
            session = open_session(cfg)
        except zenoh.ZError as exc:
            print(f"railtwin serve: cannot open the Zenoh session: {one_line(exc)}",
                  file=sys.stderr, flush=True)
            if recorder is not None:
                recorder.close()
            return 1
        with session:
            twin = Twin(site, session, physics, recorder=recorder, journal=journal, pace=args.pace,
                        chunk_period=args.chunk_period, queue_capacity=args.queue)
            twin.start()
            where = ", ".join(listen) if listen else "(from config)"
            print(f"railtwin serve: site {site.site_id!r} ({site.length:g} m, {site.contact}), "
                  f"listening on {where}; passages on {twin.keys.passage}", flush=True)
            if twin.diagnoser is not None:
                print(f"railtwin serve: diagnosis on, measurements on {twin.keys.measured} "
                      f"(pairing timeout {site.diagnosis.pairing_timeout:g} s)", flush=True)
            if recorder is not None:
                print(f"railtwin serve: recording to {args.recordings}/{stem}*", flush=True)
            print("railtwin serve: ready", flush=True)
            while not stop.wait(0.2):
                pass
            twin.stop()
            h = twin.health()
            print(f"railtwin serve: stopped after {h.passages_done} passages, "
                  f"{twin.diagnoses_done} diagnoses, {h.errors} errors", flush=True)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if journal is not None:
            journal.close()
    if recorder is not None:
        for f in sorted(args.recordings.glob(f"{stem}-*.mcap")):
            print(f"railtwin serve: MCAP log {f}", flush=True)
        if recorder.rrd_path() is not None:
            print(f"railtwin serve: Rerun recording {recorder.rrd_path()}", flush=True)
        if recorder.failures:
            print(f"railtwin serve: {recorder.failures} recording failures, last: "
                  f"{recorder.last_failure}", file=sys.stderr, flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin serve", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
