"""Rounded flats on cosines whose cells are only partly certified (sim_core.constraint.cosine_hybrid):
the piece sweep outside the windows where the uncertified cells can carry the wheel, the
ψ-search inside, against the ψ-search alone and brute force.

Cases: the 80 mm, l²/16R-deep flat on the paper's cosine (a = 0.1 mm, λ = 5 cm: its hollow's
middle ±0.035 rad is not certified) and on a steep one with a < 0 (0.2 mm, 8 cm: ±0.014 rad),
each at several phases, on stretches that hold a window and sweep on both sides: values within
1e-12 m of the ψ-search's table at 99.9 % of 20 000 points (1e-11 m everywhere), exact (brute
force over ψ) where the two differ most and at random points, node values within 1e-12 m of
the exact solve, the same kinks (slope jumps > 1e-6) within 1e-9 m, slopes equal to finite
differences of the exact solve. The windows themselves are checked by brute force: outside
them the uncertified cells never carry the wheel, inside they do somewhere.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim_core.constraint import tabulate_constraint
from sim_core.constraint.cosine_cells import UNCERTIFIED, cell_cover, uncertified_spans
from sim_core.constraint.cosine_hybrid import contact_windows, supports_cosine_hybrid
from sim_core.constraint.wheel_pieces import cosine_cover, supports, wheel_pieces
from sim_core.rail import RailProfile
from tests.test_constraint_cosine_cells import check_flat_window, flat_window, site_flat

R = 0.46
PAPER = RailProfile.cosine(1e-4, 0.05)
STEEP = RailProfile.cosine(-2e-4, 0.08)
CASES = {
    "paper cosine, 80 mm l²/16R": (PAPER, site_flat(0.08)),
    "steep cosine, 80 mm l²/16R": (STEEP, site_flat(0.08)),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("phase", [0.013, 2.9, -1.1])
def test_hybrid_against_general_and_brute_force(case: str, phase: float) -> None:
    rail, wheel = CASES[case]
    assert not supports(wheel, rail) and supports_cosine_hybrid(wheel, rail)
    lo, hi = flat_window(phase, 0.06)
    # the stretch holds one window with swept stretches on both sides
    wins = contact_windows(wheel, rail, phase, lo, hi)
    assert len(wins) == 1 and lo + 0.01 < wins[0][0] < wins[0][1] < hi - 0.01
    check_flat_window(wheel, rail, phase, (lo, hi))


def test_hybrid_over_a_passage() -> None:
    """6 m (three windows, one cut by the stretch's start): the same table as the ψ-search."""
    rail, wheel = CASES["paper cosine, 80 mm l²/16R"]
    fast = tabulate_constraint(wheel, rail, 0.0, 6.0, phase=0.0)
    gen = tabulate_constraint(wheel, rail, 0.0, 6.0, phase=0.0, method="general")
    assert len(contact_windows(wheel, rail, 0.0, fast.x[0], fast.x[-1])) == 3
    xq = np.random.default_rng(3).uniform(0.0, 6.0, 50000)
    diff = np.abs(fast.evaluate(xq) - gen.evaluate(xq))
    assert diff.max() < 1e-12
    kf = fast.kinks[(fast.kinks > 0.0) & (fast.kinks < 6.0)]
    kg = gen.kinks[(gen.kinks > 0.0) & (gen.kinks < 6.0)]
    assert kf.size == kg.size and kf.size >= 2 and np.abs(kf - kg).max() < 1e-9


@pytest.mark.parametrize("case", list(CASES))
def test_windows_hold_every_position_where_uncertified_cells_carry_the_wheel(case: str) -> None:
    """Brute force over ψ at many wheel positions within ψ_max of the uncertified span, at phases
    that put the flat's middle over a crest, a trough and in between: where the span's best is
    the wheel's maximum, the position is inside a window; and that happens (over a crest)."""
    rail, wheel = CASES[case]
    cells, psi_max = cosine_cover(wheel, rail)
    ((u0, u1),) = uncertified_spans(cells)
    lam = rail.wavelength
    crest = 0.0 if rail.amplitude > 0 else 0.5 * lam
    psi = np.linspace(-0.12, 0.12, 120001)
    carried = 0
    for shift in (0.0, 0.25, 0.5):
        phase = -(crest + shift * lam) / R  # φ = 0 (the flat's middle at the bottom) over it
        # positions where φ = phase + x/R runs over the span widened by ψ_max
        x = R * (np.linspace(u0 - psi_max, u1 + psi_max, 601) - phase)
        wins = contact_windows(wheel, rail, phase, x[0] - 1.0, x[-1] + 1.0)
        inside = np.zeros(x.size, bool)
        for a, b in wins:
            inside |= (x >= a) & (x <= b)
        for i, xc in enumerate(x):
            phi = phase + xc / R
            rho = wheel.radius_at(psi + phi)
            g = rail.height(xc + rho * np.sin(psi)) + rho * np.cos(psi)
            span = (psi + phi >= u0) & (psi + phi <= u1)
            if span.any() and g[span].max() >= g[~span].max() - 1e-15:
                carried += 1
                assert inside[i], f"the span carries the wheel at x = {xc} outside {wins}"
        # the windows are narrower than ψ_max alone would make them
        assert sum(b - a for a, b in wins) < 0.8 * R * (u1 - u0 + 2 * psi_max)
    assert carried > 0


def test_cover_marks_the_uncertified_cells() -> None:
    """The paper's case: the hollow's middle is UNCERTIFIED, every other cell certified."""
    rail, wheel = CASES["paper cosine, 80 mm l²/16R"]
    cells = cell_cover(wheel, rail, wheel_pieces(wheel))
    bad = cells[cells[:, 6] == UNCERTIFIED]
    assert bad.shape[0] == 1 and np.allclose(bad[0, :2], [-0.035, 0.035], atol=1e-3)
    assert np.all(np.isin(cells[cells[:, 6] != UNCERTIFIED, 6], [0, 1, 2, 3]))


def test_all_uncertified_is_the_general_search() -> None:
    """A cosine curved more than the round wheel (0.1 mm, 3 cm: a k² = 4.4 > 1/R) leaves even the
    round rest uncertified: the window is the whole stretch, the ψ-search's table."""
    rail = RailProfile.cosine(1e-4, 0.03)
    wheel = site_flat(0.06)
    assert supports_cosine_hybrid(wheel, rail)
    assert contact_windows(wheel, rail, 0.0, 0.0, 0.2) == [(0.0, 0.2)]
    fast = tabulate_constraint(wheel, rail, 0.0, 0.2)
    gen = tabulate_constraint(wheel, rail, 0.0, 0.2, method="general")
    xq = np.random.default_rng(8).uniform(0.0, 0.2, 5000)
    assert np.abs(fast.evaluate(xq) - gen.evaluate(xq)).max() < 1e-12
