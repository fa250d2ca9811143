"""A site's archive read back: every passage and measured passage of its MCAP logs,
paired as the twin pairs them, and the diagnoses the twin logged.

Logs are given as files or directories (every ``*.mcap`` below, rotated parts and
``railtwin recover``'s output alike). A file that is not MCAP, or a log cut short (a
killed twin's: recover it first), is refused with one line naming it (``ArchiveError``).
Inputs are read from the site's input channels only and checked as the twin checks them
(``service.clients.replay.plan_replay``); the invalid ones are counted and left out.

Pairing (``service.twin.pairing``), in log-time order: a measurement is paired with the
passage of the same id that came before it (among the last ``KEPT_PASSAGES`` passages),
or with one that comes within the site's ``pairing_timeout`` after it; a second
measurement of a passage, or a second passage of an id, is a duplicate and left out.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from service.clients.replay import ReplayError, plan_replay
from service.recording.mcap_log import LoggedMessage
from service.recording.mcap_recover import RecoveryReport, salvage

KEPT_PASSAGES = 10_000
"""Passages a measurement may follow (the twin's ``service.twin.kept_passages``)."""

MCAP_MAGIC = b"\x89MCAP0\r\n"


class ArchiveError(ValueError):
    """The logs cannot be read as a site's archive (one line: which file and why)."""


@dataclass(frozen=True)
class Pair:
    """A passage and its measurement, as logged (the JSON the twin received)."""

    passage_id: str
    passage: bytes
    measured: bytes
    log_time_ns: int


@dataclass
class Archive:
    site_id: str
    files: list[Path]
    pairs: list[Pair] = field(default_factory=list)
    passages: int = 0
    measurements: int = 0
    unpaired_passages: int = 0
    unpaired_measurements: int = 0
    duplicates: int = 0
    invalid: int = 0
    logged: dict[str, tuple[str, str]] = field(default_factory=dict)
    """passage id → (verdict, model version key or ``unversioned``) the twin logged."""


def log_files(paths: Sequence[Path]) -> list[Path]:
    """The MCAP files of ``paths`` (a directory: every ``*.mcap`` below it), sorted."""
    files: list[Path] = []
    for p in paths:
        if p.is_dir():
            found = sorted(q for q in p.rglob("*.mcap") if q.is_file())
            if not found:
                raise ArchiveError(f"{p}: no .mcap log in this directory")
            files.extend(found)
        elif p.is_file():
            files.append(p)
        else:
            raise ArchiveError(f"{p}: no such file or directory")
    return sorted(set(files))


def read_messages(files: Sequence[Path]) -> list[LoggedMessage]:
    """Every message of ``files`` in log-time order; ``ArchiveError`` for a file that is not
    MCAP or is cut short."""
    msgs: list[LoggedMessage] = []
    for path in files:
        try:
            with path.open("rb") as f:
                head = f.read(len(MCAP_MAGIC))
        except OSError as exc:
            raise ArchiveError(f"{path}: cannot read: {exc.strerror or exc}") from None
        if head != MCAP_MAGIC:
            raise ArchiveError(f"{path}: not an MCAP log (no MCAP magic at its start)")
        report = RecoveryReport()
        msgs.extend(salvage(path, report))
        if report.damaged:
            where = report.damaged[0].split(": ", 1)[-1]
            raise ArchiveError(
                f"{path}: the log is cut short ({where}: its writer was killed?): "
                f"repair it first with 'railtwin recover {path} --out FIXED.mcap'"
            )
    msgs.sort(key=lambda m: m.log_time_ns)
    return msgs


def _version_key(doc: dict[str, object]) -> str:
    v = doc.get("model_version")
    if not isinstance(v, dict):
        return "unversioned"
    return "/".join(str(v.get(k)) for k in ("package", "track", "site"))


def read_archive(paths: Sequence[Path], site_id: str, pairing_timeout: float) -> Archive:
    """The archive of ``site_id`` in the logs ``paths`` (see module doc)."""
    files = log_files(paths)
    msgs = read_messages(files)
    try:
        plan = plan_replay(msgs, site_id=site_id)
    except ReplayError as exc:
        raise ArchiveError(f"the logs: {exc}") from None
    names = ", ".join(str(f) for f in files[:3]) + (" ..." if len(files) > 3 else "")
    if not plan.logged_sites:
        raise ArchiveError(f"{names}: no site's inputs in the log(s): nothing to re-analyse")
    if site_id not in plan.logged_sites:
        raise ArchiveError(
            f"{names}: the logs hold the inputs of site(s) {', '.join(plan.logged_sites)}, "
            f"not of the site file's {site_id!r}"
        )
    archive = Archive(site_id=site_id, files=files)
    archive.invalid = plan.rejected_skipped + plan.truncated + plan.damaged
    timeout_ns = int(pairing_timeout * 1e9)
    kept: OrderedDict[str, tuple[bytes, int]] = OrderedDict()  # the twin's kept passages
    seen: set[str] = set()  # every passage id (a second passage of an id is refused)
    waiting: OrderedDict[str, tuple[bytes, int]] = OrderedDict()
    paired: set[str] = set()
    for item in plan.inputs:
        pid = json.loads(item.payload)["passage_id"]
        t = item.log_time_ns
        while waiting:  # measurements whose passage did not come in time
            old, (_, t0) = next(iter(waiting.items()))
            if t - t0 <= timeout_ns:
                break
            del waiting[old]
            archive.unpaired_measurements += 1
        if item.kind == "passage":
            archive.passages += 1
            if pid in seen:
                archive.duplicates += 1
                continue
            seen.add(pid)
            kept[pid] = (item.payload, t)
            while len(kept) > KEPT_PASSAGES:
                kept.popitem(last=False)
            m = waiting.pop(pid, None)
            if m is not None:
                archive.pairs.append(Pair(pid, item.payload, m[0], t))
                paired.add(pid)
            continue
        archive.measurements += 1
        if pid in paired or pid in waiting:
            archive.duplicates += 1
            continue
        p = kept.get(pid)
        if p is not None:
            archive.pairs.append(Pair(pid, p[0], item.payload, t))
            paired.add(pid)
        else:
            waiting[pid] = (item.payload, t)
    archive.unpaired_measurements += len(waiting)
    archive.unpaired_passages = len(seen - paired)
    topic = f"railtwin/{site_id}/diagnosis"
    for msg in msgs:
        if msg.topic != topic:
            continue
        try:
            doc = json.loads(msg.data)
            archive.logged[str(doc["passage_id"])] = (str(doc["verdict"]), _version_key(doc))
        except (ValueError, KeyError, TypeError):
            continue
    return archive
