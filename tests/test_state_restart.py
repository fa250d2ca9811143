"""A plastic site's rail survives a restart; a passage id is never applied twice."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.cli.serve import open_state
from service.physics.rail_store import (
    STATE_SCHEMA,
    RailStore,
    StateMismatchError,
    physics_fingerprint,
)
from service.physics.worker import ProcessPhysics

SITE = SiteConfig.model_validate(
    {
        "site_id": "plastic",
        "length": 2.0,
        "output_sample_rate": 5000.0,
        "rail": {"kind": "flat"},
        "contact": "hertz_plastic",
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3, "yield_stress": 6e8},
    }
)


def _flat_wheel(pid: str) -> WheelPassage:
    return WheelPassage(
        passage_id=pid,
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=20.0,
        load=50e3,
        mass=500.0,
        radius=0.46,
        outline={"kind": "flat", "length": 0.05},
        phase=4.1,
    )  # flat at x = 1 m  # type: ignore[arg-type]


def test_restart_goes_on_from_the_dented_rail_and_remembers_applied_ids(tmp_path: Path) -> None:
    store = open_state(tmp_path, SITE)
    physics = ProcessPhysics(SITE, store=store, warm_up=False)
    physics.start()
    try:
        result = physics.simulate(_flat_wheel("p1"))
        before = physics.rail_state()
    finally:
        physics.close()
        store.close()
    assert result.summary.max_dent > 0.0 and before.revision == 1
    store = open_state(tmp_path, SITE)  # a new run
    physics = ProcessPhysics(SITE, store=store, warm_up=False)
    physics.start()
    try:
        after = physics.rail_state()
        assert after.revision == before.revision
        assert after.max_dent == pytest.approx(before.max_dent, rel=1e-12)
        assert after.y == pytest.approx(before.y, abs=1e-12)
        assert physics.already_applied("p1") == 1
        assert physics.already_applied("p2") is None
    finally:
        physics.close()
        store.close()


def _dented_state(directory: Path) -> None:
    """A state as a run leaves it: one passage applied, the rail at revision 1."""
    store = open_state(directory, SITE)
    store.commit("p1", 1, np.array([0.0, 1.0, 2.0]), np.array([0.0, -1e-5, 0.0]))
    store.close()


def _reopened(directory: Path, site: SiteConfig) -> tuple[int, int | None, int]:
    """(rail revision, revision p1 was applied at, passages applied) after reopening."""
    store = open_state(directory, site)
    try:
        rail = store.load()
        assert rail is not None
        return rail.revision, store.applied_revision("p1"), store.applied_count()
    finally:
        store.close()


def _edit(site: SiteConfig, **parts: Any) -> SiteConfig:
    """``site`` with some fields replaced, validated again (as a new site file would be)."""
    return SiteConfig.model_validate({**site.model_dump(), **parts})


@pytest.mark.parametrize(
    "edit",
    [
        {"diagnosis": {"watch_force": 240e3, "inspect_force": 300e3, "remove_force": 400e3}},
        {"output_sample_rate": 8000.0},
        {"description": "km 12, after the 2026 grinding campaign"},
        {"rtol": 1e-7},
    ],
    ids=["limits", "sample-rate", "description", "rtol"],
)
def test_what_does_not_change_the_dents_keeps_the_rail(
    tmp_path: Path, edit: dict[str, Any]
) -> None:
    _dented_state(tmp_path)
    assert _reopened(tmp_path, _edit(SITE, **edit)) == (1, 1, 1)


def test_a_railtwin_upgrade_keeps_the_rail(tmp_path: Path) -> None:
    _dented_state(tmp_path)
    path = tmp_path / "plastic.sqlite"
    store = RailStore(tmp_path, "plastic", physics_fingerprint(SITE), written_by="railtwin 99")
    store.close()
    assert _reopened(tmp_path, SITE) == (1, 1, 1)
    assert path.exists()


@pytest.mark.parametrize(
    ("edit", "named"),
    [
        ({"rail": {"kind": "cosine", "amplitude": 1e-5, "wavelength": 0.5}}, "the rail"),
        (
            {"material": {"youngs_modulus": 2.0e11, "poisson_ratio": 0.3, "yield_stress": 6e8}},
            "the material",
        ),
        ({"contact": "hertz"}, "the contact law"),
        (
            {"foundation": {"kind": "compliant", "stiffness": 1e9, "damping": 1e5, "mass": 100.0}},
            "the foundation",
        ),
        ({"length": 3.0}, "the site length"),
    ],
    ids=["rail", "material", "contact", "foundation", "length"],
)
def test_what_changes_the_dents_refuses_the_state_naming_it(
    tmp_path: Path, edit: dict[str, Any], named: str
) -> None:
    _dented_state(tmp_path)
    edited = _edit(SITE, **edit)
    with pytest.raises(StateMismatchError, match=f"{named} changed since") as err:
        open_state(tmp_path, edited)
    assert "move the state away" in str(err.value)
    assert isinstance(open_state(tmp_path / "other", edited), RailStore)
    assert _reopened(tmp_path, SITE) == (1, 1, 1)  # the refused state is untouched


def test_a_schema_1_state_is_migrated_keeping_rail_and_ids(tmp_path: Path) -> None:
    """Schema 1 (meta ``model_version``: a digest of the whole site file) opens as schema 2."""
    path = tmp_path / "plastic.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
        CREATE TABLE rail (id INTEGER PRIMARY KEY CHECK (id = 1), revision INTEGER NOT NULL,
                           x BLOB NOT NULL, y BLOB NOT NULL);
        CREATE TABLE applied (passage_id TEXT PRIMARY KEY, revision INTEGER NOT NULL);
    """)
    db.executemany(
        "INSERT INTO meta VALUES (?, ?)",
        [("site_id", "plastic"), ("model_version", "railtwin 0.1, site file 0123")],
    )
    x, y = np.array([0.0, 1.0, 2.0]), np.array([0.0, -2e-5, 0.0])
    db.execute("INSERT INTO rail VALUES (1, 3, ?, ?)", (x.tobytes(), y.tobytes()))
    db.executemany("INSERT INTO applied VALUES (?, ?)", [("p0", 2), ("p1", 3)])
    db.commit()
    db.close()
    store = open_state(tmp_path, SITE)
    try:
        assert store.migrated_from == 1
        rail = store.load()
        assert rail is not None and rail.revision == 3 and rail.y.tolist() == y.tolist()
        assert store.applied_revision("p1") == 3 and store.applied_count() == 2
        meta = store.meta()
        assert meta["state_schema"] == str(STATE_SCHEMA) and "model_version" not in meta
        assert meta["physics"] == physics_fingerprint(SITE)
    finally:
        store.close()
    again = open_state(tmp_path, SITE)  # now an ordinary schema-2 state
    assert again.migrated_from is None
    again.close()
    with pytest.raises(StateMismatchError, match="the rail changed since"):
        open_state(
            tmp_path, _edit(SITE, rail={"kind": "cosine", "amplitude": 1e-5, "wavelength": 0.5})
        )


def test_a_state_of_a_newer_railtwin_is_refused(tmp_path: Path) -> None:
    _dented_state(tmp_path)
    db = sqlite3.connect(tmp_path / "plastic.sqlite")
    db.execute("UPDATE meta SET value = ? WHERE key = 'state_schema'", (str(STATE_SCHEMA + 1),))
    db.commit()
    db.close()
    with pytest.raises(StateMismatchError, match="newer railtwin"):
        open_state(tmp_path, SITE)
