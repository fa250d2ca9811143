"""The scenario runner and the streaming site build their physics with one converter.

A scenario and a site describing the same wheel, rail, material and foundation
must produce the same ``sim_core`` objects and the same passage.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from schemas.messages import WheelPassage
from schemas.scenario import Scenario
from schemas.site import FileRail, SiteConfig
from service.physics import inputs as physics_inputs
from service.physics.scenario_runner import run_scenario
from service.physics.site_physics import SitePhysics

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _scenario(name: str) -> Scenario:
    return Scenario.model_validate(json.loads((EXAMPLES / name).read_text()))


def test_contact_model_carries_the_materials_johnson_coefficient() -> None:
    scenario = _scenario("cosine_johnson.json")
    w = scenario.wheel
    model, derived = physics_inputs.contact_model(
        scenario.contact, scenario.material, radius=w.radius, load=w.load, mass=w.mass
    )
    mat = physics_inputs.material(scenario.material)
    assert model.johnson_coefficient == mat.johnson_coefficient
    assert model.yield_force == derived.yield_force
    # MODEL.md §3: the laws are continuous at δ_Y
    assert model.coefficient * model.yield_indentation**1.5 == pytest.approx(model.yield_force)


def test_unresolved_file_rail_is_refused_with_its_kind() -> None:
    with pytest.raises(ValueError, match=r"'file'.*resolved"):
        physics_inputs.rail_profile(FileRail(kind="file", path="rail.csv"))


def test_scenario_and_site_simulate_the_same_passage() -> None:
    """The same wheel on the same cosine rail: the runner's forces equal the site's."""
    # 56 Hz excitation: well below resonance, so the comparison is not chaotic
    scenario = _scenario("compliant_foundation.json").model_copy(update={"speed": 2.8})
    w = scenario.wheel
    length = scenario.speed * scenario.duration
    site = SiteConfig.model_validate(
        {
            "site_id": "same",
            "length": length,
            "output_sample_rate": scenario.sample_rate,
            "rail": scenario.rail.model_dump(),
            "material": scenario.material.model_dump(),
            "contact": scenario.contact,
            "foundation": scenario.foundation.model_dump(),
            "rtol": scenario.rtol,
        }
    )
    passage = WheelPassage(
        passage_id="p",
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=scenario.speed,
        load=w.load,
        mass=w.mass,
        radius=w.radius,
        outline=w.outline,
        phase=w.phase,
    )
    from_site = SitePhysics(site).simulate(passage)
    from_runner = run_scenario(scenario)
    n = min(len(from_site.force), len(from_runner.series.force))
    assert n > 10
    np.testing.assert_allclose(from_site.force[:n], from_runner.series.force[:n], rtol=1e-6)


def test_sampled_rail_arrays_hold_the_schemas_floats_exactly() -> None:
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.uniform(1e-4, 1e-3, 5000)).tolist()
    y = (rng.normal(0.0, 1e-5, 5000) * 10.0 ** rng.integers(-300, 0, 5000)).tolist()
    rail = physics_inputs.rail_profile(
        Scenario.model_validate(
            {
                **json.loads((EXAMPLES / "sampled_rail.json").read_text()),
                "rail": {"kind": "sampled", "x": x, "y": y},
            }
        ).rail
    )
    assert rail.x.dtype == np.float64 and rail.x.tolist() == x and rail.y.tolist() == y
    assert physics_inputs.float_array([]).size == 0
    with pytest.raises(ValueError, match="expected numbers"):
        physics_inputs.float_array([0.0, "x"])  # type: ignore[list-item]
