"""``validation.line_truth_reference``: the own generator's line-speed truth (the project's
integrator) agrees with the test suite's slow reference solver (SciPy DOP853, one contact
mode at a time, restarted at every kink of the constraint) on the same passage."""

from __future__ import annotations

import numpy as np

from validation import own_generator
from validation.line_truth_reference import reference_row, summary


def test_a_long_fresh_flat_at_line_speed_agrees_with_the_reference() -> None:
    row = reference_row(20261201, 1)  # fresh 89.8 mm at 44.44 m/s on a rough rail
    assert row is not None and row.kind == "flat"
    assert abs(row.error) <= 1e-5
    # "ours" is exactly the own generator's line-speed truth
    rng = np.random.default_rng(20261201)
    own_generator.skip_cases(1, rng)
    assert own_generator.run_case(1, rng)["line_truth"] == row.ours
    assert "largest relative difference" in summary([row])


def test_a_round_wheel_has_no_row() -> None:
    rng = np.random.default_rng(20261201)
    kinds = []
    for i in range(12):
        kinds.append(own_generator.draw_case(i, rng)[0])
        own_generator.draw_record(rng)
    i = kinds.index("round")
    assert reference_row(20261201, i) is None
