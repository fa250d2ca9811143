"""The reduction's shortcuts against the plain computation they replace (issue 26's speed).

- The static compliance blocks K⁻¹[e, e] of the kept elements come from a sparse LU of K
  solved for their columns only: the same as a dense inverse's to 1e-10 relative (rounding
  is ~1e-13), on a ballasted and a slab track, at the calibration's settings and the twin's.
- A track that differs in its damping alone reuses the undamped modes: the ModalTrack is the
  same to the bit as one reduced from scratch, and the generalized eigen-solve is not run.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import pytest
import scipy.linalg as sla

from sim_core.calibration import forward
from sim_core.track import modal
from sim_core.track.assembly import TrackMatrices, assemble
from sim_core.track.layout import ABSORBER_BAYS, ELEMENTS_PER_BAY, MARGIN_BAYS, layout
from sim_core.track.spec import Crib, Support, TrackSpec

BALLASTED = TrackSpec.discrete(
    sleeper_spacing=0.6,
    first_sleeper=0.3,
    pad=Support(2.0e8, 3.0e4),
    sleeper_mass=150.0,
    ballast=Support(1.2e8, 8.0e4),
)
SLAB = TrackSpec.slab(sleeper_spacing=0.65, first_sleeper=0.3, pad=Support(5.0e7, 2.0e4))
CRIBS = (Crib("c1", 0.45, 0.85), Crib("c2", 1.05, 1.45))
X0, X1 = -0.6, 2.0
CALIBRATION = {
    "cutoff": forward.CUTOFF,
    "elements_per_bay": forward.ELEMENTS_PER_BAY,
    "absorber_bays": forward.ABSORBER_BAYS,
    "margin_bays": forward.MARGIN_BAYS,
}
TWIN: dict[str, float] = {"cutoff": modal.CUTOFF}
FIELDS = (
    "lam",
    "weight",
    "rows",
    "elem_x",
    "elem_len",
    "elem_phi",
    "resid",
    "bubble",
    "crib_rows",
    "fe_compliance_blocks",
)


def _matrices(track: TrackSpec, settings: dict[str, float]) -> TrackMatrices:
    gauges = tuple(g for c in CRIBS for g in (c.x_a, c.x_b))
    lay = layout(
        track,
        X0,
        X1,
        gauges=gauges,
        elements_per_bay=int(settings.get("elements_per_bay", ELEMENTS_PER_BAY)),
        absorber_bays=int(settings.get("absorber_bays", ABSORBER_BAYS)),
        margin_bays=int(settings.get("margin_bays", MARGIN_BAYS)),
    )
    return assemble(track, lay)


@pytest.mark.parametrize("track", [BALLASTED, SLAB], ids=["ballasted", "slab"])
@pytest.mark.parametrize("settings", [CALIBRATION, TWIN], ids=["calibration", "twin"])
def test_compliance_blocks_are_the_dense_inverse(
    track: TrackSpec, settings: dict[str, float]
) -> None:
    mats = _matrices(track, settings)
    cutoff = float(settings["cutoff"])
    mt = modal._modal(mats, cutoff, CRIBS, X0, X1)
    kinv = np.linalg.inv(mats.k)
    w2, phi = sla.eigh(
        mats.k, mats.m, subset_by_value=(-np.inf, (2 * np.pi * cutoff) ** 2), driver="gvx"
    )
    first = mt.first_element
    blocks = np.array(
        [kinv[2 * e : 2 * e + 4, 2 * e : 2 * e + 4] for e in range(first, first + mt.elem_x.size)]
    )
    phi_r = phi[: mats.n_rail_dofs]
    resid = np.array(
        [
            blocks[k] - (phi_r[2 * e : 2 * e + 4] / w2) @ phi_r[2 * e : 2 * e + 4].T
            for k, e in enumerate(range(first, first + mt.elem_x.size))
        ]
    )
    assert mt.elem_x.size > 10
    scale = np.max(np.abs(blocks))
    assert np.max(np.abs(mt.fe_compliance_blocks - blocks)) < 1e-10 * scale
    assert np.max(np.abs(mt.resid - resid)) < 1e-10 * scale
    # and the reduced model still holds the FE model's static compliance
    for x in (0.3, 0.61, 1.2):
        assert mt.static_compliance(x) == pytest.approx(mt.fe_static_compliance(x), rel=1e-9)


def _reduced(track: TrackSpec) -> modal.ModalTrack:
    """``track`` reduced as the calibration's forward model reduces it."""
    return modal.reduce_track(
        track,
        X0,
        X1,
        CRIBS,
        cutoff=forward.CUTOFF,
        elements_per_bay=forward.ELEMENTS_PER_BAY,
        absorber_bays=forward.ABSORBER_BAYS,
        margin_bays=forward.MARGIN_BAYS,
    )


@pytest.mark.parametrize("track", [BALLASTED, SLAB], ids=["ballasted", "slab"])
def test_a_damping_change_reuses_the_undamped_modes_exactly(
    track: TrackSpec, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("RAILTWIN_TRACK_CACHE", "off")
    modal._UNDAMPED.clear()
    modal._reduce.cache_clear()
    calls = []
    real = sla.eigh

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(modal.sla, "eigh", counted)
    _reduced(track)
    assert len(calls) == 1
    ballast = None if track.ballast is None else Support(track.ballast.stiffness, 5.0e4)
    damped = dataclasses.replace(track, pad=Support(track.pad.stiffness, 4.4e4), ballast=ballast)
    reused = _reduced(damped)
    assert len(calls) == 1  # the modes came from the first reduction
    # a stiffness change is a new eigen-solve
    stiffer = dataclasses.replace(track, pad=Support(1.05 * track.pad.stiffness, 3.0e4))
    _reduced(stiffer)
    assert len(calls) == 2
    modal._UNDAMPED.clear()
    modal._reduce.cache_clear()
    fresh = _reduced(damped)
    assert len(calls) == 3
    assert fresh is not reused
    for f in FIELDS:
        assert np.array_equal(getattr(fresh, f), getattr(reused, f)), f
    # the damping did change the modes' decay
    base = _reduced(track)
    assert base.lam.shape != reused.lam.shape or not np.allclose(
        np.sort(base.lam.real), np.sort(reused.lam.real)
    )
    modal._reduce.cache_clear()
    modal._UNDAMPED.clear()
