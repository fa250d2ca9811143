"""Reading and repairing MCAP logs cut short (a kill -9, an OOM kill, a full disk).

A log whose writer died before ``finish()`` has no summary or footer: ``make_reader``
refuses it. Its records are still there, in order, up to the last complete chunk (the
twin flushes the chunk in progress at least once a second), so ``salvage`` streams them
with ``mcap.stream_reader.StreamReader`` and stops at the first damaged record, and
``recover`` writes what was salvaged into a new, complete file.

    >>> import io, tempfile
    >>> from pathlib import Path
    >>> from schemas.messages import RejectedInput
    >>> from service.recording.mcap_log import McapLog
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

import base64
import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer
from pydantic import BaseModel

from schemas.diagnosis import MeasuredPassage
from schemas.messages import (
    MESSAGE_MODELS,
    MESSAGE_SCHEMA_VERSION,
    RejectedInput,
    WheelPassage,
    encoding_schema,
    is_encoding_of,
)
from service.recording.input_journal import MAGIC as JOURNAL_MAGIC
from service.recording.input_journal import read_journal
from service.recording.mcap_log import LoggedMessage

__all__ = ["RecoveryReport", "log_problem", "read_any", "recover", "salvage"]


@dataclass
class RecoveryReport:
    """What ``recover`` found: messages kept, and per damaged file where it stopped."""

    messages: int = 0
    files: int = 0
    from_journal: int = 0
    damaged: list[str] = field(default_factory=list)


def log_problem(path: Path, *, journals: bool = True) -> str | None:
    """Why ``path`` is no log to read (not MCAP; not an input journal, when ``journals`` and
    it is named ``*.journal``), or None. A log cut anywhere, even in its first bytes, is one:
    ``salvage`` reads what it holds."""
    journal = journals and path.suffix == ".journal"
    magic = JOURNAL_MAGIC if journal else MCAP0_MAGIC
    with path.open("rb") as f:
        head = f.read(len(magic))
    if head == magic[: len(head)]:
        return None
    what = "a railtwin input journal" if journal else "an MCAP log"
    return f"not {what} (it starts with {head!r}, not {magic!r})"


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
                    yield LoggedMessage(
                        topic=ch.topic,
                        schema_name=sc.name if sc else "",
                        log_time_ns=record.log_time,
                        data=record.data,
                    )
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


def _raw_input(m: LoggedMessage) -> bytes:
    """The payload as received for a logged input (valid or rejected), else the data."""
    if is_encoding_of(m.schema_name, RejectedInput):
        try:
            return base64.b64decode(RejectedInput.model_validate_json(m.data).payload_base64)
        except ValueError:  # not what its schema says: compared as it is
            return m.data
    return m.data


OUTPUT_MODELS = {"result": "PassageResult", "diagnosis": "Diagnosis", "error": "ServiceError"}
"""The outputs the twin journals, by the last chunk of their topic."""


def journal_messages(path: Path) -> Iterator[LoggedMessage]:
    """A journal's records as the twin logs them: valid inputs on their key, the others as
    ``RejectedInput`` on ``<key>/rejected``; outputs on their topic."""
    for e in read_journal(path):
        out = OUTPUT_MODELS.get(e.key.rsplit("/", 1)[-1])
        if out is not None:
            yield LoggedMessage(
                e.key, f"railtwin.{out}/{MESSAGE_SCHEMA_VERSION}", e.received_ns, e.payload
            )
            continue
        model: type[BaseModel] = MeasuredPassage if e.key.endswith("/measured") else WheelPassage
        try:
            model.model_validate_json(e.payload)
        except ValueError:
            rejected = RejectedInput(
                key=e.key,
                payload_base64=base64.b64encode(e.payload).decode("ascii"),
                payload_text=e.payload.decode("utf-8", errors="replace"),
            )
            yield LoggedMessage(
                f"{e.key}/rejected",
                encoding_schema(RejectedInput),
                e.received_ns,
                rejected.model_dump_json().encode(),
            )
            continue
        yield LoggedMessage(e.key, encoding_schema(model), e.received_ns, e.payload)


def recover(paths: list[Path], out: Path) -> RecoveryReport:
    """Write every salvageable message of ``paths`` (in log-time order) to a complete ``out``.

    ``.journal`` files (``service.recording.input_journal``) add the inputs, results, diagnoses and
    errors the MCAP files lack.
    """
    report = RecoveryReport()
    msgs: list[LoggedMessage] = []
    schema_data: dict[str, tuple[str, bytes]] = {}
    journals = [p for p in paths if p.suffix == ".journal"]
    paths = [p for p in paths if p.suffix != ".journal"]
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
    have = {(m.log_time_ns, _raw_input(m)) for m in msgs} if journals else set()
    for j in sorted(journals):
        report.files += 1
        for m in journal_messages(j):
            raw = _raw_input(m)
            if (m.log_time_ns, raw) not in have:
                msgs.append(m)
                report.from_journal += 1
    for m in msgs:
        if m.schema_name not in schema_data:
            model = MESSAGE_MODELS.get(m.schema_name.removeprefix("railtwin.").split("/")[0])
            if model is not None:
                schema_data[m.schema_name] = (
                    "jsonschema",
                    json.dumps(model.model_json_schema()).encode(),
                )
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
            w.add_message(
                channel_id=cid,
                log_time=m.log_time_ns,
                publish_time=m.log_time_ns,
                data=m.data,
                sequence=seq,
            )
            report.messages += 1
        w.finish()
    tmp.replace(out)
    return report
