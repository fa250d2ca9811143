"""Shared fixtures: the repository's paths, the example scenarios, a CLI runner."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
EXAMPLE_SCENARIOS = sorted(EXAMPLES.glob("*.json"))

# The fleet tests' fixtures (a PostgreSQL server for the session, stores): one server for
# every module that uses them.
pytest_plugins = ("tests.fleet_support",)

# Tests never ask Rerun's CLI about analytics, and share one numba cache.
os.environ.setdefault("RERUN_ANALYTICS", "0")


@pytest.fixture
def contract_example() -> dict[str, Any]:
    """The scenario of CONTRACT.md, verbatim, as a fresh dict (safe to mutate)."""
    from schemas.scenario import EXAMPLE_JSON

    data: dict[str, Any] = json.loads(EXAMPLE_JSON)
    return data


def run_cli_subprocess(*args: str, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    """``python -m service.cli.main ARGS`` in a child process, from the repository root."""
    return subprocess.run(
        [sys.executable, "-m", "service.cli.main", *args],
        cwd=ROOT,
        input=stdin,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


@pytest.fixture
def cli() -> Callable[..., subprocess.CompletedProcess[str]]:
    return run_cli_subprocess


def pytest_sessionstart(session: pytest.Session) -> None:
    """Fill numba's compile cache before any test starts a service.

    Every ``railtwin serve`` warms up every constraint path in its worker process; from an
    empty cache (a fresh CI machine) that compiles for a minute or two, which would count
    against the first service test's start-up time. Compiled once here, each later
    process loads it from the cache in about a second.
    """
    from sim_core.constraint import warm_up_constraint

    warm_up_constraint()
