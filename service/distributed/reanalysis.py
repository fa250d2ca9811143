"""Re-analysis of a site's archive: every paired passage re-diagnosed with the current model,
stored once per (site, passage, model version), and what changed.

Idempotent and resumable: the passages already stored with this model version are skipped;
each batch's results are stored in one transaction (fleet store) or one file written
atomically (directory) as it comes back, so a run killed at any point (even with -9) and
started again stores nothing twice (the key) and loses nothing (a batch is stored whole or
not at all, and what is not stored is diagnosed again). The report is made from what is
stored, so it is the same however many runs it took.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any, Protocol

from schemas.diagnosis import ModelVersion
from schemas.site import SiteConfig
from service.distributed.archive import Archive, Pair
from service.distributed.cluster import IN_FLIGHT_PER_WORKER, ClusterInfo, run_batches
from service.distributed.progress import Progress
from service.distributed.tasks import Outcome, diagnose_batch
from service.fleet.entry import Entry, EntryError, entry_from_payload
from service.fleet.store import Reanalysed, Store

if TYPE_CHECKING:
    from distributed import Client

VERDICTS = ("ok", "watch", "inspect", "remove")
RANK = {v: i for i, v in enumerate(VERDICTS)}

MAX_BATCH = 32
"""Passages per task at most (a round wheel's diagnosis ~20 ms, a flat's ~0.7 s)."""


def batch_size(todo: int, workers: int) -> int:
    """Passages per task: about 8 tasks per worker (balance, and a lost worker costs
    little), at most ``MAX_BATCH``."""
    return max(1, min(MAX_BATCH, math.ceil(todo / (8 * max(1, workers)))))


# --- where results go ------------------------------------------------------------------


class Sink(Protocol):
    def done(self) -> set[str]:
        """Passage ids already stored with this model version."""
        ...

    def write(self, rows: Sequence[Reanalysed]) -> None: ...

    def rows(self) -> list[Reanalysed]:
        """Everything stored with this model version."""
        ...

    def before(self) -> dict[str, tuple[str, str]]:
        """passage id → (verdict, model version) stored with another model version."""
        ...

    def close(self) -> None: ...


class StoreSink:
    """The fleet store (SQLite or PostgreSQL): the ``reanalysis`` table, and each new
    diagnosis into the fleet's history where the passage has none yet."""

    def __init__(self, store: Store, site_id: str, version: str) -> None:
        self.store = store
        self.site_id = site_id
        self.version = version

    def done(self) -> set[str]:
        return {r.passage_id for r in self.store.reanalysed(self.site_id, self.version)}

    def write(self, rows: Sequence[Reanalysed]) -> None:
        entries: list[Entry] = []
        now = time.time()
        for r in rows:
            if r.body is not None:
                # no timestamp (a 1.0 passage): kept in the reanalysis table only
                with contextlib.suppress(EntryError):
                    entries.append(entry_from_payload(r.body, now))
        self.store.add_reanalysed(rows, entries)

    def rows(self) -> list[Reanalysed]:
        return self.store.reanalysed(self.site_id, self.version)

    def before(self) -> dict[str, tuple[str, str]]:
        return self.store.verdicts_before(self.site_id, self.version)

    def close(self) -> None:
        self.store.close()


