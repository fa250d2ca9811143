"""``railtwin warm``: its inputs are checked before anything compiles, and its groups are known."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.cli import warm


def test_jobs_below_one_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert warm.main(["--jobs", "0"]) == 2
    assert "--jobs must be >= 1" in capsys.readouterr().err


def test_missing_site_file_is_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert warm.main(["--site", str(tmp_path / "nowhere.toml")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_every_step_is_known_and_an_unknown_one_refused() -> None:
    assert warm.plan_for(None).steps == ("passage", "sweeps", "searches", "events", "track", "rail")
    assert warm.plan_for(None).rails == ("flat", "cosine", "step", "sampled")
    with pytest.raises(ValueError, match="unknown warm-up step 'everything'"):
        warm.warm_group(("everything",))


def test_only_the_sites_needs_are_planned() -> None:
    """``--only-sites`` (make demo's first run): a rail on sleepers needs the track's stepper,
    not the lumped integrator; a lumped foundation the integrator, not the track; the
    constraint's paths only on the rails' kinds (a rail the contact law dents is also a
    sampled one)."""
    from service.wire.site import load_site

    discrete = load_site(warm.DEFAULT_SITES[0])
    compliant = load_site(warm.DEFAULT_SITES[1])
    p = warm.plan_for([discrete])
    assert p.steps == ("sweeps", "searches", "track", "rail")
    assert p.rails == (discrete.rail.kind,) == ("cosine",)
    q = warm.plan_for([compliant])
    assert "passage" in q.steps and "events" in q.steps and "track" not in q.steps
    plastic = discrete.model_copy(update={"contact": "hertz_plastic"})
    assert warm.plan_for([plastic]).rails == ("cosine", "sampled")
    both = warm.plan_for([discrete, compliant])
    assert set(both.steps) == set(p.steps) | set(q.steps)
    assert list(both.steps) == sorted(both.steps, key=lambda st: -warm.STEP_COST[st])


def test_unknown_constraint_part_or_rail_kind_is_refused() -> None:
    from sim_core.constraint import warm_up_constraint

    with pytest.raises(ValueError, match="unknown rail kind 'gravel'"):
        warm_up_constraint(rails=("gravel",))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown part 'boxes'"):
        warm_up_constraint(("boxes",))  # type: ignore[arg-type]


def test_the_track_step_runs_a_passage_with_a_crib() -> None:
    """A rail on sleepers has its own stepper (~30 s to compile): ``railtwin warm`` fills
    the cache with it too, with one short passage whose crib channel is finite."""
    assert warm.warm_group(("track",)) > 0.0


def test_both_example_sites_are_warmed_by_default() -> None:
    assert [p.name for p in warm.DEFAULT_SITES] == ["site.toml", "site_compliant.toml"]
    assert all(p.is_file() for p in warm.DEFAULT_SITES)


def test_sources_are_byte_compiled_where_python_writes_no_bytecode(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib.util
    import sys

    pkg = tmp_path / "warm_probe_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "mod.py").write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    assert warm.compile_sources(("warm_probe_pkg",))
    for source in (pkg / "__init__.py", pkg / "mod.py"):
        assert Path(importlib.util.cache_from_source(str(source))).is_file()
    with pytest.raises(ValueError, match="no package 'no_such_railtwin_pkg'"):
        warm.compile_sources(("no_such_railtwin_pkg",))
    assert all(importlib.util.find_spec(name) is not None for name in warm.PACKAGES)


def test_default_jobs_is_at_most_the_groups_and_at_least_one() -> None:
    assert 1 <= warm._default_jobs() <= len(warm.STEP_COST)


def test_a_process_outside_make_finds_the_warm_cache() -> None:
    """``.venv/bin/railtwin`` run from a shell (no ``NUMBA_CACHE_DIR``) uses the cache that
    ``make venv`` filled, ``<venv>/numba-cache``: a fresh clone's first ``railtwin
    diagnose`` took 74 s compiling into ``__pycache__`` before; a set variable is kept."""
    import os
    import subprocess
    import sys

    code = "import os, sim_core; print(os.environ.get('NUMBA_CACHE_DIR', ''))"
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    got = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.strip()
    if sys.prefix == sys.base_prefix:
        assert got == ""  # not in a venv: numba's own default
    else:
        assert got == os.path.join(sys.prefix, "numba-cache")
    kept = subprocess.run(
        [sys.executable, "-c", code],
        env={**env, "NUMBA_CACHE_DIR": "/tmp/elsewhere-cache"},
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert kept == "/tmp/elsewhere-cache"
