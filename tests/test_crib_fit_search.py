"""The channel fit's forward runs and search (``sim_core.diagnosis.crib_fit``, issue 26) on the
demo site's ballasted track, with records the twin makes itself (``crib_synthetic``):

- a run over the windows only (``CribSite.run_spans``) reads what the whole stretch reads
  inside them, and the round template outside, for a fraction of the stepping;
- a worn flat longer than the length grid's longest (105 mm) is found within 10 %: the
  refinement steps half a grid step beyond the grid's end and runs again, at their aligned
  phase, the runs it steps from (a whole step, to 168 mm, drew the fit 10-20 % short).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from schemas.messages import WheelPassage
from service.physics.diagnosis import Diagnoser
from service.wire.site import load_site
from sim_core.diagnosis.crib_fit import _Search, anchor, fit_channels, flat_of
from sim_core.diagnosis.crib_forward import CribWheel
from sim_core.diagnosis.crib_screen import round_template
from sim_core.diagnosis.crib_synthetic import crib_record
from tests.conftest import ROOT

SITE = load_site(ROOT / "examples" / "site.toml")
RADIUS, LOAD, MASS = 0.46, 80e3, 600.0


@pytest.fixture(scope="module")
def diagnoser() -> Diagnoser:
    d = Diagnoser(SITE)
    d.warm_up()
    return d


def _wheel(d: Diagnoser, speed: float) -> CribWheel:
    p = WheelPassage(
        passage_id="fit",
        train_id="t",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=speed,
        load=LOAD,
        mass=MASS,
        radius=RADIUS,
    )
    return CribWheel(MASS, LOAD, RADIUS, d.physics.contact_model(p))


def test_a_run_over_the_windows_reads_the_whole_stretch_there(diagnoser: Diagnoser) -> None:
    cs = diagnoser.crib_site
    assert cs is not None
    speed = 15.0
    wheel = _wheel(diagnoser, speed)
    flat = flat_of(RADIUS, "flat", 0.04, 1.0)
    rec = crib_record(
        cs, wheel, speed, flat, sample_rate=10_000.0, noise_fraction=0.0, roughness_rms=0.0, seed=1
    )
    t = rec.t
    tpl = round_template(cs.cribs, speed, LOAD, t, cs.sensor)
    inside = cs.in_fit_stretch(t, speed)
    search = _Search(
        cs,
        wheel,
        speed,
        t,
        rec.channels,
        tpl,
        anchor(np.sum(rec.channels - tpl, axis=0), t, inside, speed),
    )
    assert search.spans and search.windows == len(search.spans)
    c0 = time.process_time()
    whole = cs.run(wheel, speed, flat, t)
    c1 = time.process_time()
    part = cs.run(wheel, speed, flat, t, spans=search.spans)
    c2 = time.process_time()
    m = search.mask
    # at 15 m/s a turn (2.9 m) lets the previous impact's wake die out on this track
    assert np.max(np.abs(part.channels[:, m] - whole.channels[:, m])) < 0.02 * LOAD
    before = t * speed < search.spans[0][0]  # not simulated: the round template
    assert np.array_equal(part.channels[:, before], tpl[:, before])
    assert part.peak_force == pytest.approx(whole.peak_force, rel=0.02)
    assert c2 - c1 < 0.7 * (c1 - c0)  # the windows are a small part of the stretch


@pytest.mark.parametrize(("kmh", "length"), [(45.0, 0.118), (110.0, 0.112)])
def test_a_worn_flat_longer_than_the_grid_is_found(
    diagnoser: Diagnoser, kmh: float, length: float
) -> None:
    cs = diagnoser.crib_site
    assert cs is not None
    speed = kmh / 3.6
    wheel = _wheel(diagnoser, speed)
    truth = flat_of(RADIUS, "rounded_flat", length, 2.0)
    rec = crib_record(
        cs,
        wheel,
        speed,
        truth,
        sample_rate=10_000.0,
        noise_fraction=0.015,
        roughness_rms=3e-6,
        seed=11,
    )
    est = fit_channels(cs, wheel, speed, rec.t, rec.channels)
    assert est.flat is not None and est.best_kind == "rounded_flat"
    assert est.flat.length == pytest.approx(length, rel=0.1)
    assert est.length_low <= length <= est.length_high


def test_a_flat_cost_gives_the_search_range_not_an_extrapolation() -> None:
    """A record a flat barely changes (the demo's axle 13: a measured outline the haversine
    does not fit, costs within 0.03 % over 7-12 mm) gives a parabola so shallow that its χ²
    bound lay at 1 µm and 104 m: the interval is clipped to the lengths the search may try."""
    from types import SimpleNamespace

    from sim_core.diagnosis.crib_fit import LENGTH_RANGE, Trial, _interval

    costs = {0.0074: 6.48979e10, 0.0094: 6.49057e10, 0.0106: 6.47606e10, 0.0119: 6.47791e10}
    costs |= {0.015: 6.56583e10, 0.025: 8.59230e10, 0.04: 1.25633e11, 0.065: 1.77267e11}
    trials = [
        Trial("rounded_flat", length, 0.0, cost, 0.0, None)  # type: ignore[arg-type]
        for length, cost in costs.items()
    ]
    best = trials[2]
    search = SimpleNamespace(trials=trials, windows=2)
    low, high = _interval(search, "rounded_flat", best)  # type: ignore[arg-type]
    assert (low, high) == LENGTH_RANGE
    # a well-curved cost keeps its own interval, inside the range
    curved = [
        Trial("flat", length, 0.0, 1e9 * (1.0 + 50.0 * np.log(length / 0.04) ** 2), 0.0, None)  # type: ignore[arg-type]
        for length in (0.025, 0.04, 0.065)
    ]
    low, high = _interval(SimpleNamespace(trials=curved, windows=2), "flat", curved[1])  # type: ignore[arg-type]
    assert LENGTH_RANGE[0] < low < 0.04 < high < LENGTH_RANGE[1]
    assert high / 0.04 == pytest.approx(0.04 / low, rel=1e-9)