class DirSink:
    """``DIR/<site>/<package>_<track>_<site fingerprint>/part-*.jsonl``: one JSON line per
    passage (``passage_id``, ``verdict``, ``error``, ``diagnosis``), one file per batch,
    written to a temporary name and renamed (a killed run leaves whole files only)."""

    def __init__(self, root: Path, site_id: str, version: str) -> None:
        self.root = root / site_id
        self.site_id = site_id
        self.version = version
        self.dir = self.root / version.replace("/", "_")
        self.dir.mkdir(parents=True, exist_ok=True)

    def _read(self, directory: Path) -> Iterator[Reanalysed]:
        for part in sorted(directory.glob("part-*.jsonl")):
            for line in part.read_text(encoding="utf-8").splitlines():
                doc = json.loads(line)
                diag = doc.get("diagnosis")
                yield Reanalysed(
                    self.site_id,
                    doc["passage_id"],
                    self.version if directory == self.dir else directory.name,
                    (diag or {}).get("wheel") and _wheel_id(diag["wheel"]),
                    (diag or {}).get("timestamp"),
                    doc.get("verdict"),
                    doc.get("error"),
                    json.dumps(diag) if diag is not None else None,
                )

    def done(self) -> set[str]:
        return {r.passage_id for r in self._read(self.dir)}

    def write(self, rows: Sequence[Reanalysed]) -> None:
        if not rows:
            return
        lines = [
            json.dumps(
                {
                    "passage_id": r.passage_id,
                    "verdict": r.verdict,
                    "error": r.error,
                    "diagnosis": json.loads(r.body) if r.body is not None else None,
                }
            )
            for r in rows
        ]
        digest = hashlib.sha256("\n".join(r.passage_id for r in rows).encode()).hexdigest()[:12]
        path = self.dir / f"part-{digest}.jsonl"
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        with tmp.open("w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)

    def rows(self) -> list[Reanalysed]:
        return sorted(self._read(self.dir), key=lambda r: r.passage_id)

    def before(self) -> dict[str, tuple[str, str]]:
        out: dict[str, tuple[str, str]] = {}
        others = [d for d in self.root.iterdir() if d.is_dir() and d != self.dir]
        for d in sorted(others, key=lambda d: d.stat().st_mtime):
            for r in self._read(d):
                if r.verdict is not None:
                    out[r.passage_id] = (r.verdict, d.name.replace("_", "/"))
        return out

    def close(self) -> None:
        pass


def _wheel_id(wheel: dict[str, Any]) -> str:
    return f"{wheel['vehicle_id']}/{wheel['wheelset']}/{wheel['side']}"


def row_of(site_id: str, version: str, o: Outcome) -> Reanalysed:
    """The stored row of one outcome."""
    if o.data is None:
        return Reanalysed(site_id, o.key, version, None, None, None, o.error, None)
    doc = json.loads(o.data)
    wheel = doc.get("wheel")
    return Reanalysed(
        site_id,
        o.key,
        version,
        _wheel_id(wheel) if wheel else None,
        doc.get("timestamp"),
        doc["verdict"],
        None,
        o.data,
    )


# --- the run and its report --------------------------------------------------------------


@dataclass
class Report:
    site_id: str
    model_version: str
    files: int
    pairs: int
    unpaired_passages: int
    unpaired_measurements: int
    duplicates: int
    invalid: int
    already_stored: int = 0
    diagnosed: int = 0
    failed: int = 0
    tasks: int = 0
    batch: int = 0
    workers: int = 0
    wall_time: float = 0.0
    compute_time: float = 0.0
    """Seconds the workers spent diagnosing (sum over passages)."""
    by_verdict: dict[str, dict[str, int]] = field(default_factory=dict)
    """new verdict → {"passages", "changed", "new", "from_<verdict>" ...}"""
    errors: int = 0
    rose_to_remove: list[dict[str, Any]] = field(default_factory=list)

    @property
    def overhead_per_task(self) -> float:
        """Wall time not spent diagnosing, per task and worker (s): scheduling, transfer,
        storing, idle tails."""
        if self.tasks == 0 or self.workers == 0:
            return 0.0
        return max(0.0, self.wall_time * self.workers - self.compute_time) / self.tasks

    def json(self) -> dict[str, Any]:
        doc = dict(self.__dict__)
        doc["overhead_per_task"] = self.overhead_per_task
        return doc

    def table(self) -> str:
        lines = [
            f"re-analysis of site {self.site_id} with model {self.model_version}",
            f"  {self.files} log file(s): {self.pairs} measured passages paired "
            f"({self.unpaired_passages} passages without a measurement, "
            f"{self.unpaired_measurements} measurements without a passage, "
            f"{self.duplicates} duplicates, {self.invalid} invalid inputs left out)",
            f"  this run: {self.diagnosed} diagnosed ({self.failed} could not be), "
            f"{self.already_stored} already stored with this model",
        ]
        if self.tasks:
            lines.append(
                f"  {self.tasks} tasks of <= {self.batch} passages on {self.workers} "
                f"worker(s): {self.wall_time:.1f} s wall, {self.compute_time:.1f} s diagnosing, "
                f"{self.overhead_per_task * 1e3:.1f} ms overhead per task"
            )
        head = ["verdict now", "passages", "changed", "new", *[f"was {v}" for v in VERDICTS]]
        rows = []
        for v in VERDICTS:
            c = self.by_verdict.get(v, {})
            rows.append(
                [
                    v,
                    str(c.get("passages", 0)),
                    str(c.get("changed", 0)),
                    str(c.get("new", 0)),
                    *[str(c.get(f"from_{w}", 0)) for w in VERDICTS],
                ]
            )
        rows.append(["(error)", str(self.errors), "", "", "", "", "", ""])
        widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
        lines.append("")
        for r in [head, *rows]:
            lines.append("  " + "  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))
        lines.append("")
        if self.rose_to_remove:
            lines.append(f"  {len(self.rose_to_remove)} wheel(s) rose to remove:")
            for w in self.rose_to_remove:
                lines.append(
                    f"    {w['wheel_id'] or '(no wheel id)'}  passage {w['passage_id']}  "
                    f"was {w['was']} ({w['was_model']})"
                )
        else:
            lines.append("  no wheel rose to remove")
        return "\n".join(lines)


def pending_pairs(archive: Archive, done: set[str]) -> list[Pair]:
    """The archive's pairs not stored yet, in log order."""
    return [p for p in archive.pairs if p.passage_id not in done]


def reanalyse(
    client: Client,
    info: ClusterInfo,
    archive: Archive,
    site: SiteConfig,
    version: ModelVersion,
    sink: Sink,
    *,
    batch: int | None = None,
    stream: IO[str] | None = None,
    every: float = 10.0,
) -> Report:
    """Diagnose every pair of ``archive`` not yet in ``sink`` on the cluster, store each
    batch as it comes back, and report against what was stored before."""
    key = version.key
    report = Report(
        site.site_id,
        key,
        len(archive.files),
        len(archive.pairs),
        archive.unpaired_passages,
        archive.unpaired_measurements,
        archive.duplicates,
        archive.invalid,
        workers=info.workers,
    )
    done = sink.done()
    todo = pending_pairs(archive, done)
    report.already_stored = len(archive.pairs) - len(todo)
    size = batch or batch_size(len(todo), info.workers)
    report.batch = size
    batches = [
        [(p.passage_id, p.passage, p.measured) for p in todo[i : i + size]]
        for i in range(0, len(todo), size)
    ]
    site_json = site.model_dump_json()
    progress = Progress(
        len(archive.pairs),
        "passages",
        stream,
        prefix="railtwin reanalyse",
        every=every,
        done=report.already_stored,
    )
    start = time.perf_counter()
    try:
        for _, outcomes in run_batches(
            client,
            diagnose_batch,
            batches,
            site_json,
            in_flight=IN_FLIGHT_PER_WORKER * max(1, info.workers),
        ):
            rows = [row_of(site.site_id, key, o) for o in outcomes]
            sink.write(rows)
            report.tasks += 1
            report.compute_time += sum(o.seconds for o in outcomes)
            report.diagnosed += sum(1 for o in outcomes if o.error is None)
            report.failed += sum(1 for o in outcomes if o.error is not None)
            progress.advance(len(outcomes))
    finally:
        progress.close()
        report.wall_time = time.perf_counter() - start
    compare(report, archive, sink)
    return report


def compare(report: Report, archive: Archive, sink: Sink) -> None:
    """Fill the report's verdict table from what is stored with this model version, each
    passage against its verdict before: stored with another model, else the twin's
    logged one (when that was another model)."""
    before = sink.before()
    for pid, (verdict, version) in archive.logged.items():
        if version != report.model_version:
            before.setdefault(pid, (verdict, version))
    wanted = {p.passage_id for p in archive.pairs}
    counts: dict[str, Counter[str]] = {v: Counter() for v in VERDICTS}
    for r in sink.rows():
        if r.passage_id not in wanted:
            continue
        if r.verdict is None:
            report.errors += 1
            continue
        c = counts[r.verdict]
        c["passages"] += 1
        was = before.get(r.passage_id)
        if was is None:
            c["new"] += 1
            continue
        c[f"from_{was[0]}"] += 1
        if was[0] != r.verdict:
            c["changed"] += 1
            if r.verdict == "remove":
                report.rose_to_remove.append(
                    {
                        "wheel_id": r.wheel_id,
                        "passage_id": r.passage_id,
                        "was": was[0],
                        "was_model": was[1],
                    }
                )
    report.by_verdict = {v: dict(c) for v, c in counts.items()}
