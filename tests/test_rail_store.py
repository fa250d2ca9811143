"""The site's rail state in SQLite: restored as committed, foreign state refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from service.physics.rail_store import RailStore, StateMismatchError


def test_state_survives_reopening_and_keeps_the_last_rail(tmp_path: Path) -> None:
    s = RailStore(tmp_path, "km12", "1.0")
    x = np.linspace(0, 6, 7)
    s.commit("a", 1, x, -1e-5 * x)
    s.commit("b", 1)  # elastic passage: applied, rail unchanged
    s.commit("c", 2, x, -2e-5 * x)
    s.close()
    s = RailStore(tmp_path, "km12", "1.0")
    st = s.load()
    assert st is not None and st.revision == 2
    assert np.array_equal(st.y, -2e-5 * x)
    assert [s.applied_revision(p) for p in ("a", "b", "c", "d")] == [1, 1, 2, None]


def test_state_of_another_site_or_version_is_refused(tmp_path: Path) -> None:
    RailStore(tmp_path, "km12", "1.0").close()
    (tmp_path / "km12.sqlite").rename(tmp_path / "km13.sqlite")
    with pytest.raises(StateMismatchError, match="belongs to site 'km12'"):
        RailStore(tmp_path, "km13", "1.0")
    RailStore(tmp_path, "km14", "1.0").close()
    with pytest.raises(StateMismatchError, match=r"model version '1\.0'"):
        RailStore(tmp_path, "km14", "2.0")
