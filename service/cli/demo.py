"""``make demo``: the twin on loopback, a sample train streamed to it, where the files are.

    railtwin demo [--site examples/site.toml]
        [--train recordings/samples/train_160kmh.json] [--recordings recordings]

Starts ``railtwin serve`` in a child process on a free loopback port, streams
the sample train at its real timing (one line per wheel: peak force, contact
losses, dent and, at a site with a detector, the crib channels' peak), stops the
service cleanly and prints where its MCAP log and Rerun recording are, and what of
the crib channels they hold. No network beyond loopback, no viewer needed.

The default site (``examples/site.toml``) is a rail on sleepers with an 8-crib detector:
the detector's records of four wheels (made by the generator: the site's track, a rough
rail the twin does not know, noise) are streamed alongside the train and the twin
diagnoses them from their crib channels while the train streams.
``--site examples/site_compliant.toml`` (the paper's lumped foundation) does the same with
a measured contact force.

The demo streams the same sample train every time, so each run starts the twin
on a fresh rail state of its own (a temporary ``--state`` directory): with the
site's persistent state its passage ids would be refused as already applied.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from schemas.messages import TrainFile
from schemas.site import SiteConfig
from service.cli.common import EXIT_USAGE, CommandError, SubParsers
from service.cli.inputs import load_json_file, load_site_file
from service.cli.service_process import ServiceProcess
from service.recording.mcap_log import read_log
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
    """``railtwin demo ARGV``, with its error reporting."""
    from service.cli.main import main as cli_main

    return cli_main(["demo", *(sys.argv[1:] if argv is None else argv)])


def diagnosed(site: SiteConfig) -> bool:
    """Whether the twin diagnoses this site's measurements: a contact force on a rigid or
    one-mass foundation, or a detector's crib channels on a rail on supports."""
    return site.foundation.kind in ("rigid", "compliant") or site.detector is not None


def channels_logged(mcap_files: list[Path], site_id: str) -> str | None:
    """What the MCAP log holds of the crib channels (results and samples that carry them,
    the highest value and its crib), or None when it holds none."""
    results = samples = 0
    peak, where = float("-inf"), ""
    for m in read_log(mcap_files):
        if m.topic == f"railtwin/{site_id}/result":
            result = json.loads(m.data)
            channels = result.get("channels") or {}
            results += bool(channels)
            for crib, values in channels.items():
                if values and max(values) > peak:
                    peak, where = max(values), f"{crib}, passage {result['passage_id']}"
        elif m.topic == f"railtwin/{site_id}/samples":
            samples += b'"channels"' in m.data
    if not results:
        return None
    return (
        f"{results} results carry the crib channels (peak {peak / 1e3:.1f} kN, {where}); "
        f"{samples} samples on railtwin/{site_id}/samples have them "
        f"(Foxglove: /railtwin/{site_id}/samples.channels.<crib>)"
    )


def run(args: argparse.Namespace) -> int:
    """Start the twin, stream the train and the measurements, print where the files are."""
    site = load_site_file(args.site, served=True)
    load_json_file(args.train, "train", TrainFile)  # refused here, not by the feeder later
    if args.recordings.exists() and not args.recordings.is_dir():
        raise CommandError(f"--recordings {args.recordings}: not a directory", EXIT_USAGE)
    endpoint = free_tcp_endpoint()
    print(
        f"demo: starting railtwin serve for site {site.site_id!r} on {endpoint} "
        "(the first start compiles the physics: allow a few minutes; up to 15 are waited for)",
        flush=True,
    )
    args.recordings.mkdir(parents=True, exist_ok=True)
    # the measurements are made while the service starts (both take seconds)
    generator = _generate_measurements(args, site) if diagnosed(site) else None
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
        measured_proc = None
        if generator is not None:
            generator.wait()
            measured_proc = _stream_measurements(args, endpoint)
        else:
            _no_measurements(site)
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
        measured_code = measured_proc.wait() if measured_proc is not None else 0
    if svc.returncode != 0:
        print(svc.output, file=sys.stderr)
        return 1
    print("\ndemo: done.", flush=True)
    for f in svc.mcap_files:
        print(f"demo: MCAP log (open in Foxglove):      {f}")
    if svc.rrd_file is not None:
        print(f"demo: Rerun recording (rerun FILE.rrd): {svc.rrd_file}")
    if site.detector is not None:
        logged = channels_logged(svc.mcap_files, site.site_id)
        if logged is None:
            print("demo: the MCAP log holds no crib channels", file=sys.stderr)
            return 1
        cribs = [c.id for c in site.detector.cribs]
        print(f"demo: MCAP: {logged}")
        if svc.rrd_file is not None:
            print(
                f"demo: Rerun: the {len(cribs)} channels at /{site.site_id}/channels/"
                f"{{{','.join(cribs)}}}, one plot each beside the force (tab Crib channels)"
            )
    return feeder.returncode or measured_code


def _measured_cmd(args: argparse.Namespace) -> list[str]:
    return [*RAILTWIN, "feed-measured", "--train", str(args.train), "--site-file", str(args.site)]


def _saved(args: argparse.Namespace) -> Path:
    return Path(args.recordings) / "demo-measured.json"


def _generate_measurements(args: argparse.Namespace, site: SiteConfig) -> subprocess.Popen[bytes]:
    """Start making the measurement of four wheels (the contact force, or the detector's
    crib channels) into ``recordings/demo-measured.json`` (``railtwin feed-measured --save``)."""
    what = (
        f"detector's {len(site.detector.cribs)} crib channels"
        if site.detector is not None
        else "measured force"
    )
    print(
        f"demo: the site's {what} of four wheels, made by the generator "
        "(each wheel's own outline, unknown roughness, sensor chain and noise)",
        flush=True,
    )
    return subprocess.Popen([*_measured_cmd(args), "--save", str(_saved(args))], cwd=ROOT)


def _stream_measurements(args: argparse.Namespace, endpoint: str) -> subprocess.Popen[bytes]:
    """Publish each made measurement when its wheel leaves the site, alongside the train
    (``railtwin feed-measured --load``)."""
    print(
        "demo: streaming the train; each measurement follows its wheel off the site, "
        "and the twin diagnoses it while the train streams",
        flush=True,
    )
    return subprocess.Popen(
        [
            *_measured_cmd(args),
            "--load",
            str(_saved(args)),
            "--with-train",
            "--connect",
            endpoint,
            "--timeout",
            "120",
        ],
        cwd=ROOT,
    )


def _no_measurements(site: SiteConfig) -> None:
    """Say why no measurement is sent: a rail on supports without a detector measures none."""
    print(
        f"demo: streaming the train over a rail on sleepers ({site.foundation.kind}) with no "
        "detector: no measurements to diagnose (examples/site.toml has an 8-crib detector)",
        flush=True,
    )


if __name__ == "__main__":
    sys.exit(main())
