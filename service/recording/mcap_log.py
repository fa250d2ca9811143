"""The service's MCAP log: every received and published message, on a channel per kind.

Channels are named by key family (``railtwin/<site>/force``, ``.../result``,
...) with ``message_encoding="json"`` and the model's JSON Schema
(``jsonschema``), so Foxglove and ``rerun mcap info`` decode them. The
payload is the exact bytes that went over Zenoh; the full key is in the
message (``passage_id``). Inputs that are not a valid ``WheelPassage`` are
kept verbatim (base64) as ``RejectedInput`` on ``.../passage/rejected``.

Chunks are ZSTD-compressed; ``flush()`` closes the chunk in progress so a
crash loses at most what arrived since (the twin flushes at least once a
second). A file is closed and a new one started when it exceeds
``max_bytes`` or is older than ``max_seconds``.

    >>> import tempfile
    >>> from schemas.messages import RejectedInput
    >>> d = Path(tempfile.mkdtemp())
    >>> log = McapLog(d, "test")
    >>> log.write("railtwin/x/passage/rejected", RejectedInput, b'{}', 1)
    >>> log.close()
    >>> [p.suffix for p in log.files]
    ['.mcap']
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from pydantic import BaseModel

from schemas.messages import MESSAGE_MODELS, encoding_schema
from service.recording import foxglove
from service.recording.retention import enforce_retention

DEFAULT_MAX_BYTES = 512 * 1024 * 1024
DEFAULT_MAX_SECONDS = 3600.0
CHUNK_SIZE = 1024 * 1024


class McapLog:
    """A rotating MCAP writer; not thread-safe (the twin writes from one thread)."""

    def __init__(
        self,
        directory: Path,
        stem: str,
        *,
        max_bytes: int = DEFAULT_MAX_BYTES,
        max_seconds: float = DEFAULT_MAX_SECONDS,
        chunk_size: int = CHUNK_SIZE,
        metadata: dict[str, str] | None = None,
        keep_bytes: int | None = None,
    ) -> None:
        self.directory = directory
        self.metadata = dict(metadata or {})
        self.keep_bytes = keep_bytes
        self.stem = stem
        self.max_bytes = max_bytes
        self.max_seconds = max_seconds
        self.chunk_size = chunk_size
        self.files: list[Path] = []
        self._file: IO[bytes] | None = None
        self._writer: Writer | None = None
        self._opened_at = 0.0
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._sequence = 0
        directory.mkdir(parents=True, exist_ok=True)

    @property
    def path(self) -> Path | None:
        """The file being written now."""
        return self.files[-1] if self._writer is not None else None

    def _open(self) -> Writer:
        if self.keep_bytes is not None:  # on every rotation: the oldest runs' files go
            enforce_retention(self.directory, self.keep_bytes, protect=self.stem)
        path = self.directory / f"{self.stem}-{len(self.files):03d}.mcap"
        self._file = path.open("wb")
        writer = Writer(self._file, chunk_size=self.chunk_size, compression=CompressionType.ZSTD)
        writer.start(profile="", library="railtwin")
        if self.metadata:  # each file says which site file and version wrote it
            writer.add_metadata(name="railtwin", data=self.metadata)
        self._writer = writer
        self._opened_at = time.monotonic()
        self._schemas = {}
        self._channels = {}
        self.files.append(path)
        return writer

    def _channel(
        self, writer: Writer, topic: str, model: type[BaseModel], schema_name: str | None = None
    ) -> int:
        channel = self._channels.get(topic)
        if channel is None:
            name = schema_name or encoding_schema(model)
            schema = self._schemas.get(name)
            if schema is None:
                data = json.dumps(model.model_json_schema()).encode()
                schema = writer.register_schema(name=name, encoding="jsonschema", data=data)
                self._schemas[name] = schema
            channel = writer.register_channel(
                topic=topic,
                message_encoding="json",
                schema_id=schema,
                metadata={"model": model.__name__},
            )
            self._channels[topic] = channel
        return channel

    def write(
        self,
        topic: str,
        model: type[BaseModel],
        data: bytes,
        log_time_ns: int,
        publish_time_ns: int | None = None,
        schema_name: str | None = None,
    ) -> None:
        """Log one message (``data`` is its JSON) on ``topic``; rotates first if due.
        ``schema_name``: the channel's schema name when not railtwin's (``foxglove.Log``)."""
        writer = self._writer
        if writer is not None and self._rotation_due():
            self._finish()
            writer = None
        if writer is None:
            writer = self._open()
        channel = self._channel(writer, topic, model, schema_name)
        writer.add_message(
            channel_id=channel,
            log_time=log_time_ns,
            publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
            data=data,
            sequence=self._sequence,
        )
        self._sequence += 1

    def _rotation_due(self) -> bool:
        assert self._file is not None
        return (
            self._file.tell() >= self.max_bytes
            or time.monotonic() - self._opened_at >= self.max_seconds
        )

    def flush(self) -> None:
        """Write the chunk in progress to disk (everything so far survives a crash)."""
        if self._writer is not None:
            self._writer.flush()

    def _finish(self) -> None:
        if self._writer is not None:
            self._writer.finish()
            self._writer = None
        if self._file is not None:
            self._file.close()
            self._file = None

    def close(self) -> None:
        """Finish the file (summary, index); the log can be read with ``make_reader``."""
        self._finish()


# --- reading back --------------------------------------------------------------------------


@dataclass(frozen=True)
class LoggedMessage:
    """One message of a log, with its channel's topic and schema name."""

    topic: str
    schema_name: str
    log_time_ns: int
    data: bytes


def read_log(paths: list[Path]) -> Iterator[LoggedMessage]:
    """Every message of the given files (rotated parts of one run), in log-time order."""
    for path in sorted(paths):
        with path.open("rb") as f:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages(log_time_order=True):
                yield LoggedMessage(
                    topic=channel.topic,
                    schema_name=schema.name if schema is not None else "",
                    log_time_ns=message.log_time,
                    data=message.data,
                )


def model_for_schema(schema_name: str) -> type[BaseModel]:
    """The pydantic model of a logged schema name (``railtwin.PassageResult/1.0``,
    ``foxglove.Log``, ``railtwin.PassageSample``)."""
    if schema_name == foxglove.SCHEMA_NAME:
        return foxglove.Log
    if schema_name == foxglove.SAMPLE_SCHEMA_NAME:
        return foxglove.PassageSample
    name = schema_name.removeprefix("railtwin.").split("/", 1)[0]
    return MESSAGE_MODELS[name]


def decode(message: LoggedMessage) -> Any:
    """Validate a logged message against its schema's model."""
    return model_for_schema(message.schema_name).model_validate_json(message.data)
