"""Recordings stay under their retention limit; the run being written is never deleted."""

from __future__ import annotations

import os
from pathlib import Path

from schemas.messages import RejectedInput
from service.mcap_log import McapLog


def test_rotation_deletes_the_oldest_runs_beyond_the_limit(tmp_path: Path) -> None:
    for i in range(5):  # five earlier runs, 10 kB each, oldest first
        old = tmp_path / f"railtwin-km12-old{i}-000.mcap"
        old.write_bytes(b"x" * 10_000)
        os.utime(old, (1_000 + i, 1_000 + i))
    log = McapLog(tmp_path, "railtwin-km12-now", max_bytes=2_000, keep_bytes=30_000)
    for i in range(200):  # rotates several times
        log.write("railtwin/km12/passage/rejected", RejectedInput, b'{"i": %d}' % i, i)
    log.close()
    left = sorted(p.name for p in tmp_path.glob("railtwin-*"))
    total = sum(p.stat().st_size for p in tmp_path.glob("railtwin-*"))
    assert all(p.exists() for p in log.files)  # this run's files all kept
    assert "railtwin-km12-old0-000.mcap" not in left and "railtwin-km12-old1-000.mcap" not in left
    assert "railtwin-km12-old4-000.mcap" in left  # the newest old run stays
    assert total <= 30_000 + sum(p.stat().st_size for p in log.files)
