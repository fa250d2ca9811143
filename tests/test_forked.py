"""``sim_core.diagnosis.forked.Forked``: a value from a forked child, or None and the caller
computes it; never a leaked or orphaned child."""

from __future__ import annotations

import os
import threading
import time

import pytest

from sim_core.diagnosis.forked import Forked


@pytest.fixture
def alone() -> None:
    """Forked forks only when no other thread runs; a thread left by an earlier test would
    make these tests meaningless, not wrong."""
    if threading.active_count() > 1:
        pytest.skip(f"{threading.active_count() - 1} other threads alive: Forked will not fork")


def _boom() -> int:
    raise ValueError("in the child")


def test_the_childs_value_comes_back(alone: None) -> None:
    with Forked(lambda: {"a": [1.5, 2.5]}) as child:
        assert child.result() == {"a": [1.5, 2.5]}


def test_a_failing_child_gives_none(alone: None) -> None:
    with Forked(_boom) as child:
        assert child.result() is None


def test_a_parent_that_raises_kills_and_reaps_the_child(alone: None) -> None:
    pid = 0
    with pytest.raises(RuntimeError, match="parent"), Forked(lambda: time.sleep(60)) as child:
        pid = child._pid
        assert pid > 0
        raise RuntimeError("the parent's own half failed")
    assert child._pid == 0
    with pytest.raises(ChildProcessError):  # reaped already: no zombie left
        os.waitpid(pid, os.WNOHANG)


def test_no_fork_while_other_threads_run() -> None:
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        with Forked(lambda: 1) as child:
            assert child._pid == 0 and child.result() is None
            assert child.value() == 1  # computed here instead
    finally:
        stop.set()
        other.join()
