"""The twin's online calibration: the per-wheel step and the range at their edges, a restart,
and the odd wheels it leaves out (``sim_core.calibration.recursive``,
``service.physics.online_calibration``), on a round wheel of the independent solver's S02
(``tests/data/calibration``: a slab whose nominal pad is 1.27 x too stiff)."""

from __future__ import annotations

import gzip
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage
from service.clients.measured_io import read_measured_csv
from service.physics.model_version import foundation_fingerprint
from service.physics.online_calibration import OnlineCalibration
from service.wire.site import load_site
from sim_core.calibration.recursive import Limits, start, update

DATA = Path(__file__).parent / "data" / "calibration"
SITE = load_site(DATA / "S02.site.toml")


def _wheel(tmp_path: Path, name: str = "S02_P11") -> tuple[WheelPassage, MeasuredPassage]:
    passage = WheelPassage.model_validate_json((DATA / f"{name}.json").read_text())
    csv = tmp_path / f"{name}.csv"
    with gzip.open(DATA / f"{name}.csv.gz", "rb") as src, csv.open("wb") as dst:
        shutil.copyfileobj(src, dst)
    return passage, read_measured_csv(csv, passage.passage_id, sample_rate=1e4)


# --- the limits, at their edges --------------------------------------------------------------


def _asking(step: float, z0: float = 0.0) -> tuple[float, bool, float]:
    """(applied, clamped, z after) of a wheel asking for ``step`` on one log-factor at z0:
    a Jacobian of 1e4 (the prior's 25 then weighs nothing: the request is step·1e8/(1e8+25))."""
    s = start(1, 0.2, (z0,))
    jac = np.array([[1.0e4]])
    want = step * (1e8 + 0.999 * 25.0) / 1e8
    new, u = update(s, jac, np.array([want * 1e4]), Limits(max_step=0.01, max_range=0.1))
    assert u.requested[0] == pytest.approx(step, rel=1e-12)
    return u.applied[0], u.clamped, new.z[0]


def test_a_step_within_the_rate_limit_is_made_as_asked() -> None:
    applied, clamped, z = _asking(0.0099)
    assert applied == pytest.approx(0.0099, rel=1e-12) and not clamped and z == applied


def test_a_step_beyond_the_rate_limit_is_cut_to_it() -> None:
    for ask in (0.0101, 0.5, -3.0):
        applied, clamped, _ = _asking(ask)
        assert applied == math.copysign(0.01, ask) and clamped


def test_the_range_holds_at_its_edge() -> None:
    applied, clamped, z = _asking(0.006, z0=0.095)  # 0.101 asked: the range is 0.1
    assert z == 0.1 and applied == pytest.approx(0.005, abs=1e-15) and clamped
    applied, clamped, z = _asking(0.004, z0=0.095)  # 0.099: inside
    assert z == pytest.approx(0.099, abs=1e-15) and not clamped


# --- a real wheel -----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def learned(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, OnlineCalibration]:
    tmp = tmp_path_factory.mktemp("online")
    oc = OnlineCalibration(SITE, tmp / "state")
    passage, measured = _wheel(tmp)
    step = oc.observe(passage, measured, None)
    assert step is not None
    return tmp, oc


def test_a_round_wheel_moves_the_pad_toward_the_truth_by_the_step_limit(
    learned: tuple[Path, OnlineCalibration],
) -> None:
    _, oc = learned
    step = oc.history[-1]
    truth = json.loads((DATA / "S02_truth.json").read_text())
    wanted = math.log(truth["track_true"]["k_p"] / truth["track_nominal"]["k_p"])  # -0.236
    assert wanted < -0.2
    # the wheel asks for a softer pad (this fast wheel sees 1.13 x its noise on the nominal)
    assert step.requested[0] < -0.01
    assert step.applied[0] == -0.01  # and gets the per-wheel limit, no more
    assert step.residual_ratio == pytest.approx(1.06, abs=0.03)  # its own noise from MAD
    assert oc.factors[0] == pytest.approx(math.exp(-0.01), rel=1e-12)
    assert oc.state.wheels == 1


def test_the_calibration_survives_a_restart(learned: tuple[Path, OnlineCalibration]) -> None:
    tmp, oc = learned
    again = OnlineCalibration(SITE, tmp / "state")
    assert again.state == oc.state
    assert again.history == oc.history
    site = again.site()
    assert site.calibration is not None and site.calibration.source == "online"
    assert site.calibration.id == foundation_fingerprint(site.foundation) == oc.ref().id
    assert site.calibration.wheels == 1
    assert site.foundation.pad.stiffness == pytest.approx(  # type: ignore[union-attr]
        SITE.foundation.pad.stiffness * math.exp(-0.01)  # type: ignore[union-attr]
    )
    assert "pad.stiffness x0.990" in again.drift().line()
    # a site file with another foundation starts afresh
    other = SITE.model_copy(
        update={"foundation": SITE.foundation.model_copy(update={"sleeper_spacing": 0.6})}
    )
    assert OnlineCalibration(other, tmp / "state").state.wheels == 0


def test_odd_and_flat_wheels_are_left_out(learned: tuple[Path, OnlineCalibration]) -> None:
    tmp, oc = learned
    before = oc.state
    passage, measured = _wheel(tmp)
    assert measured.channels is not None
    odd = measured.model_copy(
        update={"channels": {k: [1.6 * v for v in c] for k, c in measured.channels.items()}}
    )
    assert oc.observe(passage, odd, None) is None
    flat = WheelPassage.model_validate(
        passage.model_dump() | {"outline": {"kind": "flat", "length": 0.05}}
    )
    assert oc.observe(flat, measured, None) is None
    assert oc.state == before


def test_the_diagnosis_uses_the_current_calibration(
    learned: tuple[Path, OnlineCalibration],
) -> None:
    from service.physics.diagnosis import Diagnoser

    _, oc = learned
    first = Diagnoser(SITE)
    assert first.calibration.source == "nominal"
    swapped = oc.recalibrate(first)
    assert swapped.calibration == oc.ref()
    assert swapped.calibration.source == "online" and swapped.calibration.wheels == 1
    assert first.calibration.source == "nominal"  # a diagnosis under way keeps its own
