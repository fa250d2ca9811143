"""The fit's worn-flat tables start from a coarser grid (``WORN_TABLE_DX``): the templates
they give are those of the default grid, to well within what a fit resolves."""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.diagnosis.estimate import make_flat
from sim_core.diagnosis.forward import (
    RailTables,
    simulate_window,
    wheel_table,
    with_damping_ratio,
)
from sim_core.rail import RailProfile
from tests.test_integrator_end import WHEEL


@pytest.mark.parametrize("length", [0.02, 0.06, 0.11])
def test_worn_templates_match_the_default_grid(length: float) -> None:
    R, v = WHEEL.radius, 30.0
    flat = make_flat(R, "rounded_flat", length, 1.1)
    half = 0.5 * length / v
    t0, t1 = -(half + 4e-3), half + 0.02
    coarse = wheel_table(R, flat, RailTables(RailProfile.flat()), v * t0, v * t1)
    fine = tabulate_constraint(flat.outline(R), RailProfile.flat(), v * t0 - 0.02, v * t1 + 0.02)
    assert coarse.x.size < 0.7 * fine.x.size  # the point of it
    wheel = with_damping_ratio(WHEEL, 0.1)
    a = simulate_window(wheel, v, coarse, t0, t1, 75000.0).force
    b = simulate_window(wheel, v, fine, t0, t1, 75000.0).force
    assert float(np.max(np.abs(a - b))) < 1e-6 * WHEEL.load
