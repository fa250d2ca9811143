"""Rounded flats and sampled wheels on cosine rails by the piece sweep on certified cells
(sim_core.constraint.cosine_cells) against the general ψ-search and brute force.

Cosines: the example site's gentle one (a = 2 µm, λ = 6 cm), a short one (3 µm, 2 cm), the
paper's (0.1 mm, 5 cm: the one on which simply allowing the sweep on rounded flats was
3.3e-5 m off) and a steep one with a < 0 (0.2 mm, 8 cm); rounded flats of several lengths and
depths that the cells certify there, each at several phases, on windows where the flat carries
the wheel: values within 1e-12 m of the ψ-search's table at 99.9 % of 20 000 points (1e-11 m
everywhere), the fast table exact (brute force over ψ) where the two differ most and at random
points, node values within 1e-12 m of the exact solve, the same kinks (slope jumps > 1e-6)
within 1e-9 m, slopes equal to finite differences of the exact solve away from kinks. The
certificate itself is checked by brute force: no certified cell has two local maxima.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_core.constraint import tabulate_constraint
from sim_core.constraint.cosine_cells import certified_cells, contact_angle_bound
from sim_core.constraint.cosine_hybrid import supports_cosine_hybrid
from sim_core.constraint.wheel_pieces import supports, wheel_pieces
from sim_core.rail import RailProfile
from sim_core.wheel import WheelOutline
from tests.test_constraint_fast import compare, measured
from tests.test_constraint_flat_cosine import check_window

R = 0.46
SITE = RailProfile.cosine(2e-6, 0.06)
SHORT = RailProfile.cosine(3e-6, 0.02)
PAPER = RailProfile.cosine(1e-4, 0.05)
STEEP = RailProfile.cosine(-2e-4, 0.08)


def site_flat(length: float) -> WheelOutline:
    """A rounded flat of the example site's form: depth l²/16R."""
    return WheelOutline.rounded_flat(R, length, length**2 / (16 * R))


CASES = {
    "site cosine, 80 mm l²/16R": (SITE, site_flat(0.08)),
    "site cosine, 30 mm l²/16R": (SITE, site_flat(0.03)),
    "short cosine, 30 mm l²/16R": (SHORT, site_flat(0.03)),
    "short cosine, 80 mm x 1.5 mm": (SHORT, WheelOutline.rounded_flat(R, 0.08, 1.5e-3)),
    "paper cosine, 80 mm x 1.5 mm": (PAPER, WheelOutline.rounded_flat(R, 0.08, 1.5e-3)),
    "paper cosine, 50 mm x 1 mm": (PAPER, WheelOutline.rounded_flat(R, 0.05, 1e-3)),
    "steep cosine, 50 mm x 1 mm": (STEEP, WheelOutline.rounded_flat(R, 0.05, 1e-3)),
}


def brute(
    wheel: WheelOutline, rail: RailProfile, x: NDArray[np.float64], phase: float
) -> NDArray[np.float64]:
    """max over a dense ψ grid (numpy) in ±0.12 rad (beyond every flat's reach here): within ~1e-13 m."""
    out = np.empty(x.size)
    psi = np.linspace(-0.12, 0.12, 480001)
    for i, xc in enumerate(x):
        phi = phase + xc / R
        rho = wheel.radius_at(psi + phi)
        out[i] = np.max(rail.height(xc + rho * np.sin(psi)) + rho * np.cos(psi)) - R
    return out


def flat_window(phase: float, half: float) -> tuple[float, float]:
    """The wheel positions where the flat's centre is within ``half`` of the bottom."""
    turn = 2 * np.pi * R
    centre = (-phase * R) % turn
    centre -= turn if centre > 0.5 * turn else 0.0
    return centre - half, centre + half


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("phase", [0.0, 0.013, 2.9])
def test_rounded_flat_on_cosine_against_general_and_brute_force(case: str, phase: float) -> None:
    rail, wheel = CASES[case]
    assert supports(wheel, rail)
    check_flat_window(wheel, rail, phase, flat_window(phase, 0.06))


def check_flat_window(
    wheel: WheelOutline, rail: RailProfile, phase: float, window: tuple[float, float]
) -> None:
    """The table (auto) on a window where the flat carries the wheel against the ψ-search's
    and brute force (module docstring)."""
    lo, hi = window
    fast = tabulate_constraint(wheel, rail, lo, hi, phase=phase)
    gen = tabulate_constraint(wheel, rail, lo, hi, phase=phase, method="general")
    xq = np.random.default_rng(17).uniform(lo, hi, 20000)
    diff = np.abs(fast.evaluate(xq) - gen.evaluate(xq))
    assert np.quantile(diff, 0.999) < 1e-12 and diff.max() < 1e-11
    # where the two differ most, and at random points, the fast table is the exact one
    pts = np.concatenate((xq[np.argsort(diff)[-6:]], xq[:10]))
    assert np.abs(brute(wheel, rail, pts, phase) - fast.evaluate(pts)).max() < 1e-12
    # the flat carries the wheel: the centre drops below where a round wheel could be
    assert fast.y.min() < -abs(rail.amplitude) - 0.1 * wheel.flat_depth
    # node values, the contact on the flat somewhere, kinks and slopes
    check_window(fast, gen, wheel, rail, (lo, hi), phase, xq[:200], 0.3 * wheel.flat_length)


