"""Stream a train's wheel passages to a running twin and collect what comes back.

    railtwin feed --train recordings/samples/train_160kmh.json \\
        --site demo --connect tcp/127.0.0.1:7447

Used by ``make demo`` (one line per wheel: peak force, contact losses, dent, and the crib
channels' peak at a site with a detector)
and by the benchmark (latency from sending a passage to receiving its result,
measured in this process with one clock). Waits for the service's subscriber
to match before sending, so that no passage is lost to discovery.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from schemas.messages import Health, PassageResult, ServiceError, TrainFile, WheelPassage
from service.wire.encoding import json_encoding
from service.wire.keyspace import HEALTH_KEY, SiteKeys
from service.wire.zenoh_session import DEFAULT_ENDPOINT, build_config, open_session


def load_train(path: Path) -> TrainFile:
    return TrainFile.model_validate_json(path.read_bytes())


@dataclass
class Outcome:
    """What came back for one passage (times are ``time.monotonic()`` in this process)."""

    sent: float
    result_at: float | None = None
    force_at: float | None = None
    result: PassageResult | None = None
    error: ServiceError | None = None

    @property
    def latency(self) -> float | None:
        """Seconds from sending the passage to receiving its result."""
        return None if self.result_at is None else self.result_at - self.sent


@dataclass
class Collector:
    """Subscribes to a site's outputs; records results and errors by passage id."""

    keys: SiteKeys
    decode_results: bool = True
    on_result: Callable[[PassageResult], None] | None = None
    outcomes: dict[str, Outcome] = field(default_factory=dict)
    errors: list[ServiceError] = field(default_factory=list)
    _lock: threading.Lock = field(default_factory=threading.Lock)
    _changed: threading.Condition = field(init=False)

    def __post_init__(self) -> None:
        self._changed = threading.Condition(self._lock)

    def expect(self, passage_id: str, sent: float) -> None:
        with self._lock:
            self.outcomes[passage_id] = Outcome(sent=sent)

    def __call__(self, sample: zenoh.Sample) -> None:
        now = time.monotonic()
        key = str(sample.key_expr)
        kind = self.keys.kind_of(key)
        if kind == "error":
            err = ServiceError.model_validate_json(sample.payload.to_bytes())
            with self._lock:
                self.errors.append(err)
                o = self.outcomes.get(err.passage_id or "")
                if o is not None and o.result_at is None:
                    o.error = err
                self._changed.notify_all()
            return
        if kind not in ("result", "force"):
            return
        pid = key.rsplit("/", 1)[-1]
        result = None
        if kind == "result" and (self.decode_results or self.on_result is not None):
            result = PassageResult.model_validate_json(sample.payload.to_bytes())
        with self._lock:
            o = self.outcomes.setdefault(pid, Outcome(sent=float("nan")))
            if kind == "force":
                o.force_at = o.force_at or now
            else:
                o.result_at = now
                o.result = result
            self._changed.notify_all()
        if result is not None and self.on_result is not None:
            self.on_result(result)

    def done(self, passage_ids: Sequence[str]) -> bool:
        return all(
            (o := self.outcomes.get(p)) is not None and (o.result_at is not None or o.error)
            for p in passage_ids
        )

    def wait(self, passage_ids: Sequence[str], timeout: float) -> bool:
        """Until every passage has a result or an error (True), or ``timeout`` s (False)."""
        deadline = time.monotonic() + timeout
        with self._lock:
            while not self.done(passage_ids):
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._changed.wait(left)
        return True


def is_matching(publisher: zenoh.Publisher) -> bool:
    """Whether a subscriber matches (the stubs type ``matching_status`` as bool; it is not)."""
    return bool(publisher.matching_status.matching)  # type: ignore[attr-defined]


