"""``railtwin replay``: only one site's input keys, only valid payloads, cut logs too.

Logs are written here, as the twin writes them (``McapLog``) or crafted with the
``mcap`` writer (foreign topics, wrong schemas, several sites). The last tests replay
over loopback Zenoh to a subscriber on ``**`` and check every key that came out.
"""

from __future__ import annotations

import base64
import json
import threading
import time
from pathlib import Path

import pytest
import zenoh
from mcap.writer import Writer

from schemas.diagnosis import MeasuredPassage
from schemas.messages import RejectedInput, ServiceError, WheelPassage, encoding_schema
from service.cli import replay as replay_cli
from service.clients.replay import LoggedInput, ReplayError, check_payload, plan_replay, read_logs
from service.recording.mcap_log import LoggedMessage, McapLog
from service.wire.zenoh_session import build_config, free_tcp_endpoint

SITE = "km12"


def passage(pid: str, **update: object) -> bytes:
    data = {
        "passage_id": pid,
        "train_id": "t1",
        "axle_index": 0,
        "side": "right",
        "timestamp": 1.7e9,
        "speed": 44.4,
        "load": 54000.0,
        "mass": 600.0,
        "radius": 0.46,
        **update,
    }
    return json.dumps(data).encode()


def measured(pid: str, **update: object) -> bytes:
    data = {
        "passage_id": pid,
        "sample_rate": 10000.0,
        "t_start": 0.0,
        "force": [60000.0 + i for i in range(32)],
        **update,
    }
    return json.dumps(data).encode()


def rejected(key: str, payload: bytes, payload_bytes: int | None = None) -> bytes:
    return (
        RejectedInput(
            key=key,
            payload_base64=base64.b64encode(payload).decode(),
            payload_text=payload.decode("utf-8", "replace"),
            payload_bytes=payload_bytes,
        )
        .model_dump_json()
        .encode()
    )


def twin_log(directory: Path, site: str = SITE) -> McapLog:
    """A log as the twin writes it: inputs, rejected inputs and outputs, interleaved."""
    p = f"railtwin/{site}"
    log = McapLog(directory, f"railtwin-{site}")
    t = 1_000_000_000
    log.write(f"{p}/passage", WheelPassage, passage("w0"), t)
    log.write(f"{p}/result", ServiceError, b"{}", t + 1)  # an output (schema irrelevant)
    log.write(
        f"{p}/passage/rejected",
        RejectedInput,
        rejected(f"{p}/passage", b'{"passage_id": "broken", '),
        t + 10,
    )
    log.write(f"{p}/measured", MeasuredPassage, measured("w0"), t + 20)
    log.write(
        f"{p}/measured/rejected",
        RejectedInput,
        rejected(f"{p}/measured", measured("w0", sample_rate=-1.0)),
        t + 30,
    )
    log.write(f"{p}/passage", WheelPassage, passage("w1", load=56000.0), t + 40)
    log.write(f"{p}/error", ServiceError, b"{}", t + 41)
    return log


