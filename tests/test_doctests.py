"""The worked examples in sim_core's docstrings stay true: doctest.testmod on every module."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import sim_core

MODULES = sorted(m.name for m in pkgutil.walk_packages(sim_core.__path__, prefix="sim_core."))
MODULES += ["service.physics.inputs"]


def test_every_module_is_listed() -> None:
    for name in (
        "materials",
        "contact_laws",
        "constraint",
        "constraint.table",
        "passage",
        "integrate.loop",
        "integrate.tableau",
        "track.modal",
        "dents",
    ):
        assert f"sim_core.{name}" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} doctest(s) failed in {name}"
