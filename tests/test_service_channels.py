"""A site's detector channels through the running twin: published with the result on Zenoh,
logged sample by sample in the MCAP (plottable against time in Foxglove), drawn in Rerun
(one plot per crib, with the contact force beside it).

The twin runs here with the closed-form stand-in physics (``StubPhysics``: a crib's channel
is the force while the wheel is between its gauges), so the plumbing is tested in a second;
the channels of the site's own physics are ``tests/test_track_contract.py``'s.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun.blueprint as rrb
import zenoh
from mcap.reader import make_reader

from schemas.messages import PassageResult, WheelPassage
from schemas.site import SiteConfig
from service.physics.local import LocalPhysics
from service.physics.stub import StubPhysics
from service.recording import foxglove
from service.recording.mcap_log import LoggedMessage, decode
from service.recording.recorder_process import ProcessRecorder, RecordingPlan
from service.recording.rerun_recording import (
    RerunRecording,
    channel_entity,
    default_blueprint,
    entities,
)
from service.twin.twin import Twin
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.zenoh_session import build_config, free_tcp_endpoint
from tests.test_service_rerun import rrd_columns, rrd_entities, rrd_texts

CRIBS = [{"id": "ch1", "x_a": 1.0, "x_b": 1.4}, {"id": "ch2", "x_a": 1.6, "x_b": 2.0}]
"""Between the sleepers at 0.9, 1.5 and 2.1 m."""


def site(detector: bool = True) -> SiteConfig:
    """A 2.4 m ballasted site at 2 kHz, with two cribs (or none)."""
    data: dict[str, Any] = {
        "site_id": "s",
        "length": 2.4,
        "output_sample_rate": 2000.0,
        "contact": "hertz",
        "rail": {"kind": "flat"},
        "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
        "foundation": {
            "kind": "discrete",
            "sleeper_spacing": 0.6,
            "first_sleeper": 0.3,
            "pad": {"stiffness": 2.0e8, "damping": 3.0e4},
            "sleeper_mass": 150.0,
            "ballast": {"stiffness": 1.2e8, "damping": 8.0e4},
        },
    }
    if detector:
        data["detector"] = {"cribs": CRIBS}
    return SiteConfig.model_validate(data)


def passage(pid: str) -> WheelPassage:
    return WheelPassage(
        passage_id=pid,
        train_id="t1",
        axle_index=0,
        side="right",
        timestamp=1_780_000_000.0,
        speed=40.0,
        load=60e3,
        mass=500.0,
        radius=0.46,
    )


class Served:
    """A twin of ``config`` on the stand-in physics, with MCAP and Rerun, and a client."""

    def __init__(self, config: SiteConfig, recordings: Path) -> None:
        self.config = config
        self.keys = SiteKeys(config.site_id)
        endpoint = free_tcp_endpoint()
        self.session = zenoh.open(build_config(listen=[endpoint]))
        cribs = tuple(c.id for c in config.detector.cribs) if config.detector else ()
        self.recorder = ProcessRecorder(
            RecordingPlan(recordings, "run", config.site_id, flush_interval=0.05, cribs=cribs)
        )
        self.twin = Twin(
            config, self.session, LocalPhysics(StubPhysics(config)), recorder=self.recorder
        )
        self.twin.start()
        self.client = zenoh.open(build_config(connect=[endpoint]))
        self.results: dict[str, bytes] = {}
        self._sub = self.client.declare_subscriber(
            f"{self.keys.prefix}/result/*",
            lambda s: self.results.__setitem__(
                str(s.key_expr).rsplit("/", 1)[1], s.payload.to_bytes()
            ),
        )

    def send(self, p: WheelPassage, timeout: float = 20.0) -> bytes:
        pub = self.client.declare_publisher(self.keys.passage)
        deadline = time.monotonic() + timeout
        while not pub.matching_status.matching:  # type: ignore[attr-defined]
            assert time.monotonic() < deadline, "the twin did not subscribe"
            time.sleep(0.05)
        pub.put(p.model_dump_json(), encoding=json_encoding(WheelPassage))
        while p.passage_id not in self.results:
            assert time.monotonic() < deadline, "no result"
            time.sleep(0.02)
        pub.undeclare()
        return self.results[p.passage_id]

    def close(self) -> None:
        self._sub.undeclare()
        self.client.close()
        self.twin.stop()
        self.recorder.close()
        self.session.close()


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[Served, bytes, Path]]:
    """The twin of the site with a detector after one passage: (twin, its result, files)."""
    s = Served(site(), tmp_path)
    try:
        data = s.send(passage("p1"))
    finally:
        s.close()
    yield s, data, tmp_path


def stub_channel(r: PassageResult, x_a: float, x_b: float) -> np.ndarray:
    x, f = np.asarray(r.x), np.asarray(r.force)
    return np.where((x >= x_a) & (x <= x_b), f, 0.0)


def test_the_result_on_zenoh_carries_each_cribs_channel(
    served: tuple[Served, bytes, Path],
) -> None:
    _, data, _ = served
    r = PassageResult.model_validate_json(data)
    assert r.channels is not None and list(r.channels) == ["ch1", "ch2"]
    for crib in CRIBS:
        values = np.asarray(r.channels[crib["id"]])
        np.testing.assert_array_equal(values, stub_channel(r, crib["x_a"], crib["x_b"]))
        assert values.max() == pytest.approx(passage("p1").load, rel=0.05)  # wheel in the crib
    assert json.loads(data)["channels"].keys() == {"ch1", "ch2"}


def mcap_messages(directory: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, schema name, log time, data) of every message of the run's MCAP."""
    out = []
    for path in sorted(directory.glob("*.mcap")):
        with path.open("rb") as f:
            for schema, channel, m in make_reader(f).iter_messages(log_time_order=True):
                out.append((channel.topic, schema.name if schema else "", m.log_time, m.data))
    return out


