"""The track's modes in single precision (``sim_core.track.stepper.MODE_DTYPE``) against the same
stepper in double precision: a flat's impact with a loss and a return of contact, on a ballasted
track with a crib, read through every output.

At the usual step the two differ by ~3e-6 of P (force and channel) and ~1e-10 s (transitions);
a single-precision mode's error grows as the step shortens (``stepper.MODE_DTYPE``), ~1e-4 of P
at 0.5 µs. The bounds are 10-100x those, far below what the track's validation allows (2 % of
P), so the test depends on no last bit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim_core.constraint.tabulate import tabulate_constraint
from sim_core.contact_laws import ContactLaw, ContactModel
from sim_core.materials import Material, derive
from sim_core.passage import PassageOutput, PassageSpec
from sim_core.rail import RailProfile
from sim_core.track import modal, stepper
from sim_core.track.passage import simulate_on_track
from sim_core.track.spec import Crib, Support, TrackSpec
from sim_core.wheel import WheelOutline

LOAD = 85000.0
TRACK = TrackSpec.discrete(
    sleeper_spacing=0.6,
    first_sleeper=0.3,
    pad=Support(2.0e8, 3.0e4),
    sleeper_mass=150.0,
    ballast=Support(1.2e8, 8.0e4),
)


def _passage(
    dtype: type[np.floating], monkeypatch: pytest.MonkeyPatch, step: float
) -> PassageOutput:
    monkeypatch.setattr(stepper, "MODE_DTYPE", dtype)
    monkeypatch.setattr(modal, "MODE_DTYPE", dtype)
    d = derive(Material(2.14e11, 0.3), radius=0.46, load=LOAD, mass=700.0)
    spec = PassageSpec(
        mass=700.0,
        load=LOAD,
        speed=30.0,
        duration=0.03,
        sample_rate=20000.0,
        contact=ContactModel(ContactLaw.HERTZ, d.contact_coefficient),
        foundation=TRACK,
        cribs=(Crib("c1", 0.4, 0.8),),
    )
    wheel = WheelOutline.ideal_flat(0.46, 0.06)
    table = tabulate_constraint(wheel, RailProfile.flat(), 0.0, 0.9, phase=2 * math.pi - 0.5 / 0.46)
    model = modal.reduce_track(TRACK, 0.0, 0.9, spec.cribs)
    model.__dict__.pop("arrays", None)  # the stepper's view, in the patched precision
    try:
        return simulate_on_track(table, spec, TRACK, model=model, step=step)
    finally:
        model.__dict__.pop("arrays", None)


@pytest.mark.parametrize(
    ("step", "bound", "bound_t", "bound_y"),
    [(2e-5, 3e-4, 1e-8, 1e-8), (5e-7, 1e-3, 1e-7, 5e-7)],  # measured: 3e-6, 4e-11, 3e-10;
)  # 1.5e-4, 5.5e-9 s, 5.2e-8 m
def test_single_precision_modes_keep_every_output(
    monkeypatch: pytest.MonkeyPatch, step: float, bound: float, bound_t: float, bound_y: float
) -> None:
    single = _passage(np.float32, monkeypatch, step)
    double = _passage(np.float64, monkeypatch, step)
    assert [t.kind for t in single.transitions] == [t.kind for t in double.transitions]
    assert "loss" in [t.kind for t in double.transitions]
    for a, b in zip(single.transitions, double.transitions, strict=True):
        assert abs(a.t - b.t) < bound_t
    assert np.max(np.abs(single.force - double.force)) < bound * LOAD
    assert np.max(np.abs(single.channels["c1"] - double.channels["c1"])) < bound * LOAD
    assert single.peak_force == pytest.approx(double.peak_force, rel=bound / 10)
    assert np.max(np.abs(single.y_m - double.y_m)) < bound_y  # m, the rail under the wheel