@pytest.mark.parametrize("rail", [PAPER, STEEP], ids=["paper", "steep"])
def test_measured_wheel_on_a_curved_cosine(rail: RailProfile) -> None:
    """A sampled wheel on a cosine curved more than 0.1/R (the plain sweep's limit) falls out of
    the same cells: all its pieces certified concave by one bound."""
    w = measured()
    cells = certified_cells(w, rail, wheel_pieces(w))
    assert cells is not None and np.all(cells[:, 6] == 0.0)
    fast = tabulate_constraint(w, rail, 1.0, 1.1, phase=0.5)
    gen = tabulate_constraint(w, rail, 1.0, 1.1, phase=0.5, method="general")
    compare(fast, gen, 1.0, 1.1, w, rail, 0.5)


@pytest.mark.parametrize("case", ["site cosine, 80 mm l²/16R", "paper cosine, 80 mm x 1.5 mm"])
def test_certified_cells_have_one_local_maximum(case: str) -> None:
    """The proof, checked: on every cell, at many wheel positions, G (dense ψ grid within the
    bound ψ_max) has at most one interior local maximum, and G'' changes sign at most once on
    RISING/FALLING cells and never on CONCAVE/CONVEX ones."""
    rail, wheel = CASES[case]
    cells = certified_cells(wheel, rail, wheel_pieces(wheel))
    assert cells is not None
    pm = contact_angle_bound(wheel, rail)
    rng = np.random.default_rng(5)
    for u0, u1, shape in cells[:, [0, 1, 6]]:
        for _ in range(60):
            phi = rng.uniform(u0 - pm, u1 + pm)
            x = rng.uniform(-1.0, 1.0)
            psi = np.linspace(max(u0 - phi, -pm), min(u1 - phi, pm), 4001)
            if psi[-1] <= psi[0]:
                continue
            rho = wheel.radius_at(psi + phi)
            g = rail.height(x + rho * np.sin(psi)) + rho * np.cos(psi)
            d1 = np.diff(g)
            maxima = np.sum((d1[:-1] > 0) & (d1[1:] <= 0))
            assert maxima <= 1
            d2 = np.sign(np.diff(g, 2))
            d2 = d2[np.abs(np.diff(g, 2)) > 1e-15]
            changes = np.count_nonzero(np.diff(d2))
            assert changes <= (1 if shape >= 2 else 0)


def test_uncertified_cells_are_marked() -> None:
    """Not covered: a flat whose concave middle is curved less than the rail's crests, e.g. the
    site's 80 mm, l²/16R-deep flat on the paper's cosine (the shortcut's failing case): G'' at
    the flat's centre then takes the sign of the rail's curvature, and G'' = G''' = 0 occurs.
    The cover marks those cells UNCERTIFIED, the sweep alone is refused, and the hybrid takes
    the case (test_constraint_cosine_hybrid)."""
    wheel = site_flat(0.08)
    assert supports(wheel, SITE) and not supports(wheel, PAPER)
    assert certified_cells(wheel, PAPER, wheel_pieces(wheel)) is None
    assert supports_cosine_hybrid(wheel, PAPER) and not supports_cosine_hybrid(wheel, SITE)


def _depth_first_cover(
    wheel: WheelOutline, rail: RailProfile, pieces: NDArray[np.float64]
) -> list[tuple[int, float, float, int]]:
    """The cells (piece, u0, u1, shape) of a cover halved one cell at a time with the scalar
    outline bounds (``_shape``): the reference for ``cell_cover``'s one pass per level."""
    from sim_core.constraint import cosine_cells as cc

    R = wheel.nominal_radius
    psi_max = contact_angle_bound(wheel, rail)
    k = 2.0 * np.pi / rail.wavelength
    out = []
    for i, row in enumerate(pieces):
        if int(row[2]) == 1:  # a chord: kept whole
            continue
        stack = [(float(row[0]), float(row[1]), 0)]
        while stack:
            u0, u1, depth = stack.pop()
            shape = cc._shape(row, R, u0, u1, psi_max, float(rail.amplitude), k)
            if shape < 0 and depth < cc.MAX_HALVINGS:
                um = 0.5 * (u0 + u1)
                stack += [(um, u1, depth + 1), (u0, um, depth + 1)]
                continue
            out.append((i, u0, u1, shape if shape >= 0 else cc.UNCERTIFIED))
    return out


@pytest.mark.parametrize(
    ("length", "amplitude", "wavelength"),
    [(0.08, 1e-4, 0.05), (0.05, 3e-5, 0.03), (0.12, 2e-6, 0.06)],
)
def test_cover_halving_per_level_is_the_cell_by_cell_one(
    length: float, amplitude: float, wavelength: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cell_cover`` halves all of a level's cells in one array pass; its cells and shapes
    are those of halving one cell at a time on the scalar outline bounds (a shallower halving
    limit keeps the reference quick; the hollow on the paper's cosine has an uncertified
    middle, the site's flat none)."""
    from sim_core.constraint import cosine_cells as cc

    monkeypatch.setattr(cc, "MAX_HALVINGS", 9)
    wheel = WheelOutline.rounded_flat(0.46, length, length**2 / (16 * 0.46))
    rail = RailProfile.cosine(amplitude, wavelength)
    pieces = wheel_pieces(wheel)
    R = wheel.nominal_radius
    psi_max = contact_angle_bound(wheel, rail)
    k = 2.0 * np.pi / wavelength
    got = [
        (i, u0, u1, s)
        for i, row in enumerate(pieces)
        if int(row[2]) != 1
        for u0, u1, s in cc._cells(row, R, psi_max, amplitude, k)
    ]
    assert got == _depth_first_cover(wheel, rail, pieces)
    if amplitude == 1e-4:
        assert any(s == cc.UNCERTIFIED for *_, s in got)