def test_the_mcap_holds_the_channels_sample_by_sample_beside_the_force(
    served: tuple[Served, bytes, Path],
) -> None:
    """``railtwin/<site>/samples``: each sample's channels at its own time, so that
    Foxglove's Plot panel draws ``.channels.ch1`` against time beside ``.force``."""
    _, data, directory = served
    r = PassageResult.model_validate_json(data)
    assert r.channels is not None
    messages = mcap_messages(directory)
    results = [d for topic, _, _, d in messages if topic == "railtwin/s/result"]
    assert results == [data]  # the whole result, channels and all, as published
    rows = [(t, name, d) for topic, name, t, d in messages if topic == "railtwin/s/samples"]
    assert len(rows) == len(r.x)
    assert [t for t, _, _ in rows] == [round((r.timestamp + x / r.speed) * 1e9) for x in r.x]
    samples = [decode(LoggedMessage("railtwin/s/samples", n, t, d)) for t, n, d in rows]
    assert all(isinstance(s, foxglove.PassageSample) for s in samples)
    np.testing.assert_allclose([s.force for s in samples], r.force, rtol=1e-6)
    for crib, values in r.channels.items():
        got = [s.channels[crib] for s in samples]
        np.testing.assert_allclose(got, values, rtol=1e-6, atol=0)
    with sorted(directory.glob("*.mcap"))[0].open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    (schema,) = [s for s in summary.schemas.values() if s.name == foxglove.SAMPLE_SCHEMA_NAME]
    assert "channels" in json.loads(schema.data)["properties"]


def test_rerun_draws_one_plot_per_crib_with_the_force_beside_it(
    served: tuple[Served, bytes, Path],
) -> None:
    _, data, directory = served
    r = PassageResult.model_validate_json(data)
    assert r.channels is not None
    (rrd,) = directory.glob("*.rrd")
    cols = rrd_columns(rrd)
    for crib, values in r.channels.items():
        entity = channel_entity("s", crib)
        assert entity == f"/s/channels/{crib}"
        np.testing.assert_array_equal(cols[entity]["values"], values)  # N
        np.testing.assert_array_equal(cols[entity]["x_mm"], cols[entities("s")["force"]]["x_mm"])
        np.testing.assert_array_equal(cols[entity]["time"], cols[entities("s")["force"]]["time"])
    (doc,) = [text for _, text in rrd_texts(rrd)[entities("s")["wheel"]]]
    assert "crib channels, peak: ch1" in doc


def views(x: object) -> list[rrb.TimeSeriesView]:
    if isinstance(x, rrb.TimeSeriesView):
        return [x]
    return [v for c in getattr(x, "contents", None) or [] for v in views(c)]


def test_the_blueprint_has_a_channel_plot_per_crib_only_at_a_detector_site() -> None:
    plain = views(default_blueprint("s").root_container)
    assert len(plain) == 5 and not any("Crib" in str(v.name) for v in plain)
    with_cribs = views(default_blueprint("s", ("ch1", "ch2")).root_container)
    cribs = [v for v in with_cribs if str(v.name).startswith("Crib")]
    assert len(with_cribs) == 7 and len(cribs) == 2
    for crib, view in zip(("ch1", "ch2"), cribs, strict=True):
        assert crib in str(view.name) and "[N]" in str(view.name)
        contents = str(view.contents)
        assert channel_entity("s", crib) in contents and entities("s")["force"] in contents


def test_a_site_without_a_detector_logs_and_draws_no_channels(tmp_path: Path) -> None:
    s = Served(site(detector=False), tmp_path)
    try:
        data = s.send(passage("p1"))
    finally:
        s.close()
    assert PassageResult.model_validate_json(data).channels is None
    samples = [d for t, _, _, d in mcap_messages(tmp_path) if t == "railtwin/s/samples"]
    assert samples and not any(b"channels" in d for d in samples)  # as before the detector
    (rrd,) = tmp_path.glob("*.rrd")
    assert not any("/channels" in e for e in rrd_entities(rrd))


def test_a_channel_of_a_crib_the_recording_was_not_told_of_is_drawn_all_the_same(
    tmp_path: Path,
) -> None:
    r = PassageResult.model_validate_json(
        StubPhysics(site()).simulate(passage("p1")).model_dump_json()
    )
    path = tmp_path / "run.rrd"
    rec = RerunRecording(path, "s")  # no cribs: no channel plots, the series drawn
    rec.log_passage(r)
    rec.close()
    assert r.channels is not None
    cols = rrd_columns(path)
    for crib, values in r.channels.items():
        np.testing.assert_array_equal(cols[channel_entity("s", crib)]["values"], values)
