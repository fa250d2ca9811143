"""Recordings stay under their retention limit; the run being written is never deleted."""

from __future__ import annotations

import os
from pathlib import Path

from schemas.messages import RejectedInput
from service.recording.mcap_log import McapLog


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


def test_a_single_long_run_gives_up_its_own_oldest_parts(tmp_path: Path) -> None:
    """Months in one run: its closed MCAP parts go, oldest first; the one being written stays."""
    (tmp_path / "railtwin-km12-now.rrd").write_bytes(b"r" * 1_000)  # its Rerun part, open
    log = McapLog(tmp_path, "railtwin-km12-now", max_bytes=2_000, keep_bytes=8_000, chunk_size=500)
    for i in range(2_000):  # many rotations
        log.write("railtwin/km12/passage/rejected", RejectedInput, b'{"i": %d}' % i, i)
    current = log.path
    log.close()
    left = sorted(tmp_path.glob("railtwin-*"))
    assert len(log.files) > 10 and not log.files[0].exists()  # the oldest part went
    assert current is not None and current.exists()
    assert (tmp_path / "railtwin-km12-now.rrd").exists()  # newest of its series: kept
    # at each rotation the limit held, counting the part that was then about to be written
    assert sum(p.stat().st_size for p in left) <= 8_000 + 2 * log.files[-1].stat().st_size


def test_another_runs_recent_files_are_kept(tmp_path: Path) -> None:
    """Another twin may be writing in the same directory: its files changed lately stay."""
    from service.recording.retention import enforce_retention

    live = tmp_path / "railtwin-km13-live-000.mcap"
    live.write_bytes(b"x" * 10_000)
    os.utime(live, (1_000_000, 1_000_000))
    dead = tmp_path / "railtwin-km13-dead-000.mcap"
    dead.write_bytes(b"x" * 10_000)
    os.utime(dead, (1_000, 1_000))
    deleted = enforce_retention(tmp_path, 0, protect="railtwin-km12-now", now=1_000_100.0)
    assert deleted == [dead] and live.exists()


def test_journal_goes_on_in_parts_and_recover_reads_them_all(tmp_path: Path) -> None:
    from service.recording.input_journal import InputJournal, read_journal

    journal = InputJournal(tmp_path / "railtwin-km12-now-inputs.journal", part_bytes=500)
    for i in range(40):
        journal.append("railtwin/km12/passage", i, b'{"i": %d}' % i)
    journal.close()
    parts = journal.paths
    assert len(parts) > 3 and all(p.stat().st_size <= 500 for p in parts)
    assert parts[1].name == "railtwin-km12-now-inputs-001.journal"
    got = [e.received_ns for p in parts for e in read_journal(p)]
    assert got == list(range(40))  # no record split or lost between parts
