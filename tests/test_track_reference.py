"""The discrete and slab track against the independent reference solver (validation/data/track):
two of its six cases through the scenario runner, as ``railtwin simulate`` runs them
(``make validate-track`` runs all six and ROSE's)."""

from __future__ import annotations

import pytest

from validation.track_validation import P_TOL_REF, reference_cases, run_reference_case


@pytest.mark.parametrize("case_id", ["T02", "T06"])
def test_reference_case(case_id: str) -> None:
    case = next(c for c in reference_cases() if c["id"] == case_id)
    row = run_reference_case(case)
    assert abs(row.peak_rel) <= P_TOL_REF
    assert row.losses == row.losses_ref
    assert row.channel_err_away <= row.channel_allowed
