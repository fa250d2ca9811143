"""``make demo``: the twin on loopback, a sample train streamed to it, where the files are.

    railtwin demo [--site examples/site.toml]
        [--train recordings/samples/train_160kmh.json] [--recordings recordings]

Starts ``railtwin serve`` in a child process on a free loopback port, streams
the sample train at its real timing (one line per wheel: peak force, contact
losses, dent), stops the service cleanly and prints where its MCAP log and
Rerun recording are. No network beyond loopback, no viewer needed.

The demo streams the same sample train every time, so each run starts the twin
on a fresh rail state of its own (a temporary ``--state`` directory): with the
site's persistent state its passage ids would be refused as already applied.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from service.cli.common import SubParsers
from service.cli.service_process import ServiceProcess
from service.wire.site import load_site
from service.wire.zenoh_session import free_tcp_endpoint

ROOT = Path(__file__).resolve().parents[2]

RAILTWIN = (sys.executable, "-m", "service.cli")
"""``railtwin`` of this interpreter (the console script may not be on PATH)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--site",
        type=Path,
        default=ROOT / "examples/site.toml",
        help="site file (default examples/site.toml)",
    )
    p.add_argument(
        "--train",
        type=Path,
        default=ROOT / "recordings/samples/train_160kmh.json",
        help="train file (default recordings/samples/train_160kmh.json)",
    )
    p.add_argument(
        "--recordings",
        type=Path,
        default=ROOT / "recordings",
        help="where the MCAP log and the .rrd go (default recordings/)",
    )


def register(subparsers: SubParsers) -> argparse.ArgumentParser:
    """Add ``demo`` to the ``railtwin`` CLI's subparsers."""
    p: argparse.ArgumentParser = subparsers.add_parser(
        "demo",
        help="the twin on loopback with a sample train streamed through it (make demo)",
        description=__doc__.split("\n")[0],
    )
    add_arguments(p)
    p.set_defaults(func=run)
    return p


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin demo", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


def run(args: argparse.Namespace) -> int:
    """Start the twin, stream the train and the measurements, print where the files are."""
    site = load_site(args.site)
    endpoint = free_tcp_endpoint()
    print(
        f"demo: starting railtwin serve for site {site.site_id!r} on {endpoint} "
        "(the first start compiles the physics: allow a few minutes; up to 15 are waited for)",
        flush=True,
    )
    with (
        tempfile.TemporaryDirectory(prefix="railtwin-demo-state-") as state,
        ServiceProcess(
            args.site,
            listen=endpoint,
            recordings=args.recordings,
            start_timeout=900.0,
            extra_args=("--state", state),
        ) as svc,
    ):
        saved = args.recordings / "demo-measured.json"
        args.recordings.mkdir(parents=True, exist_ok=True)
        measured_cmd = [
            *RAILTWIN,
            "feed-measured",
            "--train",
            str(args.train),
            "--site-file",
            str(args.site),
        ]
        print(
            "demo: the site's measured force of four wheels, made by the generator "
            "(each wheel's own outline, unknown roughness and damping, sensor noise)",
            flush=True,
        )
        subprocess.run([*measured_cmd, "--save", str(saved)], cwd=ROOT, check=False)
        print(
            "demo: streaming the train; each measurement follows its wheel off the site, "
            "and the twin diagnoses it while the train streams",
            flush=True,
        )
        measured_proc = subprocess.Popen(
            [
                *measured_cmd,
                "--load",
                str(saved),
                "--with-train",
                "--connect",
                endpoint,
                "--timeout",
                "120",
            ],
            cwd=ROOT,
        )
        feeder = subprocess.run(
            [
                *RAILTWIN,
                "feed",
                "--train",
                str(args.train),
                "--site",
                site.site_id,
                "--connect",
                endpoint,
                "--timeout",
                "300",
            ],
            cwd=ROOT,
            check=False,
        )
        measured_code = measured_proc.wait()
    if svc.returncode != 0:
        print(svc.output, file=sys.stderr)
        return 1
    print("\ndemo: done.", flush=True)
    for f in svc.mcap_files:
        print(f"demo: MCAP log (open in Foxglove):      {f}")
    if svc.rrd_file is not None:
        print(f"demo: Rerun recording (rerun FILE.rrd): {svc.rrd_file}")
    return feeder.returncode or measured_code


if __name__ == "__main__":
    sys.exit(main())