def wait_matching(publisher: zenoh.Publisher, timeout: float) -> bool:
    """Until a subscriber matches ``publisher`` (ECOSYSTEM.md: test ``.matching``)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if is_matching(publisher):
            return True
        time.sleep(0.02)
    return False


def declare_passage_publisher(session: zenoh.Session, keys: SiteKeys) -> zenoh.Publisher:
    return session.declare_publisher(
        keys.passage,
        encoding=json_encoding(WheelPassage),
        congestion_control=zenoh.CongestionControl.BLOCK,
        express=True,
    )


def send_train(
    publisher: zenoh.Publisher,
    collector: Collector,
    wheels: Sequence[tuple[float, WheelPassage]],
    *,
    flood: bool = False,
    extra: Sequence[tuple[float, bytes]] = (),
) -> list[str]:
    """Publish each passage at its offset (s from now; all at once if ``flood``).

    The timestamp of each passage is set to the wall-clock time it is sent.
    ``extra`` are raw payloads (e.g. bad input) sent at their offsets too.
    Returns the passage ids in the order sent.
    """
    items: list[tuple[float, WheelPassage | bytes]] = [(o, p) for o, p in wheels]
    items += [(o, b) for o, b in extra]
    items.sort(key=lambda item: item[0])
    start = time.monotonic()
    sent: list[str] = []
    for offset, item in items:
        if not flood:
            delay = start + offset - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        if isinstance(item, bytes):
            publisher.put(item)
            continue
        passage = item.model_copy(update={"timestamp": time.time()})
        data = passage.model_dump_json().encode()
        collector.expect(passage.passage_id, time.monotonic())
        publisher.put(data)
        sent.append(passage.passage_id)
    return sent


def query_health(session: zenoh.Session, timeout: float = 2.0) -> list[Health]:
    out = []
    for reply in session.get(HEALTH_KEY, timeout=timeout):
        if reply.ok is not None:
            out.append(Health.model_validate_json(reply.ok.payload.to_bytes()))
    return out


def describe(r: PassageResult) -> str:
    """One line per wheel, for the demo; at a site with a detector, the highest of its crib
    channels (kN, and which crib) and how many channels the result carried."""
    s = r.summary
    flag = "  <-- contact lost" if s.contact_losses else ""
    dent = f"{s.max_dent * 1e6:7.2f} µm" if s.max_dent > 0 else "      -   "
    cribs = ""
    if r.channels:
        crib, peak = max(
            ((c, max(v, default=0.0)) for c, v in r.channels.items()), key=lambda cv: cv[1]
        )
        cribs = f"  channels {len(r.channels)}, peak {peak / 1e3:7.1f} kN ({crib})"
    return (
        f"{r.passage_id:<16} axle {r.axle_index:>2}  peak {s.peak_force / 1e3:7.1f} kN  "
        f"losses {s.contact_losses:>2}  max δ {s.max_indentation * 1e6:6.1f} µm  "
        f"dent {dent}{cribs}{flag}"
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``railtwin feed``."""
    p.add_argument("--train", type=Path, default=Path("recordings/samples/train_160kmh.json"))
    p.add_argument("--site", default="demo", help="site id of the running service")
    p.add_argument(
        "--connect",
        action="append",
        default=[],
        metavar="ENDPOINT",
        help=f"endpoint of the service (repeatable; default {DEFAULT_ENDPOINT})",
    )
    p.add_argument("--zenoh-config", type=Path, default=None)
    p.add_argument("--flood", action="store_true", help="send all passages at once")
    p.add_argument("--timeout", type=float, default=60.0, help="s to wait for all results")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin feed", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


def endpoints(args: argparse.Namespace) -> list[str]:
    """The endpoints to connect to: ``--connect``, else the default one (none with a
    ``--zenoh-config``: its own)."""
    return list(args.connect) or ([] if args.zenoh_config else [DEFAULT_ENDPOINT])


def run(args: argparse.Namespace) -> int:
    """Stream the train, print a line per result; 0 when every passage got its result."""
    cfg = build_config(connect=endpoints(args), config_file=args.zenoh_config)
    return feed(args, load_train(args.train), cfg)


def feed(args: argparse.Namespace, train: TrainFile, cfg: zenoh.Config) -> int:
    """``run`` with the train read and the Zenoh config made (``railtwin feed`` reads and
    checks them itself)."""
    keys = SiteKeys(args.site)
    connect = endpoints(args)
    printed = threading.Lock()

    def show(r: PassageResult) -> None:
        with printed:
            print(describe(r), flush=True)

    with open_session(cfg) as session:
        collector = Collector(keys, on_result=show)
        sub = session.declare_subscriber(keys.all_outputs, collector)
        pub = declare_passage_publisher(session, keys)
        if not wait_matching(pub, 10.0):
            print(f"feeder: no service subscribed to {keys.passage} at {connect}", file=sys.stderr)
            sub.undeclare()
            return 1
        print(
            f"feeder: streaming {len(train.wheels)} wheels of train {train.train_id} "
            f"to {keys.passage}",
            flush=True,
        )
        ids = send_train(
            pub, collector, [(w.offset, w.passage) for w in train.wheels], flood=args.flood
        )
        ok = collector.wait(ids, args.timeout)
        health = query_health(session)
        sub.undeclare()
        pub.undeclare()
    results = [o.result for o in collector.outcomes.values() if o.result is not None]
    lat = sorted(o.latency for o in collector.outcomes.values() if o.latency is not None)
    print(
        f"feeder: {len(results)}/{len(ids)} results, {len(collector.errors)} errors"
        + (f", latency median {lat[len(lat) // 2] * 1e3:.1f} ms" if lat else ""),
        flush=True,
    )
    for h in health:
        if h.site_id == args.site:
            print(json.dumps({"mcap": h.mcap_path, "rrd": h.rrd_path}), flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
