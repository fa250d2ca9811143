"""A site's archive generated for tests and benchmarks: MCAP logs as the twin's recorder
writes them (``McapLog``), holding wheel passages and the site's measured force of each.

Measurements come from the twin's synthesizer (``service.clients.synthesize``: the wheel
simulated over the site with what the twin does not know, noise, roughness, the true
damping, through the measuring chain). A large archive reuses a pool of ``templates``
distinct measured wheels under new passage ids (each is still diagnosed on its own), so
that making 10 000 passages costs seconds, not an hour.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from schemas.diagnosis import MeasuredPassage
from schemas.messages import WheelPassage, WheelRef
from schemas.scenario import FlatOutline
from schemas.site import SiteConfig
from service.recording.mcap_log import McapLog

T0 = 1_790_000_000.0
"""The first passage's time (UNIX s)."""


@dataclass(frozen=True)
class Template:
    passage: WheelPassage
    measured: MeasuredPassage


def templates(site: SiteConfig, count: int, flat_every: int = 4, seed: int = 0) -> list[Template]:
    """``count`` distinct measured wheels at ``site``: every ``flat_every``-th has a fresh
    flat of 30 to 70 mm (the others are round), each with its own noise seed."""
    from service.clients.synthesize import measure, passage_tread
    from service.physics.diagnosis import Diagnoser

    diagnoser = Diagnoser(site)
    out = []
    for i in range(count):
        flat = flat_every > 0 and i % flat_every == flat_every - 1
        outline = (
            FlatOutline(kind="flat", length=0.03 + 0.01 * ((i // max(flat_every, 1)) % 5))
            if flat
            else None
        )
        p = WheelPassage(
            passage_id=f"tpl-{i}",
            train_id="tpl",
            axle_index=i,
            side="right",
            timestamp=T0,
            speed=30.0 + 2.0 * (i % 7),
            load=55e3 + 1e3 * (i % 5),
            mass=600.0,
            radius=0.46,
            phase=0.5 + 0.37 * i,
        )
        if outline is not None:
            p = p.model_copy(update={"outline": outline})
        m = measure(site, p, passage_tread(p), seed=seed + i, diagnoser=diagnoser)
        mp = MeasuredPassage(
            passage_id=p.passage_id,
            sample_rate=m.sample_rate,
            t_start=m.t_start,
            force=[float(f) for f in m.force],
        )
        out.append(Template(p, mp))
    return out


def write_archive(
    site: SiteConfig,
    directory: Path,
    passages: int,
    pool: list[Template],
    *,
    max_mb: float = 512.0,
    axles: int = 32,
    stem: str | None = None,
) -> list[Path]:
    """Log ``passages`` wheels (trains of ``axles``, 4 a vehicle, two wheels an axle side
    by side) and their measurements on the site's input channels; returns the files (a new
    part past ``max_mb``)."""
    prefix = f"railtwin/{site.site_id}"
    log = McapLog(
        directory,
        stem or f"railtwin-{site.site_id}-archive",
        max_bytes=int(max_mb * 2**20),
        chunk_size=min(2**20, int(max_mb * 2**20) // 4),
        metadata={"railtwin": json.dumps({"generated": "service.distributed.archive_gen"})},
    )
    t_ns = int(T0 * 1e9)
    for i in range(passages):
        tpl = pool[i % len(pool)]
        train, axle = divmod(i, axles)
        vehicle = f"31-80-{train:04d}-{axle // 8:03d}-0"
        wheel = WheelRef(vehicle_id=vehicle, wheelset=1 + axle // 2 % 4, side="right")
        pid = f"t{train}-a{axle}"
        timestamp = T0 + 60.0 * train + 0.05 * axle
        p = tpl.passage.model_copy(
            update={
                "passage_id": pid,
                "train_id": f"t{train}",
                "axle_index": axle,
                "timestamp": timestamp,
                "wheel": wheel,
                "direction": "end2_leading",
            }
        )
        m = tpl.measured.model_copy(update={"passage_id": pid})
        t_ns += 50_000_000
        log.write(f"{prefix}/passage", WheelPassage, p.model_dump_json().encode(), t_ns)
        log.write(f"{prefix}/measured", MeasuredPassage, m.model_dump_json().encode(), t_ns + 1)
    log.close()
    return list(log.files)
