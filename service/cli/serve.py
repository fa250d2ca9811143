"""``railtwin serve``: run the streaming twin of one site until SIGINT/SIGTERM.

    railtwin serve --site examples/site.toml [--listen E]... [--connect E]...
                   [--mode peer|client] [--zenoh-config FILE] [--pace fast|realtime]
                   [--recordings DIR]

``--connect tcp/<router>:7447`` joins a Zenoh router (``railtwin router``); with
``--mode client`` the twin talks through its router only (docs/deployment.md).

Also runnable as ``python -m service.cli.serve ...`` (what the tests do).
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import secrets
import signal
import sqlite3
import sys
import threading
import time
from pathlib import Path
from typing import Any

import zenoh

from schemas.site import SiteConfig
from service.cli import logs
from service.cli.common import CommandError, SubParsers
from service.cli.inputs import load_site_file, zenoh_config, zenoh_message
from service.physics.local import LocalPhysics
from service.physics.port import PhysicsPort
from service.physics.rail_store import RailStore, StateMismatchError, physics_fingerprint
from service.physics.worker import (
    CALIBRATION_INTERVAL,
    OnlineSetting,
    PhysicsPool,
    StartCancelledError,
)
from service.recording.input_journal import InputJournal
from service.recording.mcap_log import DEFAULT_MAX_BYTES, DEFAULT_MAX_SECONDS
from service.recording.recorder_process import ProcessRecorder, RecordingPlan
from service.twin.diagnoses import DiagnosisStore
from service.twin.twin import Twin
from service.wire.limits import DEFAULT_PASSAGE_BUDGET
from service.wire.zenoh_session import DEFAULT_ENDPOINT, open_session

log = logging.getLogger("railtwin.serve")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--site", type=Path, required=True, help="site file (TOML), e.g. examples/site.toml"
    )
    p.add_argument(
        "--listen",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"Zenoh endpoint to listen on (repeatable; default {DEFAULT_ENDPOINT} "
        "unless --zenoh-config or --connect is given)",
    )
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help="Zenoh endpoint to connect to (repeatable)",
    )
    p.add_argument(
        "--mode",
        choices=("peer", "client"),
        default="peer",
        help="Zenoh mode: peer (default) or client (through the router given with "
        "--connect only, as in a network of sites: docs/deployment.md)",
    )
    p.add_argument(
        "--zenoh-config",
        type=Path,
        default=None,
        metavar="FILE",
        help="Zenoh JSON5 config file; --listen/--connect apply on top of it",
    )
    p.add_argument(
        "--multicast-scouting",
        action="store_true",
        help="enable Zenoh multicast scouting (off by default: explicit endpoints)",
    )
    p.add_argument(
        "--pace",
        choices=("fast", "realtime"),
        default="fast",
        help="fast: publish as soon as simulated; realtime: publish series in chunks "
        "as the wheel advances (for live displays)",
    )
    p.add_argument(
        "--chunk-period",
        type=float,
        default=0.02,
        metavar="S",
        help="with --pace realtime: seconds of passage per chunk (default 0.02)",
    )
    p.add_argument(
        "--recordings",
        type=Path,
        default=Path("recordings"),
        metavar="DIR",
        help="where the MCAP log and the .rrd go (default recordings/)",
    )
    p.add_argument("--no-mcap", action="store_true", help="do not write the MCAP log")
    p.add_argument("--no-rerun", action="store_true", help="do not write the Rerun recording")
    p.add_argument(
        "--mcap-max-mb",
        type=float,
        default=DEFAULT_MAX_BYTES / 2**20,
        help="start a new MCAP file past this size (MB)",
    )
    p.add_argument(
        "--keep-gb",
        type=float,
        default=50.0,
        metavar="GB",
        help="retention: when a log rotates, the oldest railtwin-* recordings in the "
        "directory are deleted until at most this much remains (default 50; "
        "0: keep everything)",
    )
    p.add_argument(
        "--mcap-max-seconds",
        type=float,
        default=DEFAULT_MAX_SECONDS,
        help="start a new MCAP file after this many seconds",
    )
    p.add_argument(
        "--queue", type=int, default=10_000, help="passages that may wait (default 10000)"
    )
    p.add_argument(
        "--passage-budget",
        type=float,
        default=DEFAULT_PASSAGE_BUDGET,
        metavar="S",
        help="wall-time budget of one passage or diagnosis in the physics worker; "
        f"past it the worker is restarted (default {DEFAULT_PASSAGE_BUDGET:g} s)",
    )
    p.add_argument(
        "--stop-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="on SIGTERM/SIGINT, seconds to go on serving the inputs already queued; "
        "those still queued then get an 'overloaded' error (default 10)",
    )
    p.add_argument(
        "--state",
        type=Path,
        default=None,
        metavar="DIR",
        help="where the site's rail state and applied passage ids persist "
        "(SQLite <site_id>.sqlite; default RECORDINGS/state, i.e. "
        "recordings/state)",
    )
    p.add_argument(
        "--no-state",
        action="store_true",
        help="keep no state: the rail starts afresh, ids are not remembered",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=1,
        metavar="N",
        help="physics worker processes (default 1); passages of an elastic site "
        "(hertz, johnson) are simulated N at a time and published in order; a "
        "hertz_plastic site always has one",
    )
    p.add_argument(
        "--calibration-interval",
        type=float,
        default=CALIBRATION_INTERVAL,
        metavar="S",
        help="at a site with a detector, the twin calibrates its track online from the round "
        "wheels it dismisses, at most one wheel per S seconds (default "
        f"{CALIBRATION_INTERVAL:g}; 0: every one), kept in the state dir as "
        "<site_id>.calibration.json (none with --no-state)",
    )
    p.add_argument(
        "--no-online-calibration",
        action="store_true",
        help="keep the site file's track values (no online calibration)",
    )
    logs.add_arguments(p)
    p.add_argument(
        "--physics",
        choices=("sim_core", "stub"),
        default="sim_core",
        help="sim_core: the site's own physics (default); stub: an instant "
        "closed-form stand-in for plumbing tests and overhead measurements "
        "(its numbers are not physics; no diagnosis)",
    )
    p.add_argument("--in-process", action="store_true", help=argparse.SUPPRESS)


def register(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Add ``serve`` to the ``railtwin`` CLI's subparsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "serve",
        help="run the streaming twin of a site over Zenoh",
        description="Run the streaming twin: wheel passages in over Zenoh, forces and "
        "indentations out; every message in MCAP, every passage in Rerun.",
    )
    add_arguments(p)
    p.set_defaults(func=run)
    return p


def package_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("railtwin")
    except PackageNotFoundError:
        return "unknown"


def open_state(directory: Path, site: SiteConfig) -> RailStore:
    """The site's state store; refuses one of another site, made with other physics (rail,
    material, contact law, foundation, dent model) or by a newer railtwin."""
    return RailStore(
        directory,
        site.site_id,
        physics_fingerprint(site),
        written_by=f"railtwin {package_version()}",
    )


def run(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; exit status 0 on a clean stop, 2 on a bad site file,
    1 when the Zenoh session cannot be opened (e.g. the port is taken).

    The signals are handled from the start: one during the warm-up abandons it, one during
    the service stops it (``--stop-timeout``)."""
    logs.configure(args.log_level, args.log_json)
    stop = threading.Event()
    pools: list[PhysicsPool] = []

    def on_signal(signum: int, _frame: Any) -> None:
        stop.set()
        for pool in pools:  # a start under way is abandoned; no worker restarts from now on
            pool.cancel()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        return _run(args, stop, pools)
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _run(args: argparse.Namespace, stop: threading.Event, pools: list[PhysicsPool]) -> int:
    try:
        site = load_site_file(args.site, served=True)
        listen = args.listen or ([] if (args.zenoh_config or args.connect) else [DEFAULT_ENDPOINT])
        cfg = zenoh_config(
            listen=listen,
            connect=args.connect,
            config_file=args.zenoh_config,
            multicast_scouting=args.multicast_scouting,
            mode=args.mode,
        )
    except CommandError as exc:
        log.error("%s", exc)
        return exc.code
    if not args.keep_gb >= 0:
        log.error("--keep-gb must be >= 0")
        return 2
    if not args.passage_budget > 0:
        log.error("--passage-budget must be > 0")
        return 2
    if not args.stop_timeout >= 0:
        log.error("--stop-timeout must be >= 0")
        return 2
    if args.mode == "client" and not (args.connect or args.zenoh_config):
        log.error("--mode client needs --connect ENDPOINT (a router)")
        return 2
    interval = args.calibration_interval
    if not (math.isfinite(interval) and interval >= 0.0):
        log.error(f"--calibration-interval must be >= 0 s, got {interval:g}")
        return 2
    if args.workers < 1:
        log.error("--workers must be >= 1")
        return 2
    workers = args.workers
    if workers > 1 and site.contact == "hertz_plastic":
        log.info(
            f"one physics worker, not {workers}: on a hertz_plastic site "
            "every wheel rolls on the dents of the ones before"
        )
        workers = 1
    worker: PhysicsPool | None = None
    store: RailStore | None = None
    physics: PhysicsPort
    if args.in_process:
        local = LocalPhysics.of(args.physics, site)
        log.info(f"physics warmed up in {local.warm_up():.1f} s")
        physics = local
    else:  # the compiled physics holds the GIL: it runs in a worker process
        if not args.no_state:
            try:
                store = open_state(args.state or args.recordings / "state", site)
            except (StateMismatchError, OSError, sqlite3.Error) as exc:
                log.error(f"state: {exc}")
                return 2
            if store.migrated_from is not None:
                log.info(
                    f"state {store.path}: migrated from state schema "
                    f"{store.migrated_from}; its rail is taken as made with the physics of "
                    f"{args.site} as it is now"
                )
            log.info(f"state {store.path} ({store.applied_count()} passages applied before)")
        online = None
        if not (args.no_state or args.no_online_calibration):
            online = OnlineSetting(args.state or args.recordings / "state", interval)
        worker = PhysicsPool(
            site,
            args.physics,
            workers=workers,
            budget=args.passage_budget,
            store=store,
            calibration=online,
        )
        pools.append(worker)
        try:
            seconds = worker.start()
        except StartCancelledError:
            worker.close()
            if store is not None:
                store.close()
            log.info("stopped during the physics warm-up")
            return 0
        physics = worker
        pids = ", ".join(str(p) for p in worker.pids)
        log.info(
            f"physics warmed up in {seconds:.1f} s (worker process"
            f"{'es' if workers > 1 else ''} {pids}, budget {args.passage_budget:g} s a "
            "passage)"
        )
    try:
        if stop.is_set():
            log.info("stopped before serving")
            return 0
        return _serve(args, site, cfg, listen, physics, stop)
    finally:
        if worker is not None:
            worker.close()
        if store is not None:  # after the workers: the last passage's commit is in it
            store.close()


