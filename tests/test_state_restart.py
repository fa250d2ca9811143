"""A plastic site's rail survives a restart; a passage id is never applied twice."""

from __future__ import annotations

from pathlib import Path

import pytest

from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.cli.serve import open_state
from service.physics.rail_store import RailStore, StateMismatchError
from service.physics.worker import ProcessPhysics

SITE = SiteConfig.model_validate({
    "site_id": "plastic", "length": 2.0, "output_sample_rate": 5000.0,
    "rail": {"kind": "flat"}, "contact": "hertz_plastic",
    "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3, "yield_stress": 6e8},
})


def _flat_wheel(pid: str) -> WheelPassage:
    return WheelPassage(passage_id=pid, train_id="t", axle_index=0, side="right", timestamp=0.0,
                        speed=20.0, load=50e3, mass=500.0, radius=0.46,
                        outline={"kind": "flat", "length": 0.05}, phase=4.1)  # flat at x = 1 m  # type: ignore[arg-type]


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


def test_state_of_an_edited_site_file_is_refused(tmp_path: Path) -> None:
    open_state(tmp_path, SITE).close()
    edited = SITE.model_copy(update={"length": 3.0})
    with pytest.raises(StateMismatchError, match="site file"):
        open_state(tmp_path, edited)
    assert isinstance(open_state(tmp_path / "other", edited), RailStore)
