"""The general ψ-search's table between its nodes, against the exact solve and brute force.

The ψ-search refines an interval until its cubic Hermite matches the exact solve at the
midpoint, in value and in slope. A value-only check misses an error odd about the midpoint:
on a rounded flat over a rough sampled rail it left 2.4e-12 m at an interval's quarter
points, 24 times the table's tolerance (HERMITE_TOL = 1e-13 m). Here every interval the
refinement leaves holds the exact solve within 2e-13 m at 7 interior points, and the worst of
them hold the brute-force maximum over ψ. The same holds for the cosine hybrid, whose flat
windows the ψ-search tabulates (a short cosine: 6.6e-13 m there with the value-only check).

An ideal flat's corner 0.4 µm beside a rail vertex is a maximum the ψ grid cannot see: the
solve took the next vertex instead, 7.6e-11 m too low over 70 nm of x at x = 0.0197185, and
the table showed two 'kinks' 6 pm apart and 5.0e-11 m in the 20 nm interval after them. The
corners are now evaluated exactly; the solve there is the brute-force maximum, and the table's
kink is where the polyline sweep puts it.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_core.constraint import evaluate_exact, tabulate_constraint
from sim_core.constraint.cosine_hybrid import supports_cosine_hybrid
from sim_core.constraint.polyline import supports_polyline
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from tests.test_constraint_cosine_cells import brute
from tests.test_constraint_polyline import reference, rough_rail

R = 0.46

CASES = {
    # the flat faces the rail at x = 0.02 m; the round part, sliding over the roughness,
    # showed the odd error at x = -0.0382 (h = 15.6 µm)
    "rounded flat 80 mm, rough rail": (
        WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R)),
        rough_rail(),
        (-0.04, 0.06),
        -0.02 / R,
    ),
    "ideal flat 50 mm, rough rail": (
        WheelOutline.ideal_flat(R, 0.05),
        rough_rail(),
        (-0.04, 0.06),
        -0.02 / R,
    ),
    # the cosine hybrid's case: the ψ-search takes the flat's windows on the paper's cosine
    "rounded flat l²/16R, paper cosine": (
        WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R)),
        RailProfile.cosine(1e-4, 0.05),
        (-0.05, 0.05),
        0.0,
    ),
}

HYBRID = {
    # a 7 µm / 13 mm cosine: the flat faces the rail at x = -0.006 m
    "rounded flat l²/16R, short cosine": (
        WheelOutline.rounded_flat(R, 0.08, 0.08**2 / (16 * R)),
        RailProfile.cosine(7e-6, 0.013),
        (-0.066, 0.054),
        0.013,
    ),
}


def interior(x: NDArray[np.float64], lo: float, hi: float) -> NDArray[np.float64]:
    """7 points inside each interval of the nodes ``x`` in [lo, hi], one row per interval."""
    a, b = x[:-1], x[1:]
    keep = (a >= lo) & (b <= hi)
    a, b = a[keep], b[keep]
    return a[:, None] + (b - a)[:, None] * (np.arange(1, 8) / 8.0)[None, :]


@pytest.mark.parametrize(
    ("case", "method"),
    [(c, "general") for c in CASES] + [(c, "auto") for c in HYBRID],
)
def test_general_table_between_nodes(case: str, method: str) -> None:
    wheel, rail, (lo, hi), phase = {**CASES, **HYBRID}[case]
    if method == "auto":
        assert supports_cosine_hybrid(wheel, rail)
    t = tabulate_constraint(wheel, rail, lo, hi, phase=phase, method=method)
    xq = interior(t.x, lo, hi)
    assert xq.shape[0] > 300
    exact, _ = evaluate_exact(wheel, rail, xq.ravel(), phase=phase)
    err = np.abs(t.evaluate(xq.ravel()) - exact)
    assert err.max() < 2e-13, f"{err.max():.3e} m at x = {xq.ravel()[err.argmax()]:.9f}"
    # the exact solve is the brute-force maximum where the table misses it most
    worst = xq.ravel()[np.argsort(err)[-4:]]
    ref = (
        reference(wheel, rail, worst, phase)
        if rail.kind == "sampled"
        else brute(wheel, rail, worst, phase)
    )
    assert np.abs(ref - t.evaluate(worst)).max() < 1e-12


def test_flat_corner_beside_a_rail_vertex() -> None:
    """The 50 mm flat's trailing corner at x_D = -5.0004 mm, 0.4 µm left of a rail vertex,
    carries the wheel up to x = 0.01971856 m, where the vertex at x_D = -4.5 mm takes over."""
    wheel, rail, (lo, hi), phase = CASES["ideal flat 50 mm, rough rail"]
    x = np.linspace(0.0197184, 0.0197187, 61)
    exact, xd = evaluate_exact(wheel, rail, x, phase=phase)
    assert np.abs(exact - reference(wheel, rail, x, phase)).max() < 1e-15
    on_corner = np.abs(xd + 5.0004e-3) < 1e-7
    assert on_corner[:30].all() and not on_corner[-10:].any()
    general = tabulate_constraint(wheel, rail, lo, hi, phase=phase, method="general")
    assert supports_polyline(wheel, rail) and not supports_cosine_hybrid(wheel, rail)
    sweep = tabulate_constraint(wheel, rail, 0.015, 0.025, phase=phase)  # the polyline sweep
    near = general.kinks[np.abs(general.kinks - 0.0197185) < 1e-6]
    swept = sweep.kinks[np.abs(sweep.kinks - 0.0197185) < 1e-6]
    assert near.size == 1 and swept.size == 1
    assert abs(near[0] - swept[0]) < 1e-12
