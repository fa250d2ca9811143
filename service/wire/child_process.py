"""Starting the service's child processes (physics workers, the recorder) shielded from the
signals that stop the service.

A service manager stops a service by sending SIGTERM to its whole process group. A child
must not die of it: the service stops its children itself (through their pipes), so that a
passage in flight is answered and the MCAP file gets its footer. Each child ignores SIGINT
and SIGTERM once it runs (``ignore_stop_signals``), and to cover the moment before (a
``spawn`` child spends a second importing), ``start_shielded`` starts it with both blocked:
the child inherits the mask, and a signal that comes meanwhile stays pending until the child
ignores it.

multiprocessing's resource tracker, started with the first child, unblocks both in the
starting thread after it has started itself: it is started first, outside the mask.
"""

from __future__ import annotations

import signal
from multiprocessing import resource_tracker
from multiprocessing.process import BaseProcess

STOP_SIGNALS = frozenset({signal.SIGINT, signal.SIGTERM})
"""What a terminal or a service manager sends to stop the service."""


def start_shielded(process: BaseProcess) -> None:
    """``process.start()`` with the stop signals blocked (the child inherits the mask)."""
    resource_tracker.ensure_running()  # it would unblock them in this thread while starting
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        process.start()
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def ignore_stop_signals() -> None:
    """In the child, first thing: ignore the stop signals, then unblock them (one that came
    while they were blocked is dropped)."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