def _serve(
    args: argparse.Namespace,
    site: SiteConfig,
    cfg: zenoh.Config,
    listen: list[str],
    physics: PhysicsPort,
    stop: threading.Event,
) -> int:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    # unique per run, not per second: two services started together keep both logs
    stem = f"railtwin-{site.site_id}-{stamp}-{os.getpid()}{secrets.token_hex(2)}"
    # every input on disk before it is queued: recover merges it into a cut MCAP; the
    # recorder tells the journal what a flushed MCAP chunk holds, and it lets that go
    journal = None if args.no_mcap else InputJournal(args.recordings / f"{stem}-inputs.journal")
    recorder: ProcessRecorder | None = None
    if not (args.no_mcap and args.no_rerun):
        # MCAP and Rerun are written by a child process, off this interpreter's GIL
        recorder = ProcessRecorder(
            RecordingPlan(
                directory=args.recordings,
                stem=stem,
                site_id=site.site_id,
                mcap=not args.no_mcap,
                rerun=not args.no_rerun,
                mcap_max_bytes=int(args.mcap_max_mb * 2**20),
                mcap_max_seconds=args.mcap_max_seconds,
                keep_bytes=int(args.keep_gb * 2**30) if args.keep_gb > 0 else None,
                cribs=tuple(c.id for c in site.detector.cribs) if site.detector else (),
                metadata=(
                    ("railtwin_version", package_version()),
                    ("site", site.model_dump_json()),
                    ("site_file", str(args.site)),
                    ("started_at", stamp),
                ),
            ),
            journal=journal,
        )

    # the diagnoses made, for catch-up queries: beside the rail state, else in memory
    state_dir = None if args.no_state else (args.state or args.recordings / "state")
    try:
        diagnoses = DiagnosisStore(
            None if state_dir is None else state_dir / f"{site.site_id}-diagnoses.sqlite"
        )
    except (OSError, sqlite3.Error) as exc:
        log.error(f"diagnoses store: {exc}")
        if recorder is not None:
            recorder.close()
        if journal is not None:
            journal.close()
        return 2
    try:
        try:
            session = open_session(cfg)
        except zenoh.ZError as exc:
            log.error(f"cannot open the Zenoh session: {zenoh_message(exc)}")
            if recorder is not None:
                recorder.close()
            return 1
        with session:
            twin = Twin(
                site,
                session,
                physics,
                recorder=recorder,
                journal=journal,
                pace=args.pace,
                chunk_period=args.chunk_period,
                queue_capacity=args.queue,
                diagnoses=diagnoses,
            )
            twin.start()
            where = ", ".join(listen) if listen else "(from config)"
            log.info(
                f"site {site.site_id!r} ({site.length:g} m, {site.contact}), "
                f"listening on {where}; passages on {twin.keys.passage}"
            )
            if physics.diagnoses:
                log.info(
                    f"diagnosis on, measurements on {twin.keys.measured} "
                    f"(pairing timeout {site.diagnosis.pairing_timeout:g} s)"
                )
            if recorder is not None:
                log.info(f"recording to {args.recordings}/{stem}*")
            log.info("ready")
            while not stop.wait(0.2):
                pass
            twin.stop(deadline=time.monotonic() + args.stop_timeout)
            h = twin.health()
            log.info(
                f"stopped after {h.passages_done} passages, "
                f"{twin.diagnoses_done} diagnoses, {h.errors} errors"
            )
    finally:
        if journal is not None:
            journal.close()
        diagnoses.close()
    if recorder is not None:
        for f in sorted(args.recordings.glob(f"{stem}-*.mcap")):
            log.info(f"MCAP log {f}")
        if recorder.rrd_path() is not None:
            log.info(f"Rerun recording {recorder.rrd_path()}")
        if recorder.failures:
            log.warning(f"{recorder.failures} recording failures, last: {recorder.last_failure}")
    return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin serve", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
