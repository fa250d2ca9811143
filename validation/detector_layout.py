"""What the detector's layout buys: the fitted length's interval against cribs and speed.

The twin makes its own records (it is the generator here, so this measures what the channels
can tell, not the model's error): site S01 of the detector sites (``validation/track-sites``,
its nominal track taken as the truth), a fresh flat of 30 or 40 mm at 40 or 160 km/h, each at
``PHASES`` phases (the flat may hit over a sleeper), white noise of ``NOISE`` × P, seeded. Each
record is fitted with ``crib_fit.fit_channels`` on a detector of the first 2, 4 or 8 of the
site's cribs, with the site's gauges (0.1 m inside the sleepers) or gauges 0.05 m inside.

    .venv/bin/python -m validation.detector_layout [--out docs/detector_layout.png]

Prints per layout and speed the median length interval's width for each flat and whether the
30 mm flat's interval excludes 40 mm (and the 40 mm's excludes 30 mm) in every phase, and
draws the widths against the number of cribs.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from schemas.messages import WheelPassage
from service.physics.site_physics import SitePhysics
from service.wire.site import load_site
from sim_core.diagnosis.crib_fit import fit_channels, flat_of
from sim_core.diagnosis.crib_forward import CribSite, CribWheel
from sim_core.diagnosis.sensor import SensorModel
from sim_core.track.spec import Crib, TrackSpec

SITE = Path(__file__).parent / "track-sites" / "S01.site.toml"
CRIB_COUNTS = (2, 4, 8)
SPEEDS_KMH = (40.0, 160.0)
LENGTHS = (0.03, 0.04)
PHASES = 4
NOISE = 0.015
INSETS = (0.1, 0.05)
"""m from each sleeper to its crib's gauge: the site's, and a wider crib."""


def layout(cribs: tuple[Crib, ...], n: int, inset: float) -> tuple[Crib, ...]:
    """The first ``n`` cribs, with gauges ``inset`` from their sleepers (the site's are 0.1 m)."""
    out = []
    for c in cribs[:n]:
        s0, s1 = c.x_a - 0.1, c.x_b + 0.1
        out.append(Crib(c.id, s0 + inset, s1 - inset))
    return tuple(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("docs/detector_layout.png"))
    args = ap.parse_args(argv)
    site = load_site(SITE)
    phys = SitePhysics(site)
    cfg = site.diagnosis
    sensor = SensorModel(cfg.sensor_lowpass_hz, cfg.sensor_lowpass_order)
    rate = cfg.sample_rate or 10_000.0
    probe = WheelPassage(
        passage_id="layout",
        train_id="layout",
        axle_index=0,
        side="right",
        timestamp=0.0,
        speed=20.0,
        load=80e3,
        mass=700.0,
        radius=0.46,
    )
    wheel = CribWheel(700.0, 80e3, 0.46, phys.contact_model(probe))
    rng = np.random.default_rng(20261128)
    phases = rng.uniform(0.0, 2.0 * math.pi, PHASES)
    track = phys.foundation
    assert isinstance(track, TrackSpec), "the layout study needs a site on a track"
    truth_site = CribSite(track, phys.cribs, sensor, site.length)  # all 8 cribs
    rows: list[tuple[float, int, float, float, float, float]] = []
    records: dict[tuple[float, float, int], tuple[np.ndarray, np.ndarray]] = {}
    for kmh in SPEEDS_KMH:
        v = kmh / 3.6
        t = np.arange(0.0, site.length / v, 1.0 / rate)
        for length in LENGTHS:
            for k, ph in enumerate(phases):
                flat = flat_of(wheel.radius, "flat", length, float(ph))
                clean = truth_site.run(wheel, v, flat, t).channels
                noisy = clean + rng.normal(0.0, NOISE * wheel.load, clean.shape)
                records[(kmh, length, k)] = (t, noisy)
    for inset in INSETS:
        for n in CRIB_COUNTS:
            if inset != INSETS[0] and n != CRIB_COUNTS[-1]:
                continue
            cribs = layout(phys.cribs, n, inset)
            fit_site = CribSite(track, cribs, sensor, site.length)
            for kmh in SPEEDS_KMH:
                for length in LENGTHS:
                    for k in range(PHASES):
                        t, noisy = records[(kmh, length, k)]
                        if inset != INSETS[0]:
                            # the wider cribs' own record (the gauges moved)
                            flat = flat_of(wheel.radius, "flat", length, float(phases[k]))
                            clean = fit_site.run(wheel, kmh / 3.6, flat, t).channels
                            chans = clean + rng.normal(0.0, NOISE * wheel.load, clean.shape)
                        else:
                            chans = noisy[:n]
                        est = fit_channels(fit_site, wheel, kmh / 3.6, t, chans)
                        # no flat found (every impact blind to these cribs): no interval
                        nan = math.nan
                        lo, hi = (est.length_low, est.length_high) if est.flat else (nan, nan)
                        found = est.flat.length if est.flat else 0.0
                        rows.append((inset, n, kmh, length, lo, hi))
                        print(
                            f"inset {inset:.2f} m, {n} cribs, {kmh:.0f} km/h, {length * 1e3:.0f} mm"
                            f" (phase {k}): {found * 1e3:.1f} [{lo * 1e3:.1f}, {hi * 1e3:.1f}] mm",
                            flush=True,
                        )
    print()
    print(
        "| gauges from sleeper | cribs | km/h | 30 mm: found, median width "
        "| 40 mm: found, median width | 30 vs 40 mm told apart (phases) |"
    )
    print("|---|---|---|---|---|---|")
    for inset in INSETS:
        for n in CRIB_COUNTS:
            for kmh in SPEEDS_KMH:
                sel = [r for r in rows if r[0] == inset and r[1] == n and r[2] == kmh]
                if not sel:
                    continue
                w30 = [r[5] - r[4] for r in sel if r[3] == LENGTHS[0]]
                w40 = [r[5] - r[4] for r in sel if r[3] == LENGTHS[1]]
                apart = sum(
                    1
                    for a, b in zip(
                        [r for r in sel if r[3] == LENGTHS[0]],
                        [r for r in sel if r[3] == LENGTHS[1]],
                        strict=True,
                    )
                    if a[5] < LENGTHS[1] and b[4] > LENGTHS[0]  # NaN: never apart
                )
                print(
                    f"| {inset:.2f} m | {n} | {kmh:.0f} | {_found(w30)} | {_found(w40)} "
                    f"| {apart}/{len(w30)} |"
                )
    _plot(rows, args.out)
    return 0


def _found(widths: list[float]) -> str:
    got = [w for w in widths if not math.isnan(w)]
    med = f"{np.median(got) * 1e3:.1f} mm" if got else "-"
    return f"{len(got)}/{len(widths)}, {med}"


def _plot(rows: list[tuple[float, int, float, float, float, float]], out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.0, 4.0))
    for kmh, style in zip(SPEEDS_KMH, ("-", "--"), strict=True):
        for length, colour in zip(LENGTHS, ("tab:blue", "tab:orange"), strict=True):
            ns, med = [], []
            for n in CRIB_COUNTS:
                w = [
                    r[5] - r[4]
                    for r in rows
                    if r[0] == INSETS[0] and r[1] == n and r[2] == kmh and r[3] == length
                ]
                got = [x for x in w if not math.isnan(x)]
                if got:
                    ns.append(n)
                    med.append(float(np.median(got)) * 1e3)
            label = f"{length * 1e3:.0f} mm fresh flat, {kmh:.0f} km/h"
            ax.plot(ns, med, style, color=colour, marker="o", label=label)
        apart = []
        for n in CRIB_COUNTS:
            sel = [r for r in rows if r[0] == INSETS[0] and r[1] == n and r[2] == kmh]
            a = [r for r in sel if r[3] == LENGTHS[0]]
            b = [r for r in sel if r[3] == LENGTHS[1]]
            told = sum(
                1 for x, y in zip(a, b, strict=True) if x[5] < LENGTHS[1] and y[4] > LENGTHS[0]
            )
            apart.append(told / max(len(a), 1))
        bx.plot(CRIB_COUNTS, apart, style, color="k", marker="s", label=f"{kmh:.0f} km/h")
    ax.set_xlabel("cribs (gauges 0.1 m inside the sleepers)")
    ax.set_ylabel("length interval width, median over phases (mm)")
    ax.set_xticks(list(CRIB_COUNTS))
    ax.legend(fontsize=8)
    ax.set_title("interval width where a flat was found", fontsize=9)
    bx.set_xlabel("cribs (gauges 0.1 m inside the sleepers)")
    bx.set_ylabel("phases in which 30 and 40 mm are told apart")
    bx.set_xticks(list(CRIB_COUNTS))
    bx.set_ylim(-0.05, 1.05)
    bx.legend(fontsize=8)
    bx.set_title("30 mm vs 40 mm: intervals that exclude each other", fontsize=9)
    fig.suptitle(
        "What the detector's layout buys (site S01, twin-made records, 1.5 % noise)", fontsize=10
    )
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())
