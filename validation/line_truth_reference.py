"""The own generator's line-speed truth, re-computed by the test suite's slow reference solver.

``validation.own_generator`` takes its line-speed truth (the peak the site's chain would
measure of the true wheel, rail and foundation at 44.44 m/s) from the project's own
integrator. This re-integrates the same passage with ``tests.reference_solver`` (SciPy's
DOP853 one contact mode at a time, terminal events per mode, restarted at every kink and
curvature jump of the constraint), on the same constraint table (the true flat on the
rough rail), from the same static start, and passes its force through the same chain.
What it checks is the integration and its event location at line speed, where the wheel
bounces hardest; the table itself is checked against closed forms in ``tests/``.

    .venv/bin/python -m validation.line_truth_reference [--seed 20261201] [--cases 6]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass
from multiprocessing import get_context

import numpy as np

from sim_core.diagnosis.forward import wheel_table
from sim_core.diagnosis.synthetic import Perturbations, simulated_passage
from tests import reference_solver as rs
from validation.own_generator import LINE_SPEED, measured_case, skip_cases

RTOL = 1e-9
"""The reference's tolerance: far below the 1e-4 at which peaks are compared."""


@dataclass(frozen=True)
class LineTruthRow:
    """One flat: the line-speed peak the chain measures, by both solvers (N)."""

    seed: int
    case: str
    kind: str
    length: float
    ours: float
    reference: float
    seconds: float

    @property
    def error(self) -> float:
        return self.ours / self.reference - 1.0


def reference_row(seed: int, i: int) -> LineTruthRow | None:
    """Case ``i`` of ``seed``'s own generator at line speed by both solvers (None: round)."""
    rng = np.random.default_rng(seed)
    skip_cases(i, rng)
    c = measured_case(i, rng)
    if c.tread is None:
        return None
    d = c.diagnoser
    rate = c.measured.sample_rate
    # the own generator's line-speed truth, recomputed: the same passage and chain
    sim = simulated_passage(
        d.wheel(c.passage),
        LINE_SPEED,
        c.tread,
        d.physics.base_rail,
        c.site.length,
        rate,
        d.sensor,
        Perturbations(noise_fraction=0.0, roughness_rms=c.roughness, seed=c.seed),
    )
    wheel, speed, rails, x_end, ours = sim.wheel, sim.speed, sim.rails, sim.x_end, sim.output
    t_meas = sim.t_measure
    peak_ours = float(np.max(d.sensor.measure(ours.t, ours.force, t_meas)))
    start = time.perf_counter()
    t0 = float(ours.t[0])
    table = wheel_table(wheel.radius, c.tread, rails, speed * t0, x_end)
    f = wheel.foundation
    prob = rs.Problem(
        rs.table_constraint(table),
        wheel.mass,
        wheel.load,
        speed,
        "hertz",
        rs.paper_constants(
            c.site.material.youngs_modulus,
            c.site.material.poisson_ratio,
            wheel.radius,
            wheel.load,
            wheel.mass,
        ),
        f.mass,
        f.stiffness,
        f.damping,
    )
    t1 = float(ours.t[-1])
    r = rs.solve(
        prob,
        prob.static_state(t0),
        t0,
        t1,
        sample_t=ours.t,
        breaks=rs.table_breaks(table, t0, x_end / speed, speed),
        rtol=RTOL,
        atol=1e-13,
    )
    peak_ref = float(np.max(d.sensor.measure(ours.t, r.force, t_meas)))
    return LineTruthRow(
        seed,
        c.passage.passage_id,
        c.tread.kind,
        c.tread.length,
        peak_ours,
        peak_ref,
        time.perf_counter() - start,
    )


def _row(key: tuple[int, int]) -> LineTruthRow | None:
    return reference_row(*key)


def reference_rows(keys: list[tuple[int, int]], processes: int = 2) -> list[LineTruthRow]:
    """``reference_row`` of each (seed, case index), in ``processes`` processes."""
    if processes <= 1 or len(keys) <= 1:
        rows = [_row(k) for k in keys]
    else:
        with get_context("fork").Pool(processes) as pool:
            rows = pool.map(_row, keys, chunksize=1)
    return [r for r in rows if r is not None]


def summary(rows: list[LineTruthRow]) -> str:
    """The table of both solvers' peaks, and the largest relative difference."""
    lines = [
        "| seed | case | kind | length mm | own integrator kN | SciPy reference kN | difference |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.seed} | {r.case} | {r.kind} | {r.length * 1e3:.1f} | {r.ours / 1e3:.1f} "
            f"| {r.reference / 1e3:.1f} | {r.error:+.1e} |"
        )
    worst = max((abs(r.error) for r in rows), default=0.0)
    lines += [
        "",
        f"- {len(rows)} line-speed truths re-integrated by the reference solver: largest "
        f"relative difference {worst:.1e} ({sum(r.seconds for r in rows):.0f} s of SciPy)",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m validation.line_truth_reference", description=__doc__.split("\n")[0]
    )
    p.add_argument("--seed", type=int, default=20261201)
    p.add_argument("--cases", type=int, default=6, help="the first N cases (round ones skipped)")
    a = p.parse_args(argv)
    print(summary(reference_rows([(a.seed, i) for i in range(a.cases)])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
