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
    assert "no site file" in capsys.readouterr().err


def test_every_group_step_is_known_and_an_unknown_one_refused() -> None:
    steps = [s for group in warm.GROUPS.values() for s in group]
    assert sorted(steps) == ["constraint", "events", "passage"]  # each compiled once
    with pytest.raises(ValueError, match="unknown warm-up step"):
        warm.warm_group(("everything",))


def test_default_jobs_is_at_most_the_groups_and_at_least_one() -> None:
    assert 1 <= warm._default_jobs() <= len(warm.GROUPS)
