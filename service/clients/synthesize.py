"""Synthetic measured passages for a site: ``railtwin synthesize``.

    railtwin synthesize --site examples/site_compliant.toml --passage P.json
        [--flat flat|rounded_flat --length 0.05 --phase 1.0] [--seed 1]
        [--noise 0.03] [--roughness 3e-6] [--damping-ratio 0.15] [--speed-error 0.01]
        --out MEASURED.csv

Simulates the passage's wheel (with the given flat, or its own outline) over the site
with what the twin does not know added (``sim_core.diagnosis.synthetic``), through the
site's measuring chain, and writes the CSV ``railtwin diagnose`` reads (``t_s,force_N``).
At a site with a detector (a rail on discrete supports or slab with cribs) it writes the
detector's crib channels instead (``t_s,<crib ids>``; ``sim_core.diagnosis.crib_synthetic``:
the site's own track, unknown roughness and noise; ``--damping-ratio`` and
``--speed-error`` belong to the one-mass foundation and are not used there).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.wire.site import load_site

if TYPE_CHECKING:  # the physics (numba, scipy) is imported when used: ``railtwin --help`` is quick
    from service.physics.diagnosis import Diagnoser
    from sim_core.diagnosis.crib_synthetic import CribRecord
    from sim_core.diagnosis.forward import Tread
    from sim_core.diagnosis.synthetic import SyntheticMeasurement


def measure(
    site: SiteConfig,
    passage: WheelPassage,
    tread: Tread | None,
    *,
    seed: int,
    noise: float = 0.03,
    roughness: float = 3e-6,
    damping_ratio: float | None = 0.15,
    speed_error: float = 0.0,
    diagnoser: Diagnoser | None = None,
) -> SyntheticMeasurement:
    """What the site would measure of ``passage`` with ``tread`` (None: round)."""
    from service.physics.diagnosis import Diagnoser
    from sim_core.diagnosis.forward import damping_for_ratio
    from sim_core.diagnosis.synthetic import Perturbations, synthetic_measurement

    d = diagnoser or Diagnoser(site)
    wheel = d.wheel(passage)
    damping = None
    f = wheel.foundation
    if damping_ratio is not None and f.is_compliant:
        damping = damping_for_ratio(f, damping_ratio)
    rate = site.diagnosis.sample_rate or 10_000.0
    return synthetic_measurement(
        wheel,
        passage.speed,
        tread,
        d.physics.base_rail,
        site.length,
        rate,
        d.sensor,
        Perturbations(noise, roughness, damping, speed_error, seed),
    )


def measure_channels(
    site: SiteConfig,
    passage: WheelPassage,
    tread: Tread | None,
    *,
    seed: int,
    noise: float = 0.02,
    roughness: float = 3e-6,
    diagnoser: Diagnoser | None = None,
) -> CribRecord:
    """What the site's detector would record of ``passage`` with ``tread`` (None: round);
    ``ValueError`` at a site without a detector on a rail on supports."""
    from service.physics.diagnosis import Diagnoser
    from sim_core.diagnosis.crib_forward import CribWheel
    from sim_core.diagnosis.crib_synthetic import crib_record

    d = diagnoser or Diagnoser(site)
    if d.crib_site is None:
        raise ValueError(f"site {site.site_id!r} has no detector on a rail on supports")
    wheel = CribWheel(passage.mass, passage.load, passage.radius, d.physics.contact_model(passage))
    return crib_record(
        d.crib_site,
        wheel,
        passage.speed,
        tread,
        sample_rate=site.diagnosis.sample_rate or 10_000.0,
        noise_fraction=noise,
        roughness_rms=roughness,
        seed=seed,
    )


def measured_passage(
    site: SiteConfig,
    passage: WheelPassage,
    tread: Tread | None,
    *,
    seed: int,
    diagnoser: Diagnoser | None = None,
) -> tuple[MeasuredPassage, float]:
    """The site's measurement of ``passage`` as the twin receives it (the contact force, or
    the detector's channels where the site has one), with default perturbations; and the
    true peak contact force (N)."""
    from service.physics.diagnosis import Diagnoser

    d = diagnoser or Diagnoser(site)
    if d.crib_site is not None:
        rec = measure_channels(site, passage, tread, seed=seed, diagnoser=d)
        ids = [c.id for c in d.crib_site.cribs]
        return (
            MeasuredPassage(
                passage_id=passage.passage_id,
                sample_rate=rec.sample_rate,
                t_start=0.0,
                channels={i: row.tolist() for i, row in zip(ids, rec.channels, strict=True)},
                speed=passage.speed,
            ),
            rec.true_peak_force,
        )
    m = measure(site, passage, tread, seed=seed, diagnoser=d)
    return (
        MeasuredPassage(
            passage_id=passage.passage_id,
            sample_rate=m.sample_rate,
            t_start=m.t_start,
            force=m.force.tolist(),
            speed=passage.speed,
        ),
        m.true_peak_force,
    )


def passage_tread(passage: WheelPassage) -> Tread | None:
    """The passage's own outline as a tread (None if round)."""
    from service.physics.site_physics import wheel_outline
    from sim_core.diagnosis.forward import MeasuredTread

    if passage.outline.kind == "round":
        return None
    return MeasuredTread(wheel_outline(passage), passage.phase)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """The options of ``railtwin synthesize``."""
    p.add_argument("--site", type=Path, required=True)
    p.add_argument("--passage", type=Path, required=True)
    p.add_argument(
        "--flat",
        choices=("flat", "rounded_flat"),
        default=None,
        help="put this flat on the wheel (default: the passage's own outline)",
    )
    p.add_argument("--length", type=float, default=0.05, help="flat length, m")
    p.add_argument("--phase", type=float, default=1.0, help="flat position φ0, rad")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--noise", type=float, default=0.03, help="noise, fraction of the load")
    p.add_argument("--roughness", type=float, default=3e-6, help="unknown rail roughness rms, m")
    p.add_argument("--damping-ratio", type=float, default=0.15, help="true foundation damping")
    p.add_argument("--speed-error", type=float, default=0.0, help="true/reported speed - 1")
    p.add_argument("--out", type=Path, required=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="railtwin synthesize", description=__doc__.split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


def run(a: argparse.Namespace) -> int:
    """Write the synthetic measured force of one passage as CSV (t_s,force_N)."""
    site = load_site(a.site)
    passage = WheelPassage.model_validate_json(a.passage.read_text(encoding="utf-8"))
    return write_measurement(a, site, passage)


def write_measurement(a: argparse.Namespace, site: SiteConfig, passage: WheelPassage) -> int:
    """``run`` with the site and the passage read (``railtwin synthesize`` reads and checks
    them itself)."""
    import numpy as np

    from sim_core.diagnosis.forward import Flat

    R = passage.radius
    tread: Tread | None = passage_tread(passage)
    if a.flat == "flat":
        tread = Flat.ideal(R, a.length, a.phase)
    elif a.flat == "rounded_flat":
        tread = Flat.rounded(R, a.length, None, a.phase)
    from service.physics.diagnosis import Diagnoser

    d = Diagnoser(site)
    if d.crib_site is not None:
        rec = measure_channels(
            site, passage, tread, seed=a.seed, noise=a.noise, roughness=a.roughness, diagnoser=d
        )
        ids = ",".join(c.id for c in d.crib_site.cribs)
        rows = np.column_stack([rec.t, rec.channels.T])
        np.savetxt(a.out, rows, delimiter=",", header=f"t_s,{ids}", comments="", fmt="%.9g")
        print(
            f"wrote {a.out}: {rec.channels.shape[0]} crib channels of {rec.channels.shape[1]} "
            f"samples, true peak {rec.true_peak_force / 1e3:.1f} kN"
        )
        return 0
    m = measure(
        site,
        passage,
        tread,
        seed=a.seed,
        noise=a.noise,
        roughness=a.roughness,
        damping_ratio=a.damping_ratio,
        speed_error=a.speed_error,
        diagnoser=d,
    )
    rows = np.column_stack([m.t, m.force])
    np.savetxt(a.out, rows, delimiter=",", header="t_s,force_N", comments="", fmt="%.9g")
    print(f"wrote {a.out}: {m.force.size} samples, true peak {m.true_peak_force / 1e3:.1f} kN")
    return 0


if __name__ == "__main__":
    sys.exit(main())
