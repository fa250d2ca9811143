"""Rough rails the tests read from files (``tests/data/*.npy``), bit for bit the same on every CPU.

A rail synthesised by :func:`sim_core.roughness.random_roughness` is a sum of cosines compiled
for the host CPU: its last bits differ between CPUs, and where a test's verdict rests on a
near-tie (two contact features within round-off of each other at a node) it then passes on one
machine and fails on another. The tests that check a property of the constraint or of a
passage on a rough rail read these stored samples instead. They were made once by
:func:`regenerate` (``python -m tests.stored_rails``), with the same parameters the tests
synthesised before, and are stored as float64 ``.npy`` arrays (rows x, y).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np

from sim_core.rail import RailProfile

DATA = Path(__file__).resolve().parent / "data"


def _synthesised_rough_rail() -> RailProfile:
    """0.4 m sampled every 0.5 mm, 10 µm rms, power law between 1 m and 1 mm, seed 3,
    centred on x = 0 (the polyline tests' rail)."""
    from sim_core.roughness import power_law_psd, random_roughness

    length, dx, rms = 0.4, 5e-4, 1e-5
    k = np.geomspace(2 * np.pi / 1.0, 0.99 * np.pi / dx, 200)
    r = random_roughness(length, dx, k, power_law_psd(k, 1.0), 3)
    return RailProfile.sampled(r.x - 0.5 * length, r.y * (rms / np.std(r.y)))


def _synthesised_site_rail() -> RailProfile:
    """The benchmarks' site rail (``benchmarks.constraint_bench.site_rail(0.3, seed=5)``):
    0.5 m from x = -0.1 m sampled every 0.5 mm, 10 µm rms."""
    from benchmarks.constraint_bench import site_rail

    return site_rail(0.3, seed=5)


RAILS: dict[str, Callable[[], RailProfile]] = {
    "rough_rail_seed3": _synthesised_rough_rail,
    "site_rail_0p3m_seed5": _synthesised_site_rail,
}


def stored_rail(name: str) -> RailProfile:
    """The stored rail ``name`` (a key of :data:`RAILS`) as a sampled profile."""
    if name not in RAILS:
        raise ValueError(f"stored rail: unknown name {name!r}, known: {sorted(RAILS)}")
    a = np.load(DATA / f"{name}.npy")
    return RailProfile.sampled(a[0], a[1])


def rough_rail() -> RailProfile:
    """The polyline tests' rough rail (0.4 m, 0.5 mm, 10 µm rms), from its file."""
    return stored_rail("rough_rail_seed3")


def site_rail_0p3() -> RailProfile:
    """The integrator tests' site rail (0.5 m, 0.5 mm, 10 µm rms), from its file."""
    return stored_rail("site_rail_0p3m_seed5")


def regenerate() -> None:
    """Write every stored rail from its synthesis (run by hand; the files are committed)."""
    DATA.mkdir(exist_ok=True)
    for name, make in RAILS.items():
        rail = make()
        np.save(DATA / f"{name}.npy", np.stack((rail.x, rail.y)))


if __name__ == "__main__":
    regenerate()