class Crafted:
    """An MCAP written channel by channel, naming whatever topics and schemas it likes."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.file = path.open("wb")
        self.writer = Writer(self.file)
        self.writer.start()
        self.schemas: dict[str, int] = {}
        self.channels: dict[tuple[str, str], int] = {}
        self.t = 1_000_000_000

    def add(self, topic: str, schema: str, data: bytes) -> None:
        if schema not in self.schemas:
            self.schemas[schema] = self.writer.register_schema(schema, "jsonschema", b"{}")
        if (topic, schema) not in self.channels:
            self.channels[topic, schema] = self.writer.register_channel(
                topic, "json", self.schemas[schema]
            )
        self.t += 1_000_000
        self.writer.add_message(
            self.channels[topic, schema], log_time=self.t, data=data, publish_time=self.t
        )

    def close(self) -> Path:
        self.writer.finish()
        self.file.close()
        return self.path


WP, MP, RI = (encoding_schema(m) for m in (WheelPassage, MeasuredPassage, RejectedInput))


def crafted_log(path: Path) -> Path:
    c = Crafted(path)
    c.add(f"railtwin/{SITE}/passage", WP, passage("ok-1"))
    c.add("railtwin/other/result/x", WP, passage("evil-1"))  # an output key
    c.add("railtwin/**", WP, passage("evil-2"))  # a wildcard
    c.add("somewhere/else/passage", WP, passage("evil-3"))  # another key space
    c.add(f"railtwin/{SITE}/passage/extra", WP, passage("evil-4"))  # below the input key
    c.add(f"railtwin/{SITE}/passage", RI, rejected("x", passage("evil-5")))  # wrong schema
    c.add(f"railtwin/{SITE}/passage", WP, passage("bad-1", mass=-1.0))  # logged "valid"
    c.add(
        f"railtwin/{SITE}/passage/rejected",
        RI,
        rejected("railtwin/other/result/y", passage("evil-6")[:20], payload_bytes=2 << 20),
    )
    c.add(f"railtwin/{SITE}/passage/rejected", RI, b'{"not": "a RejectedInput"}')
    c.add(f"railtwin/{SITE}/measured", MP, measured("ok-1"))
    return c.close()


def sent_ids(plan_inputs: list[LoggedInput]) -> list[tuple[str, str]]:
    return [(i.kind, json.loads(i.payload)["passage_id"]) for i in plan_inputs]


# --- what is sent ----------------------------------------------------------------------


def test_valid_inputs_and_measurements_are_sent_rejected_only_when_asked(tmp_path: Path) -> None:
    log = twin_log(tmp_path)
    log.close()
    msgs = read_logs(log.files)
    plan = plan_replay(msgs)
    assert plan.site_id == SITE and plan.logged_sites == [SITE]
    assert sent_ids(plan.inputs) == [("passage", "w0"), ("measured", "w0"), ("passage", "w1")]
    assert all(i.valid for i in plan.inputs)
    assert plan.inputs[0].payload == passage("w0")  # the exact bytes received
    assert plan.rejected_skipped == 2
    assert plan.skipped_channels == {f"railtwin/{SITE}/result": 1, f"railtwin/{SITE}/error": 1}
    assert plan.unknown_channels() == []

    everything = plan_replay(msgs, include_rejected=True)
    assert [(i.kind, i.valid) for i in everything.inputs] == [
        ("passage", True),
        ("passage", False),
        ("measured", True),
        ("measured", False),
        ("passage", True),
    ]
    assert everything.inputs[1].payload == b'{"passage_id": "broken", '
    assert (
        everything.inputs[3].problem is not None and "sample_rate" in everything.inputs[3].problem
    )
    assert everything.rejected_skipped == 0


def test_a_crafted_log_names_no_key_and_sends_nothing_invalid(tmp_path: Path) -> None:
    msgs = read_logs([crafted_log(tmp_path / "crafted.mcap")])
    plan = plan_replay(msgs)
    assert sent_ids(plan.inputs) == [("passage", "ok-1"), ("measured", "ok-1")]
    assert plan.skipped_channels == {
        "railtwin/other/result/x": 1,
        "railtwin/**": 1,
        "somewhere/else/passage": 1,
        f"railtwin/{SITE}/passage/extra": 1,
        f"railtwin/{SITE}/passage": 1,  # wrong schema
    }
    assert plan.unknown_channels() == sorted(plan.skipped_channels)
    assert plan.rejected_skipped == 1  # the "valid" one with a negative mass
    assert plan.truncated == 1 and plan.damaged == 1
    with_rejected = plan_replay(msgs, include_rejected=True)
    assert sent_ids(with_rejected.inputs) == [
        ("passage", "ok-1"),
        ("passage", "bad-1"),
        ("measured", "ok-1"),
    ]
    assert with_rejected.truncated == 1  # a payload logged cut is never sent


def test_check_payload_is_the_twins_check() -> None:
    assert check_payload("passage", passage("a")) is None
    assert check_payload("measured", measured("a")) is None
    assert check_payload("passage", measured("a")) is not None
    assert check_payload("measured", passage("a")) is not None
    assert "mass" in (check_payload("passage", passage("a", mass="x")) or "")
    assert "nested" in (check_payload("passage", b"[" * 20 + b"]" * 20) or "")
    assert "larger than" in (check_payload("passage", b" " * (2 << 20)) or "")


# --- which site ------------------------------------------------------------------------


def two_site_log(path: Path) -> list[LoggedMessage]:
    c = Crafted(path)
    c.add(f"railtwin/{SITE}/passage", WP, passage("a-1"))
    c.add("railtwin/km13/passage", WP, passage("b-1"))
    c.add(f"railtwin/{SITE}/passage", WP, passage("a-2"))
    return read_logs([c.close()])


def test_the_site_comes_from_the_log_only_when_it_holds_one(tmp_path: Path) -> None:
    msgs = two_site_log(tmp_path / "two.mcap")
    with pytest.raises(ReplayError, match="several sites"):
        plan_replay(msgs)
    plan = plan_replay(msgs, site_id="km13")
    assert plan.site_id == "km13" and sent_ids(plan.inputs) == [("passage", "b-1")]
    assert plan.other_sites == 2
    with pytest.raises(ReplayError, match="must name one of them"):
        plan_replay(msgs, site_id="km99")
    with pytest.raises(ReplayError, match="not a site id"):
        plan_replay(msgs, site_id="km12/**")
    with pytest.raises(ReplayError, match="no site's inputs"):
        plan_replay([])


def test_a_one_site_log_can_be_replayed_to_another_site(tmp_path: Path) -> None:
    log = twin_log(tmp_path, site="old")
    log.close()
    plan = plan_replay(read_logs(log.files), site_id="new")
    assert plan.site_id == "new" and plan.logged_sites == ["old"]
    assert len(plan.inputs) == 3 and plan.other_sites == 0


# --- cut logs --------------------------------------------------------------------------


def cut_log(directory: Path) -> Path:
    """A log whose writer was killed: flushed chunks, no footer, a torn last record."""
    log = McapLog(directory, "cut", chunk_size=64)
    for i in range(5):
        log.write(f"railtwin/{SITE}/passage", WheelPassage, passage(f"c{i}"), 1_000 + i)
        log.flush()
    path = log.files[0]
    data = path.read_bytes()
    path.write_bytes(data + data[-40:-10])  # as if cut mid-record
    return path


def test_a_cut_log_is_replayed_up_to_its_last_chunk(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = cut_log(tmp_path)
    plan = plan_replay(read_logs([path]))
    assert [json.loads(i.payload)["passage_id"] for i in plan.inputs] == [f"c{i}" for i in range(5)]
    assert replay_cli.main([str(path), "--dry-run"]) == 0
    out = capsys.readouterr()
    assert "5 inputs to send: 5 passages, 0 measurements" in out.out
    assert "cut at byte" in out.err


def test_cli_refuses_an_ambiguous_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    two_site_log(tmp_path / "two.mcap")
    assert replay_cli.main([str(tmp_path / "two.mcap"), "--dry-run"]) == 2
    assert "say which one with --site" in capsys.readouterr().err
    assert replay_cli.main([str(tmp_path / "two.mcap"), "--dry-run", "--site", SITE]) == 0
    out = capsys.readouterr().out
    assert "2 inputs to send" in out and "1 inputs of other sites skipped" in out


# --- over Zenoh ------------------------------------------------------------------------


class Listener:
    """A peer that listens on a free loopback port and records every sample on ``**``."""

    def __init__(self) -> None:
        self.endpoint = free_tcp_endpoint()
        self.session = zenoh.open(build_config(listen=[self.endpoint]))
        self.samples: list[tuple[str, str, bytes]] = []
        self.lock = threading.Lock()
        # the twin's two input subscribers, so that the replay's publishers match
        self.subs = [
            self.session.declare_subscriber(k, self.on)
            for k in (f"railtwin/{SITE}/passage", f"railtwin/{SITE}/measured")
        ]
        self.subs.append(self.session.declare_subscriber("**", self.on_any))
        self.any_keys: list[str] = []

    def on(self, s: zenoh.Sample) -> None:
        with self.lock:
            self.samples.append((str(s.key_expr), str(s.encoding), s.payload.to_bytes()))

    def on_any(self, s: zenoh.Sample) -> None:
        with self.lock:
            self.any_keys.append(str(s.key_expr))

    def wait(self, n: int, timeout: float = 10.0) -> None:
        deadline = time.monotonic() + timeout
        while len(self.samples) < n and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)  # anything more would come now

    def close(self) -> None:
        for s in self.subs:
            s.undeclare()
        self.session.close()


def test_replay_publishes_only_to_the_sites_input_keys(tmp_path: Path) -> None:
    log = crafted_log(tmp_path / "crafted.mcap")
    listener = Listener()
    try:
        assert (
            replay_cli.main(
                [str(log), "--connect", listener.endpoint, "--rate", "0", "--include-rejected"]
            )
            == 0
        )
        listener.wait(3)
    finally:
        listener.close()
    # in log order on each key (Zenoh may interleave the two keys differently)
    assert sorted(
        ((k, e, json.loads(p)["passage_id"]) for k, e, p in listener.samples),
        key=lambda s: s[0] != f"railtwin/{SITE}/passage",
    ) == [
        (f"railtwin/{SITE}/passage", f"application/json;{WP}", "ok-1"),
        (f"railtwin/{SITE}/passage", f"application/json;{WP}", "bad-1"),
        (f"railtwin/{SITE}/measured", f"application/json;{MP}", "ok-1"),
    ]
    assert sorted(set(listener.any_keys)) == [
        f"railtwin/{SITE}/measured",
        f"railtwin/{SITE}/passage",
    ]
    assert len(listener.any_keys) == 3


def test_replay_keeps_the_timing_and_the_bytes(tmp_path: Path) -> None:
    log = twin_log(tmp_path)
    log.close()
    listener = Listener()
    try:
        start = time.monotonic()
        assert (
            replay_cli.main(
                [
                    *map(str, log.files),
                    "--connect",
                    listener.endpoint,
                    "--rate",
                    "0.5",
                    "--site",
                    SITE,
                ]
            )
            == 0
        )
        elapsed = time.monotonic() - start
        listener.wait(3)
    finally:
        listener.close()
    by_key = {k: [p for kk, _, p in listener.samples if kk == k] for k, _, _ in listener.samples}
    assert by_key == {
        f"railtwin/{SITE}/passage": [passage("w0"), passage("w1", load=56000.0)],
        f"railtwin/{SITE}/measured": [measured("w0")],
    }
    assert elapsed >= 40e-9 / 0.5  # 40 ns of log time at half speed: the spacing is kept


def test_a_log_of_an_older_minor_version_replays(tmp_path: Path) -> None:
    """Inputs logged by a 1.0 twin (schema railtwin.WheelPassage/1.0) are sent; 2.0 are not."""
    c = Crafted(tmp_path / "old.mcap")
    c.add(f"railtwin/{SITE}/passage", "railtwin.WheelPassage/1.0", passage("old-1"))
    c.add(f"railtwin/{SITE}/measured", "railtwin.MeasuredPassage/1.0", measured("old-1"))
    c.add(f"railtwin/{SITE}/passage", "railtwin.WheelPassage/2.0", passage("future-1"))
    plan = plan_replay(read_logs([c.close()]))
    assert sent_ids(plan.inputs) == [("passage", "old-1"), ("measured", "old-1")]
    assert plan.skipped_channels == {f"railtwin/{SITE}/passage": 1}  # the 2.0 one
