"""Smoke test of the core benchmark: its cases are valid and a tiny version runs end to end.

Nothing here is about speed (no timing is ever asserted); only that ``make bench``
has working case builders, that the SciPy peer agrees on a short window and that
the result carries the keys the tables and ``results.json`` read.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

pytest.importorskip("scipy")

from benchmarks import core_bench
from sim_core.constraint.table import ConstraintTable
from sim_core.passage import PassageSpec


def test_case_builders_give_valid_specs() -> None:
    table, spec = core_bench.resonance_case(periods=2)
    assert isinstance(table, ConstraintTable) and isinstance(spec, PassageSpec)
    assert math.isclose(spec.speed / 0.05, 280.0)
    assert math.isclose(spec.duration, 2 / 280.0)
    table, spec = core_bench.flat_compliant_case(turns=0.25)
    assert spec.foundation.is_compliant
    assert math.isclose(spec.foundation.mass, 4000.0)
    assert 2.2e8 < spec.foundation.stiffness < 2.4e8
    assert table.kinks.size >= 1
    _, rail, spec = core_bench.multipass_case(duration=0.005)
    assert rail.kind == "flat"
    assert spec.contact.law.is_plastic and spec.initial is not None
    assert spec.initial.v_c == -0.3
    _, rail = core_bench.tabulation_case(length=0.3)
    assert rail.kind == "sampled" and np.allclose(np.diff(rail.x), 1e-4)


def test_tiny_passage_bench_and_peer_agree() -> None:
    table, spec = core_bench.resonance_case(periods=3)
    res = core_bench.bench_passage("a", "tiny", table, spec, repeats=1)
    for key in (
        "simulated_s",
        "wall_s",
        "rtf",
        "rtol",
        "steps_per_sim_s",
        "rejected_per_sim_s",
        "rhs_per_sim_s",
        "transitions",
    ):
        assert key in res
    for peer in ("scipy_events", "scipy_plain"):
        assert {"wall_s", "ratio", "rtf"} <= res[peer].keys()
    ag = res["agreement"]
    assert ag["transitions_ours"] == ag["transitions_scipy"] > 0
    assert ag["same_sequence"]
    assert ag["peak_rel_diff"] < 1e-4
    assert ag["max_dt"] < 1e-7


def test_tiny_multipass_and_tabulation() -> None:
    res = core_bench.bench_multipass(wheels=2, peer_wheels=1, duration=0.01)
    assert {"wall_per_wheel_s", "scipy_events", "agreement", "max_dent_m"} <= res.keys()
    assert res["max_dent_m"][0] > 0  # the case dents
    assert res["agreement"]["same_sequence"]
    tb = core_bench.bench_tabulation(length=1.1, repeats=1, brute_points=4)
    assert {"wall_s", "brute_extrapolated_s", "ratio", "max_abs_diff_m"} <= tb.keys()
    # vertex-only brute force vs the exact polyline envelope: within dx²/(8R)
    assert tb["max_abs_diff_m"] < 1e-8


def test_markdown_has_every_section() -> None:
    table, spec = core_bench.resonance_case(periods=2)
    res = {
        "rtol": 1e-9,
        "repeats": 1,
        "cases": [core_bench.bench_passage("a", "tiny", table, spec, repeats=1, peer=False)],
    }
    text = core_bench.markdown(res)
    assert "| tiny |" in text and "real-time factor" in text


def test_every_benchmark_import_resolves() -> None:
    """Each ``from railtwin-module import name`` in benchmarks/ and validation/ names a module
    that exists and a name it has (a benchmark's lazy import of a moved module broke
    ``make bench`` once, and ``diagnosis_train_bench``'s of a moved function later)."""
    import ast
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    ours = ("service", "sim_core", "schemas", "benchmarks", "validation")
    missing = []
    for path in [*root.glob("benchmarks/*.py"), *root.glob("validation/*.py")]:
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(ours):
                assert node.module is not None
                if importlib.util.find_spec(node.module) is None:
                    missing.append(f"{path.relative_to(root)}: {node.module}")
                    continue
                # and the names it takes from there (a moved function broke one once more)
                mod = importlib.import_module(node.module)
                for alias in node.names:
                    if alias.name == "*" or hasattr(mod, alias.name):
                        continue
                    is_package = hasattr(mod, "__path__")
                    if (
                        not is_package
                        or importlib.util.find_spec(f"{node.module}.{alias.name}") is None
                    ):
                        missing.append(f"{path.relative_to(root)}: {node.module}.{alias.name}")
    assert not missing, missing
