"""One call in a forked child process: a second core for a diagnosis without the GIL.

The fit's two kinds are searched independently, and much of each search is Python glue
around short compiled kernels, so threads barely overlap (measured: the fit's wall time did
not move with two threads). A child forked after everything is imported and compiled shares
the parent's memory copy-on-write, computes one kind, and sends its result back pickled
through a pipe; the parent computes the other meanwhile.

    >>> with Forked(lambda: sum(range(10))) as child:
    ...     child.value()
    45

Where ``os.fork`` does not exist or fails, where other threads run (a fork would copy
their locks, held or not), or where the child fails, ``result()`` gives ``None`` and the
value is computed here instead (``value()``): the answer never depends on whether a child
helped.
Leaving the ``with`` block without asking for the result (the parent's own half raised)
kills the child and reaps it.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import signal
import threading
from collections.abc import Callable
from types import TracebackType
from typing import Generic, TypeVar

__all__ = ["Forked"]

T = TypeVar("T")


class Forked(Generic[T]):
    """``fn()`` started in a forked child (if it can be); ``result()`` waits for it."""

    def __init__(self, fn: Callable[[], T]) -> None:
        self._fn = fn
        self._pid = 0
        self._read = -1
        if not hasattr(os, "fork") or threading.active_count() > 1:
            return
        try:
            r, w = os.pipe()
        except OSError:
            return
        try:
            pid = os.fork()
        except OSError:
            os.close(r)
            os.close(w)
            return
        if pid == 0:  # the child: compute, send, and leave without running any exit handler
            code = 1
            try:
                os.close(r)
                try:
                    data = pickle.dumps(("ok", fn()), protocol=pickle.HIGHEST_PROTOCOL)
                    code = 0
                except BaseException as exc:  # whatever it was, the parent computes it
                    data = pickle.dumps(("error", type(exc).__name__))
                with os.fdopen(w, "wb") as out:
                    out.write(data)
            finally:
                os._exit(code)
        os.close(w)
        self._pid, self._read = pid, r

    def result(self) -> T | None:
        """The child's value, or None (no child, or it failed); reaps the child."""
        if self._pid == 0:
            return None
        try:
            with os.fdopen(self._read, "rb") as inp:
                data = inp.read()
        finally:
            self._read = -1
            self._reap()
        try:
            status, value = pickle.loads(data)
        except Exception:  # a child killed mid-write: computed here
            return None
        return value if status == "ok" else None

    def value(self) -> T:
        """The child's value, or ``fn()`` computed in this process if there is none."""
        got = self.result()
        return self._fn() if got is None else got

    def cancel(self) -> None:
        """Kill the child (if still there) and reap it; its value is dropped."""
        if self._pid == 0:
            return
        if self._read >= 0:
            os.close(self._read)
            self._read = -1
        with contextlib.suppress(ProcessLookupError):
            os.kill(self._pid, signal.SIGKILL)
        self._reap()

    def _reap(self) -> None:
        pid, self._pid = self._pid, 0
        with contextlib.suppress(ChildProcessError):  # SIGCHLD ignored: reaped already
            os.waitpid(pid, 0)

    def __enter__(self) -> Forked[T]:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.cancel()  # a no-op once result() has reaped it
