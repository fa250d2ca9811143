"""The project's own generator (``sim_core.diagnosis.synthetic``) over the wide set's space,
with fresh seeds: the second source of ``make validate``.

Drawn as the independent set's README says its passages were drawn (speed 20-160 km/h;
20 % round wheels, 40 % fresh flats 12-110 mm, 40 % worn flats 20-120 mm of depth
(0.7-1.3)·l²/16R; m 350-900 kg, P 45-110 kN, R 0.42-0.50 m; foundation M 150-600 kg,
k 1-4·10⁸ N/m, damping ratio 0.02-0.4 log-uniform, stated in the site file as the wide
set's are; rail roughness 2-10 µm rms unknown to the site; chain 2, 3 or 4 kHz of order 2
or 4 at 10 kHz; noise 1-3 % of P), but simulated by the twin's own physics. The line-speed
truth is the same true wheel, rail and foundation re-simulated at 44.44 m/s without noise.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage
from schemas.site import SiteConfig
from service.clients.synthesize import measure
from service.physics.diagnosis import Diagnoser
from sim_core.diagnosis.forward import Flat, damping_for_ratio
from sim_core.diagnosis.synthetic import Perturbations, SyntheticMeasurement, synthetic_measurement
from sim_core.passage import Foundation
from validation.truth_bounds import truth_fields
from validation.wide_set import fitted_fields

LINE_SPEED = 44.44


def _site(rng: np.random.Generator) -> tuple[SiteConfig, float]:
    M = float(rng.uniform(150, 600))
    k = float(rng.uniform(1e8, 4e8))
    zeta = float(math.exp(rng.uniform(math.log(0.02), math.log(0.4))))
    c = damping_for_ratio(Foundation.compliant(M, k, 0.0), zeta)
    site = SiteConfig.model_validate(
        {
            "site_id": "own",
            "length": 6.0,
            "output_sample_rate": 1e4,
            "contact": "hertz",
            "rail": {"kind": "flat"},
            "material": {"youngs_modulus": 2.14e11, "poisson_ratio": 0.3},
            "foundation": {"kind": "compliant", "mass": M, "stiffness": k, "damping": c},
            "diagnosis": {
                "line_speed": LINE_SPEED,
                "sensor_lowpass_hz": float(rng.choice([2000.0, 3000.0, 4000.0])),
                "sensor_lowpass_order": int(rng.choice([2, 4])),
                "sample_rate": 1e4,
            },
        }
    )
    return site, zeta


def draw_case(
    i: int, rng: np.random.Generator
) -> tuple[str, Flat | None, SiteConfig, WheelPassage, float]:
    u = rng.uniform()
    kind = "round" if u < 0.2 else ("flat" if u < 0.6 else "rounded_flat")
    site, zeta = _site(rng)
    R = float(rng.uniform(0.42, 0.5))
    p = WheelPassage(
        passage_id=f"o{i:03d}",
        train_id="own",
        axle_index=i % 100,
        side="right",
        timestamp=0.0,
        speed=float(rng.uniform(20, 160) / 3.6),
        load=float(rng.uniform(45e3, 110e3)),
        mass=float(rng.uniform(350, 900)),
        radius=R,
    )
    phase = float(rng.uniform(0, 2 * math.pi))
    tread: Flat | None = None
    if kind == "flat":
        tread = Flat.ideal(R, float(rng.uniform(0.012, 0.110)), phase)
    elif kind == "rounded_flat":
        ln = float(rng.uniform(0.020, 0.120))
        tread = Flat.rounded(R, ln, float(rng.uniform(0.7, 1.3)) * ln * ln / (16 * R), phase)
    return kind, tread, site, p, zeta


def draw_record(rng: np.random.Generator) -> tuple[int, float, float]:
    """(seed, noise fraction, roughness rms) of a case's record, drawn after the case."""
    return (
        int(rng.integers(2**31)),
        float(rng.uniform(0.01, 0.03)),
        float(rng.uniform(2e-6, 10e-6)),
    )


@dataclass(frozen=True)
class MeasuredCase:
    """One case drawn and measured: the truth, the site's Diagnoser and the record."""

    kind: str
    tread: Flat | None
    site: SiteConfig
    passage: WheelPassage
    damping_ratio: float
    diagnoser: Diagnoser
    synthesized: SyntheticMeasurement
    measured: MeasuredPassage
    seed: int
    noise: float
    roughness: float


def measured_case(i: int, rng: np.random.Generator) -> MeasuredCase:
    """Case ``i`` drawn from ``rng`` (``draw_case``, ``draw_record``) and measured."""
    kind, tread, site, p, zeta = draw_case(i, rng)
    seed, noise, rough = draw_record(rng)
    d = Diagnoser(site)
    m = measure(
        site, p, tread, seed=seed, noise=noise, roughness=rough, damping_ratio=None, diagnoser=d
    )
    mp = MeasuredPassage(
        passage_id=p.passage_id,
        sample_rate=m.sample_rate,
        t_start=m.t_start,
        force=m.force.tolist(),
    )
    return MeasuredCase(kind, tread, site, p, zeta, d, m, mp, seed, noise, rough)


def skip_cases(n: int, rng: np.random.Generator) -> None:
    """Draw what the first ``n`` cases draw, without simulating them (``rng`` then gives
    case ``n`` as ``run_all`` would)."""
    for i in range(n):
        draw_case(i, rng)
        draw_record(rng)


def run_case(i: int, rng: np.random.Generator) -> dict[str, Any]:
    c = measured_case(i, rng)
    kind, tread, site, p, zeta = c.kind, c.tread, c.site, c.passage, c.damping_ratio
    d, m, mp, seed, noise, rough = (
        c.diagnoser,
        c.synthesized,
        c.measured,
        c.seed,
        c.noise,
        c.roughness,
    )
    cpu = time.process_time()
    diag, curves = d.diagnose(p, mp)
    cpu = time.process_time() - cpu
    line_truth = None
    bounds: dict[str, Any] = {}
    if tread is not None:
        wheel = d.wheel(p)
        lm = synthetic_measurement(
            wheel,
            LINE_SPEED,
            tread,
            d.physics.base_rail,
            site.length,
            m.sample_rate,
            d.sensor,
            Perturbations(noise_fraction=0.0, roughness_rms=rough, seed=seed),
        )
        line_truth = float(np.max(lm.force))
        bounds = truth_fields(
            d, p, mp, tread.kind, tread.length, tread.depth, tread.phase, line_truth
        )
    return {
        "case": p.passage_id,
        "index": i,
        "source": "own",
        "kind": kind,
        "true_length": tread.length if tread else 0.0,
        "true_depth": tread.depth if tread else None,
        "speed_kmh": p.speed * 3.6,
        "true_damping_ratio": zeta,
        "true_peak": m.true_peak_force,
        "true_noise": noise * p.load,
        "line_truth": line_truth,
        **fitted_fields(diag, curves, cpu),
        **bounds,
    }


def run_all(n: int, seed: int) -> list[dict[str, Any]]:
    from validation.wide_set import summary_line

    rng = np.random.default_rng(seed)
    rows = []
    for i in range(n):
        r = run_case(i, rng) | {"seed": seed}
        rows.append(r)
        print(summary_line(r), file=sys.stderr, flush=True)
    return rows


__all__ = [
    "LINE_SPEED",
    "MeasuredCase",
    "draw_case",
    "draw_record",
    "measured_case",
    "run_all",
    "run_case",
    "skip_cases",
]
