"""A busy child process leaves once the service that started it is killed (service.physics.parent_watch)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from service.physics.parent_watch import exit_when_orphaned

ROOT = Path(__file__).resolve().parents[1]

# The "service": spawns a child that is busy in Python (as the physics worker is while
# numba compiles, not reading its pipe), prints the child's pid, then waits to be killed.
SERVICE = """
import multiprocessing, os, sys, time
from tests.test_parent_watch import busy_child
if __name__ == "__main__":
    ctx = multiprocessing.get_context("spawn")
    p = ctx.Process(target=busy_child, args=(os.getpid(), sys.argv[1] == "watch"), daemon=True)
    p.start()
    print(p.pid, flush=True)
    time.sleep(600)
"""


def busy_child(parent_pid: int, watch: bool) -> None:
    if watch:
        exit_when_orphaned(parent_pid, poll=0.1)
    deadline = time.monotonic() + 60.0
    n = 0
    while time.monotonic() < deadline:  # busy, never reading a pipe
        n += 1


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in status  # a zombie has exited


def _orphan_lives(watch: bool, wait: float) -> bool:
    svc = subprocess.Popen(
        [sys.executable, "-c", SERVICE, "watch" if watch else "none"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert svc.stdout is not None
    child = int(svc.stdout.readline())
    try:
        assert _alive(child)
        svc.send_signal(signal.SIGKILL)  # no atexit, no daemon clean-up: only the watch
        svc.wait(10)
        deadline = time.monotonic() + wait
        while time.monotonic() < deadline and _alive(child):
            time.sleep(0.05)
        return _alive(child)
    finally:
        if _alive(child):
            os.kill(child, signal.SIGKILL)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_busy_child_leaves_when_its_service_is_killed() -> None:
    assert not _orphan_lives(watch=True, wait=5.0)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_without_the_watch_a_busy_child_outlives_its_service() -> None:
    # the control: what the physics worker did before (it left only on its next read)
    assert _orphan_lives(watch=False, wait=1.0)


def test_poll_must_be_positive() -> None:
    with pytest.raises(ValueError, match="poll must be > 0"):
        exit_when_orphaned(os.getpid(), poll=0.0)
