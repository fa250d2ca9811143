"""Reading and repairing MCAP logs cut short (a kill -9, an OOM kill, a full disk).

A log whose writer died before ``finish()`` has no summary or footer: ``make_reader``
refuses it. Its records are still there, in order, up to the last complete chunk (the
twin flushes the chunk in progress at least once a second), so ``salvage`` streams them
with ``mcap.stream_reader.StreamReader`` and stops at the first damaged record, and
``recover`` writes what was salvaged into a new, complete file.

    >>> import io, tempfile
    >>> from pathlib import Path
    >>> from schemas.messages import RejectedInput
    >>> from service.mcap_log import McapLog
    >>> d = Path(tempfile.mkdtemp())
    >>> log = McapLog(d, "cut", chunk_size=64)
    >>> for i in range(20):
    ...     log.write("railtwin/x/passage/rejected", RejectedInput, b'{"i": %d}' % i, i)
    ...     log.flush()
    >>> raw = log.files[0]
    >>> _ = raw.write_bytes(raw.read_bytes())  # as if killed: no finish(), no footer
    >>> report = recover([raw], d / "fixed.mcap")
    >>> report.messages, [d.split(" (")[-1] for d in report.damaged]
    (20, ['EndOfFile)'])
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from service.mcap_log import LoggedMessage

__all__ = ["RecoveryReport", "read_any", "recover", "salvage"]


@dataclass
class RecoveryReport:
    """What ``recover`` found: messages kept, and per damaged file where it stopped."""

    messages: int = 0
    files: int = 0
    damaged: list[str] = field(default_factory=list)


def salvage(path: Path, report: RecoveryReport | None = None) -> Iterator[LoggedMessage]:
    """Every complete message of ``path`` in file order, whether or not it was finished."""
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    with path.open("rb") as f:
        try:
            for record in StreamReader(f, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    ch = channels.get(record.channel_id)
                    if ch is None:
                        continue
                    sc = schemas.get(ch.schema_id)
                    yield LoggedMessage(topic=ch.topic, schema_name=sc.name if sc else "",
                                        log_time_ns=record.log_time, data=record.data)
        except (McapError, struct.error, EOFError, ValueError) as exc:
            if report is not None:
                report.damaged.append(f"{path}: cut at byte {f.tell()} ({type(exc).__name__})")


def read_any(paths: list[Path]) -> Iterator[LoggedMessage]:
    """The messages of several logs (finished or cut), in log-time order."""
    msgs: list[LoggedMessage] = []
    for p in sorted(paths):
        msgs.extend(salvage(p))
    msgs.sort(key=lambda m: m.log_time_ns)
    yield from msgs


def recover(paths: list[Path], out: Path) -> RecoveryReport:
    """Write every salvageable message of ``paths`` (in log-time order) to a complete ``out``."""
    report = RecoveryReport()
    msgs: list[LoggedMessage] = []
    schema_data: dict[str, tuple[str, bytes]] = {}
    for p in sorted(paths):
        report.files += 1
        with p.open("rb") as f:
            try:
                for record in StreamReader(f).records:
                    if isinstance(record, Schema):
                        schema_data[record.name] = (record.encoding, record.data)
            except (McapError, struct.error, EOFError, ValueError):
                pass
        msgs.extend(salvage(p, report))
    msgs.sort(key=lambda m: m.log_time_ns)
    tmp = out.with_suffix(out.suffix + ".partial")
    with tmp.open("wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library="railtwin recover")
        schema_ids: dict[str, int] = {}
        channel_ids: dict[str, int] = {}
        for seq, m in enumerate(msgs):
            cid = channel_ids.get(m.topic)
            if cid is None:
                sid = schema_ids.get(m.schema_name)
                if sid is None:
                    enc, data = schema_data.get(m.schema_name, ("jsonschema", b"{}"))
                    sid = w.register_schema(name=m.schema_name, encoding=enc, data=data)
                    schema_ids[m.schema_name] = sid
                cid = w.register_channel(topic=m.topic, message_encoding="json", schema_id=sid)
                channel_ids[m.topic] = cid
            w.add_message(channel_id=cid, log_time=m.log_time_ns, publish_time=m.log_time_ns,
                          data=m.data, sequence=seq)
            report.messages += 1
        w.finish()
    tmp.replace(out)
    return report
