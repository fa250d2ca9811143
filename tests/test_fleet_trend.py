"""The fleet's growth trend: weighted least squares and the crossing's 95 % interval."""

from __future__ import annotations

import math
import random

import pytest

from service.fleet.trend import DAY, crossing, fit_trend


def test_exact_line_is_recovered_with_known_sigma_errors() -> None:
    t = [0.0, 1 * DAY, 3 * DAY, 6 * DAY]
    y = [0.030 + 0.002 * (ti / DAY) for ti in t]
    tr = fit_trend(t, y, [0.001] * 4)
    assert tr is not None
    assert tr.slope_per_day == pytest.approx(0.002, rel=1e-12)
    # chi² = 0 < dof: the stated sigmas stand (Birge ratio floored at 1)
    sxx = sum((ti / DAY - 2.5) ** 2 for ti in t)
    assert tr.slope_se_per_day == pytest.approx(0.001 / math.sqrt(sxx), rel=1e-12)
    assert tr.value_se == pytest.approx(0.001 / 2, rel=1e-12)
    c = crossing(tr, "remove", 0.060)
    assert c.status == "forecast"
    assert c.at == pytest.approx(15 * DAY, rel=1e-9)
    assert c.earliest is not None and c.latest is not None
    assert c.earliest < c.at < c.latest


def test_weights_follow_the_intervals() -> None:
    # a wide-interval outlier barely moves the line
    t = [0.0, DAY, 2 * DAY, 3 * DAY]
    tr = fit_trend(t, [0.03, 0.031, 0.032, 0.050], [0.0005, 0.0005, 0.0005, 0.05])
    assert tr is not None and tr.slope_per_day == pytest.approx(0.001, abs=5e-5)


def test_scatter_beyond_the_intervals_widens_the_error() -> None:
    t = [0.0, DAY, 2 * DAY, 3 * DAY, 4 * DAY]
    y = [0.030, 0.040, 0.032, 0.045, 0.038]
    tight = fit_trend(t, y, [1e-4] * 5)
    assert tight is not None and tight.chi2_per_dof is not None and tight.chi2_per_dof > 1
    assert tight.slope_se_per_day > 1e-4 / math.sqrt(10)  # scaled up by sqrt(chi2/dof)


def test_undetermined_and_not_growing() -> None:
    assert fit_trend([0.0], [0.03], [0.001]) is None
    assert fit_trend([5.0, 5.0], [0.03, 0.04], [0.001, 0.001]) is None
    assert fit_trend([0.0, DAY], [1.0, 2.0], None) is None  # unweighted needs 3
    tr = fit_trend([0.0, DAY, 2 * DAY], [0.05, 0.045, 0.04], [0.001] * 3)
    assert tr is not None and crossing(tr, "remove", 0.06).status == "not_growing"
    assert crossing(tr, "inspect", 0.035).status == "reached"
    with pytest.raises(ValueError):
        fit_trend([0.0, DAY], [0.03, 0.04], [0.0, 0.001])


def test_crossing_interval_covers_the_truth_about_95_percent() -> None:
    """Fieller's interval, checked by simulation: 6 noisy diagnoses over 10 days of a flat
    growing 1 mm/day from 30 mm; the true date of reaching 60 mm is day 30."""
    rng = random.Random(7)
    t = [i * 2 * DAY for i in range(6)]
    hits = trials = 0
    for _ in range(600):
        y = [0.030 + 0.001 * ti / DAY + rng.gauss(0, 0.002) for ti in t]
        tr = fit_trend(t, y, [0.002] * 6)
        assert tr is not None
        c = crossing(tr, "remove", 0.060)
        trials += 1
        upper = math.inf if c.latest is None else c.latest
        if c.earliest is not None and c.earliest <= 30 * DAY <= upper:
            hits += 1
    assert 0.92 <= hits / trials <= 0.98
