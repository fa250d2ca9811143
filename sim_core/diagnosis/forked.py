"""One call in a forked child process: a second core for a diagnosis without the GIL.

The fit's two kinds are searched independently, and much of each search is Python glue
around short compiled kernels, so threads barely overlap (measured: the fit's wall time did
not move with two threads). A child forked after everything is imported and compiled shares
the parent's memory copy-on-write, computes one kind, and sends its result back pickled
through a pipe; the parent computes the other meanwhile.

    >>> join = fork_call(lambda: sum(range(10)))
    >>> join()
    45

Where ``os.fork`` does not exist, or the child fails, ``join()`` gives ``None`` and the caller
computes the value itself: the answer never depends on whether a child helped.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable
from typing import TypeVar

__all__ = ["fork_call"]

T = TypeVar("T")


def fork_call(fn: Callable[[], T]) -> Callable[[], T | None]:
    """Start ``fn()`` in a forked child; the returned function waits for it and gives its
    result, or ``None`` if there is no fork or the child failed."""
    if not hasattr(os, "fork"):
        return lambda: None
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: compute, send, and leave without running any exit handler
        code = 0
        try:
            os.close(r)
            data = pickle.dumps(("ok", fn()), protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException as exc:  # whatever it was, the parent computes
            data = pickle.dumps(("error", f"{type(exc).__name__}: {exc}"))
            code = 1
        try:
            with os.fdopen(w, "wb") as out:
                out.write(data)
        finally:
            os._exit(code)
    os.close(w)

    def join() -> T | None:
        with os.fdopen(r, "rb") as inp:
            data = inp.read()
        os.waitpid(pid, 0)
        try:
            status, value = pickle.loads(data)
        except Exception:  # a child killed mid-write: computed here
            return None
        return value if status == "ok" else None

    return join
