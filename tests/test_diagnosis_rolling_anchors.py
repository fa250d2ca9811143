"""Each turn's anchor is its first impact after rolling, not a landing after a bounce
(``turns.first_impact_after_rolling``, ``FitOptions.rolling_anchors``; docs/diagnosis.md).

The walk is checked on records built sample by sample, then on the wide set's W30, where a
107 mm fresh flat at 90 km/h throws the wheel and it lands 19 ms after the impact, harder
than it hit."""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from service.physics.diagnosis import Diagnoser
from sim_core.diagnosis.estimate import contact_floor, record_noise
from sim_core.diagnosis.turns import find_anchors, first_impact_after_rolling
from validation.wide_set import WIDE_DIR, load_case

ROLL = 30  # samples of contact that count as rolling in the built records


def _record(*parts: tuple[float, int]) -> np.ndarray:
    """A record of (force, samples) pieces."""
    return np.concatenate([np.full(n, v) for v, n in parts])


def test_a_landing_after_a_bounce_walks_back_to_the_impact() -> None:
    f = _record((1.0, 100), (0.0, 20), (6.0, 10), (0.0, 150), (20.0, 10), (0.0, 5))
    landing = 100 + 20 + 10 + 150 + 5
    assert first_impact_after_rolling(f, landing, 0.1, 400, ROLL) == 120


def test_several_bounces_walk_back_to_the_first() -> None:
    f = _record((1.0, 100), (0.0, 20), (6.0, 10), (0.0, 40), (3.0, 10), (0.0, 40), (9.0, 10))
    assert first_impact_after_rolling(f, f.size - 5, 0.1, 400, ROLL) == 120


def test_an_impact_reached_in_contact_or_after_rolling_stays() -> None:
    rolled_into = _record((1.0, 100), (0.5, 20), (6.0, 10), (1.0, 50))
    assert first_impact_after_rolling(rolled_into, 125, 0.1, 400, ROLL) == 125
    thrown = _record((1.0, 100), (0.0, 20), (6.0, 10), (1.0, 50))  # first impact after a flight
    assert first_impact_after_rolling(thrown, 125, 0.1, 400, ROLL) == 125


def test_a_wheel_bouncing_all_the_way_back_keeps_its_largest_peak() -> None:
    # impacts every 30 samples, never 30 samples of contact: no rolling within reach
    f = np.tile(_record((0.0, 25), (4.0, 5)), 12)
    f[-3] = 9.0
    assert first_impact_after_rolling(f, f.size - 3, 0.1, 200, ROLL) == f.size - 3


def test_a_dip_is_not_walked() -> None:
    f = _record((1.0, 100), (0.0, 20), (6.0, 10), (0.0, 40))
    assert first_impact_after_rolling(f, 150, 0.1, 400, ROLL) == 150


def test_w30s_anchors_move_from_the_landings_to_the_impacts_and_its_length_is_found() -> None:
    c = load_case("W30")
    meta = json.loads((WIDE_DIR / "W30.json").read_text(encoding="utf-8"))
    v = c.passage.speed
    centres = np.array(meta["truth"]["flat_centre_bottom_x_in_site"]) / v
    f = np.asarray(c.measured.force)
    t = c.measured.t_start + np.arange(f.size) / c.measured.sample_rate
    P, R = c.passage.load, c.passage.radius
    floor = contact_floor(P, record_noise(f))
    largest = find_anchors(t, f, P, R, v).times
    walked = find_anchors(t, f, P, R, v, contact_floor=floor)
    first = walked.times
    # without the walk, the first turn's anchor is the landing 20 ms after the flat's centre
    assert largest[0] - centres[0] > 0.015
    # with it, the trailing corner's impact, within the half flat (2.2 ms) and the chain's
    # delay of the centre
    assert 0.0 < first[0] - centres[0] < 0.004
    # the second turn arrives bouncing and keeps its landing, 30 ms after the flat: the
    # anchors' spacing (1.25 turns) is not the period, the fold's is
    assert abs(first[1] - centres[1]) > 0.02
    assert abs(walked.period / (centres[1] - centres[0]) - 1.0) < 0.01
    d = Diagnoser(c.site)
    diag, _ = d.diagnose(c.passage, c.measured)
    assert diag.flat is not None and diag.flat.length_low is not None
    true = meta["truth"]["flat_length_m"]
    assert abs(diag.flat.length - true) <= 0.1 * true
    assert diag.flat.length_low <= true <= diag.flat.length_high
    # and the landing anchors, the way it was, miss it
    d.options = dataclasses.replace(d.options, rolling_anchors=False)
    before, _ = d.diagnose(c.passage, c.measured)
    assert before.flat is not None and abs(before.flat.length - true) > 0.1 * true
