"""A child process that leaves when the service that started it is gone.

The physics worker (``service.physics.worker``) spends its first minutes compiling
the physics (numba, no cache yet) and later runs passages that hold the GIL; in
neither does it read its pipe, so a service killed with SIGKILL (or by the
out-of-memory killer) used to leave it behind, compiling, until it next read. A
daemon thread that looks at the parent's pid once a second ends it instead: when
the service dies the child is re-parented (to init or a subreaper), its parent pid
changes, and the thread calls ``os._exit``. The thread runs between the compiler's
Python steps, so a compiling child leaves within about a second; a child inside a
compiled passage leaves when that passage returns (its wall-time budget bounds it).

Worked example: the service (pid 4100) spawns a worker; the service is killed;
the worker's ``os.getppid()`` becomes 1 and ``exit_when_orphaned(4100)``'s thread
ends the worker with exit code ``ORPHANED_EXIT``.
"""

from __future__ import annotations

import os
import threading
import time

ORPHANED_EXIT = 3
"""The exit code of a child that left because its service died."""

POLL_SECONDS = 1.0
"""How often the child looks at its parent's pid."""


def exit_when_orphaned(parent_pid: int, poll: float = POLL_SECONDS) -> threading.Thread:
    """Start a daemon thread that ends this process once its parent is no longer ``parent_pid``.

    Args:
        parent_pid: the pid of the process that started this one (passed in by it:
            if it is already gone when this runs, ``os.getppid()`` would not tell).
        poll: seconds between looks, > 0.

    Returns the started thread (tests join it; callers need not keep it).
    """
    if not poll > 0.0:
        raise ValueError(f"poll must be > 0 s, got {poll!r}")

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(ORPHANED_EXIT)
            time.sleep(poll)

    thread = threading.Thread(target=watch, name="railtwin-parent-watch", daemon=True)
    thread.start()
    return thread
