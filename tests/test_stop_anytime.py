"""SIGTERM at any moment stops the service cleanly (docs/service.md, "Serve").

The service is started (stub physics: the start-up is seconds, not minutes) and a client
floods it with passages as soon as it is ready; SIGTERM goes to its main process or to its
whole process group (what a service manager sends) at a moment drawn from a seeded random
schedule: during start-up and warm-up (aimed within the start-up time measured in the
earlier runs), during the flood, or idle. Each time every process of the group
must be gone within ``STOP_BOUND`` s and every MCAP file it names must read to its end.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh

from schemas.messages import WheelPassage
from service.cli.service_process import MCAP_LOG, READY
from service.clients.feeder import declare_passage_publisher, wait_matching
from service.recording.mcap_log import read_log
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config, free_tcp_endpoint

ROOT = Path(__file__).resolve().parents[1]
RUNS = 20
SEED = 15
STOP_TIMEOUT = 2.0
STOP_BOUND = 30.0
"""s from the signal until no process of the group is left: ``--stop-timeout`` (2 s here)
plus the recorder finishing its files and the workers' stop (docs/service.md)."""
FLOOD = 400


def group_members(pgid: int) -> list[int]:
    """Live (not zombie) processes whose process group is ``pgid``."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        state, pgrp = fields[0], int(fields[2])
        if pgrp == pgid and state != "Z":
            found.append(int(entry.name))
    return found


def flood(endpoint: str, site_id: str, ready: threading.Event, done: threading.Event) -> None:
    """Publish FLOOD passages as fast as the service takes them, once it is ready."""
    if not ready.wait(60.0):
        return
    keys = SiteKeys(site_id)
    try:
        with zenoh.open(build_config(connect=[endpoint])) as session:
            pub = declare_passage_publisher(session, keys)
            if not wait_matching(pub, 10.0):
                return
            for i in range(FLOOD):
                if done.is_set():
                    break
                pub.put(
                    WheelPassage(
                        passage_id=f"f{i}",
                        train_id="flood",
                        axle_index=i % 32,
                        side="right",
                        timestamp=1.7e9 + i,
                        speed=44.4,
                        load=80e3,
                        mass=600.0,
                        radius=0.46,
                    )
                    .model_dump_json()
                    .encode()
                )
            pub.undeclare()
    except zenoh.ZError:
        return  # the service went away under the client: that is the point


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_sigterm_at_random_moments_ends_every_process_with_readable_logs(tmp_path: Path) -> None:
    rng = random.Random(SEED)
    moments = []
    ready_after: list[float] = []  # s from the spawn to "ready", as measured so far
    for run in range(RUNS):
        # the moment: during start-up and warm-up (before "ready", aimed at the start-up
        # time measured in the runs before), during the flood that follows "ready", or idle
        phase = "idle" if run == 0 else rng.choice(["start-up", "start-up", "flood", "idle"])
        whole_group = rng.random() < 0.5
        endpoint = free_tcp_endpoint()
        recordings = tmp_path / f"run{run}"
        spawned = time.monotonic()
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "service.cli",
                "serve",
                "--site",
                "examples/site.toml",
                "--listen",
                endpoint,
                "--recordings",
                str(recordings),
                "--physics",
                "stub",
                "--state",
                str(recordings / "state"),
                "--stop-timeout",
                str(STOP_TIMEOUT),
            ],
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
            start_new_session=True,
        )
        lines: list[str] = []
        ready, done = threading.Event(), threading.Event()

        def pump(
            p: subprocess.Popen[str] = proc, out: list[str] = lines, seen: threading.Event = ready
        ) -> None:
            assert p.stdout is not None
            for line in p.stdout:
                out.append(line.rstrip("\n"))
                if READY in line:
                    seen.set()

        reader = threading.Thread(target=pump, daemon=True)
        reader.start()
        client = threading.Thread(target=flood, args=(endpoint, "demo", ready, done), daemon=True)
        client.start()
        if phase == "start-up":
            typical = sorted(ready_after)[len(ready_after) // 2]
            time.sleep(rng.uniform(0.0, 0.95 * typical))
        else:
            if ready.wait(120.0):
                ready_after.append(time.monotonic() - spawned)
            time.sleep(rng.uniform(0.0, 0.5) if phase == "flood" else rng.uniform(1.0, 2.0))
        delay = time.monotonic() - spawned
        was_ready = ready.is_set()
        signalled = time.monotonic()
        if whole_group:
            os.killpg(proc.pid, signal.SIGTERM)
        else:
            proc.send_signal(signal.SIGTERM)
        try:
            code = proc.wait(STOP_BOUND)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            pytest.fail(
                f"run {run} (SIGTERM at {delay:.2f} s, group {whole_group}, ready "
                f"{was_ready}): the service did not stop within {STOP_BOUND:g} s\n"
                + "\n".join(lines)
            )
        while group_members(proc.pid) and time.monotonic() - signalled < STOP_BOUND:
            time.sleep(0.05)
        left = group_members(proc.pid)
        done.set()
        if left:
            os.killpg(proc.pid, signal.SIGKILL)
        reader.join(5.0)
        stopped = time.monotonic() - signalled
        moments.append((delay, whole_group, was_ready, code, stopped))
        context = (
            f"run {run}: SIGTERM at {delay:.2f} s to the "
            f"{'group' if whole_group else 'main process'} (ready: {was_ready})\n"
            + "\n".join(lines)
        )
        assert not left, f"processes {left} still running {STOP_BOUND:g} s after\n{context}"
        # the handler is installed once the interpreter has loaded railtwin; before, the
        # default action ends the process, which then has started nothing
        assert code == 0 or (code == -signal.SIGTERM and not lines), context
        named = [Path(s.split(MCAP_LOG, 1)[1]) for s in lines if MCAP_LOG in s]
        on_disk = sorted(recordings.glob("*.mcap")) if recordings.exists() else []
        assert sorted(named) == on_disk, context
        for path in on_disk:
            list(read_log([path]))  # closed: index and footer are there (raises if cut)
    print(
        "\n".join(
            f"SIGTERM at {d:5.2f} s {'group' if g else 'main '} ready={r!s:5} "
            f"exit {c} all gone in {s:.2f} s"
            for d, g, r, c, s in moments
        )
    )
