"""Publish measured forces for some wheels of a train and print the twin's diagnoses.

    railtwin feed-measured --train recordings/samples/train_160kmh.json \\
        --site-file examples/site_compliant.toml --connect tcp/127.0.0.1:7447 [--axles 0 5 13 20]
        [--save M.json | --load M.json | --measured FILE...] [--with-train]

The measurements are made by the generator (``railtwin synthesize``: each wheel's own
outline, unknown roughness, foundation damping, sensor chain and noise); the wheels'
passages must already have been sent (``railtwin feed``), or come later: the twin pairs
them by passage id. One line per diagnosis, with the time from publishing the
measurement to receiving its verdict. ``--save`` only generates (no Zenoh), ``--load``
publishes saved ones (a JSON list of ``MeasuredPassage``), ``--measured`` measured files
(CSV or MCAP, ``service.clients.measured_io``; a file's name is its passage id:
``<passage_id>.csv``), of the contact force or of the site's crib channels; a channel
measurement must name exactly the site's ``detector.cribs`` (``railtwin feed-measured``
refuses any other with exit 2 before publishing). The twin answers a channel measurement
with an error until the diagnosis from crib channels exists. ``--with-train`` publishes each measurement when its wheel leaves
the site, timed from the start like ``service.clients.feeder`` times the train (run both
together: the diagnoses are then made while the train streams, as at a real site).
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from pathlib import Path

import zenoh

from schemas.diagnosis import Diagnosis, MeasuredPassage
from schemas.messages import ServiceError, TrainFile
from schemas.site import SiteConfig
from service.clients.feeder import load_train, wait_matching
from service.clients.measured_io import MeasuredFileError, read_measured
from service.clients.synthesize import measured_passage, passage_tread
from service.wire.encoding import json_encoding
from service.wire.keyspace import SiteKeys
from service.wire.measured_channels import CHANNELS_FIELD, channels_mismatch
from service.wire.site import load_site
from service.wire.zenoh_session import DEFAULT_ENDPOINT, build_config, open_session

DEFAULT_AXLES = (0, 5, 13, 20)


def describe(d: Diagnosis, latency: float) -> str:
    flat = (
        "no flat"
        if d.flat is None
        else (
            f"{d.flat.kind} {d.flat.length * 1e3:.1f} mm "
            f"[{d.flat.length_low * 1e3:.1f}-{d.flat.length_high * 1e3:.1f}]"
        )
    )
    line = (
        ""
        if d.peak_force_at_line_speed is None
        else (f", {d.peak_force_at_line_speed / 1e3:.0f} kN at line speed")
    )
    wheel = f" (wheel {d.wheel.id})" if d.wheel is not None else ""
    return (
        f"diagnosis {d.passage_id}{wheel}: {d.verdict.upper():7s} {flat}; measured peak "
        f"{d.peak_force_measured / 1e3:.0f} kN{line}; verdict {latency * 1e3:.0f} ms "
        f"after the measurement"
    )


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``railtwin feed-measured``."""
    p.add_argument("--train", type=Path, default=Path("recordings/samples/train_160kmh.json"))
    p.add_argument("--site-file", type=Path, default=Path("examples/site_compliant.toml"))
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT")
    p.add_argument("--axles", type=int, nargs="+", default=list(DEFAULT_AXLES))
    p.add_argument("--timeout", type=float, default=60.0)
    p.add_argument("--save", type=Path, default=None, help="only generate, into this file")
    p.add_argument("--load", type=Path, default=None, help="publish measurements saved before")
    p.add_argument(
        "--measured",
        type=Path,
        nargs="+",
        default=None,
        metavar="FILE",
        help="publish these measured files (CSV: t_s,force_N or t_s,<crib id>,...; or .mcap), "
        "each named <passage_id>.csv",
    )
    p.add_argument(
        "--with-train",
        action="store_true",
        help="publish each when its wheel leaves the site (train timing)",
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin feed-measured", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


def run(a: argparse.Namespace) -> int:
    """Make (or load) the measurements and publish them, or only save them."""
    site = load_site(a.site_file)
    saved = None
    if a.load is not None:
        saved = [
            MeasuredPassage.model_validate(d)
            for d in json.loads(a.load.read_text(encoding="utf-8"))
        ]
    elif a.measured:
        try:
            saved = read_measured_files(a.measured, site)
        except MeasuredFileError as exc:
            print(f"railtwin feed-measured: {exc}", file=sys.stderr)
            return 2
    if saved is not None:
        problem = measurements_problem(saved, site)
        if problem is not None:
            print(f"railtwin feed-measured: {problem}", file=sys.stderr)
            return 2
    cfg = build_config(connect=a.connect or [DEFAULT_ENDPOINT])
    return feed_measured(a, site, load_train(a.train), saved, cfg)


def read_measured_files(paths: list[Path], site: SiteConfig) -> list[MeasuredPassage]:
    """The measurements in ``paths``, each file's name (without suffix) its passage id, read
    at the site's measuring rate; ``MeasuredFileError`` for the first that cannot be read."""
    return [read_measured(p, p.stem, sample_rate=site.diagnosis.sample_rate) for p in paths]


def measurements_problem(measured: list[MeasuredPassage], site: SiteConfig) -> str | None:
    """One line on the first measurement whose channels are not the site's cribs, or None
    (what the twin would refuse anyway: refused before anything is published)."""
    for m in measured:
        mismatch = channels_mismatch(m, site)
        if mismatch is not None:
            return f"measurement of {m.passage_id}: {CHANNELS_FIELD}: {mismatch}"
    return None


def feed_measured(
    a: argparse.Namespace,
    site: SiteConfig,
    train: TrainFile,
    saved: list[MeasuredPassage] | None,
    cfg: zenoh.Config,
) -> int:
    """``run`` with the files read (``saved``: those of ``--load``) and the Zenoh config made
    (``railtwin feed-measured`` reads and checks them itself)."""
    keys = SiteKeys(site.site_id)
    offsets = {w.passage.passage_id: w.offset + site.length / w.passage.speed for w in train.wheels}
    payloads: list[MeasuredPassage] = []
    if saved is not None:
        payloads = list(saved)
    else:
        from service.physics.diagnosis import Diagnoser  # the physics, only when it is used

        diagnoser = Diagnoser(site)
        wheels = [w.passage for w in train.wheels if w.passage.axle_index in set(a.axles)]
        print(
            f"measured: generating the site's measurement of {len(wheels)} wheels "
            f"(axles {', '.join(str(w.axle_index) for w in wheels)})",
            flush=True,
        )
        for i, w in enumerate(wheels):
            m, _ = measured_passage(site, w, passage_tread(w), seed=1000 + i, diagnoser=diagnoser)
            payloads.append(m)
    if a.save is not None:
        a.save.write_text(json.dumps([m.model_dump() for m in payloads]), encoding="utf-8")
        return 0
    sent: dict[str, float] = {}
    got: dict[str, Diagnosis] = {}
    done = threading.Event()
    lock = threading.Lock()

    def on_output(sample: zenoh.Sample) -> None:
        kind = keys.kind_of(str(sample.key_expr))
        data = sample.payload.to_bytes()
        with lock:
            if kind == "diagnosis":
                d = Diagnosis.model_validate_json(data)
                if d.passage_id in sent and d.passage_id not in got:
                    got[d.passage_id] = d
                    print(describe(d, time.monotonic() - sent[d.passage_id]), flush=True)
            elif kind == "error":
                e = ServiceError.model_validate_json(data)
                if e.passage_id in sent and e.passage_id not in got:
                    print(f"diagnosis {e.passage_id}: ERROR {e.kind}: {e.message}", flush=True)
                    got[e.passage_id] = None  # type: ignore[assignment]
            if len(got) == len(payloads):
                done.set()

    with open_session(cfg) as session:
        sub = session.declare_subscriber(keys.all_outputs, on_output)
        pub = session.declare_publisher(
            keys.measured,
            encoding=json_encoding(MeasuredPassage),
            congestion_control=zenoh.CongestionControl.BLOCK,
        )
        wait_matching(pub, 10.0)
        start = time.monotonic()
        for mp in sorted(payloads, key=lambda m: offsets.get(m.passage_id, 0.0)):
            if a.with_train:
                delay = start + offsets.get(mp.passage_id, 0.0) - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            with lock:
                sent[mp.passage_id] = time.monotonic()
            pub.put(mp.model_dump_json().encode())
            if not a.with_train:
                time.sleep(0.05)  # a train brings a wheel every ~50 ms
        ok = done.wait(a.timeout)
        sub.undeclare()
    if not ok:
        print(
            f"measured: {len(payloads) - len(got)} diagnoses missing after {a.timeout} s",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
