"""Reading ``run.mcap``, the recording ``glint run SCENARIO --record --out DIR`` writes.

One channel per topic, named as the topic; its schema is named by the contract type name and
its data is JSON: ``{"type", "contract_version", "repr", "frame", "types": [TypeLayout…]}``.
Each message is the ``#[repr(C)]`` bytes as they were in shared memory; a frame topic's message
is its ``FrameHeader`` then ``width_px × height_px`` little-endian ``u16`` pixels. Log time: the
producer's send time (``CLOCK_MONOTONIC`` ns); publish time: the simulated time (ns); sequence:
``meta.seq`` (low 32 bits). Metadata ``scenario``: ``name``, ``seed``, ``toml`` (resolved).

Newer glints add channels of other encodings (``faults``: JSON messages with a ``jsonschema``
schema) and attachments (``report.json``): JSON channels are decoded as JSON, any other
channel's messages come back as their bytes (``RecordedRaw``).
"""

from __future__ import annotations

import json
import os
import tomllib
from dataclasses import dataclass, field
from typing import Any, BinaryIO, Iterable, Iterator

import numpy as np
from mcap.reader import make_reader

from .layout import CONTRACT_VERSION, Layouts, LayoutError, TypeLayout, View

SCHEMA_ENCODING = "glint.repr-c"


class RecordingError(ValueError):
    """A file that is not a glint recording this package can read."""


@dataclass(frozen=True)
class Channel:
    id: int
    topic: str
    type_name: str  #: the schema's name: a contract type name, ``glint.v8.Detections``
    layout: TypeLayout | None  #: a ``glint.repr-c`` channel's payload layout
    is_frame: bool  #: the header, then the pixels
    message_count: int
    metadata: dict[str, str]
    message_encoding: str  #: ``glint.repr-c``, ``json`` …
    schema: dict[str, Any] | bytes = field(repr=False)


@dataclass(frozen=True)
class RecordedMessage:
    topic: str
    log_time_ns: int  #: the producer's send time, CLOCK_MONOTONIC
    publish_time_ns: int  #: the simulated time the message describes
    sequence: int
    value: View  #: decoded, a read-only view on ``data``
    data: bytes

    def __getattr__(self, name: str) -> Any:
        return getattr(self.value, name)


@dataclass(frozen=True)
class RecordedJson:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    value: Any  #: the message's JSON
    data: bytes


@dataclass(frozen=True)
class RecordedRaw:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes


@dataclass(frozen=True)
class RecordedFrame:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    header: View
    pixels: np.ndarray  #: ``uint16[height_px, width_px]``, read-only, a view on ``data``
    data: bytes

    def checksum_ok(self) -> bool:
        import xxhash

        return xxhash.xxh3_64_intdigest(self.pixels.data) == int(self.header.pixels_xxh3)


Recorded = RecordedMessage | RecordedFrame | RecordedJson | RecordedRaw


class Recording:
    """A ``run.mcap`` opened for reading; every message decoded from its channel's layout.

    >>> with Recording("run/run.mcap") as rec:
    ...     for f in rec.frames():
    ...         print(f.header.frame_index, f.pixels.mean())
    """

    def __init__(self, path: str | os.PathLike[str]):
        self.path = os.fspath(path)
        self._file: BinaryIO = open(self.path, "rb")
        try:
            self._reader = make_reader(self._file)
            summary = self._reader.get_summary()
            if summary is None:
                raise RecordingError(f"{self.path}: no summary (a recording cut short?)")
            counts = summary.statistics.channel_message_counts if summary.statistics else {}
            self.channels: dict[str, Channel] = {}
            bundled: Layouts | None = None
            layouts: Layouts | None = None
            for ch in sorted(summary.channels.values(), key=lambda c: c.id):
                sc = summary.schemas.get(ch.schema_id)
                count = int(counts.get(ch.id, 0))
                if ch.message_encoding != SCHEMA_ENCODING or sc is None:
                    self.channels[ch.topic] = Channel(
                        id=ch.id, topic=ch.topic, type_name=sc.name if sc else "", layout=None,
                        is_frame=False, message_count=count, metadata=dict(ch.metadata),
                        message_encoding=ch.message_encoding, schema=sc.data if sc else b"")
                    continue
                if sc.encoding != SCHEMA_ENCODING:
                    raise RecordingError(f"channel {ch.topic}: schema encoding {sc.encoding!r}")
                data = json.loads(sc.data)
                if data.get("contract_version") != CONTRACT_VERSION:
                    raise RecordingError(
                        f"channel {ch.topic}: contract {data.get('contract_version')}, this "
                        f"package reads {CONTRACT_VERSION}")
                if "types" in data:
                    lay = Layouts.from_json(data)
                else:
                    # A glint from before layouts were recorded: the bundled ones, if the size
                    # the schema states agrees.
                    bundled = bundled or Layouts.bundled()
                    lay = bundled
                    if lay.get(data["type"]).size != data.get("size_bytes"):
                        raise RecordingError(f"channel {ch.topic}: no layout in the schema and "
                                             "the bundled one has another size")
                layouts = lay if layouts is None else layouts.merged(lay)
                self.channels[ch.topic] = Channel(
                    id=ch.id, topic=ch.topic, type_name=data["type"],
                    layout=lay.get(data["type"]), is_frame=data.get("frame") is not None,
                    message_count=count, metadata=dict(ch.metadata),
                    message_encoding=ch.message_encoding, schema=data)
            self.layouts = layouts or Layouts.bundled()
            self._by_id = {c.id: c for c in self.channels.values()}
            self.metadata: dict[str, dict[str, str]] = {
                m.name: dict(m.metadata) for m in self._reader.iter_metadata()}
            self.attachments: dict[str, bytes] = {
                a.name: bytes(a.data) for a in self._reader.iter_attachments()}
        except Exception:
            self._file.close()
            raise

    # -- what the file holds ----------------------------------------------------------------
    def counts(self) -> dict[str, int]:
        """Messages per channel (topic), from the summary."""
        return {t: c.message_count for t, c in self.channels.items()}

    @property
    def scenario(self) -> dict[str, Any]:
        """The ``scenario`` metadata: ``name``, ``seed`` and ``toml`` (the resolved scenario),
        with ``resolved`` the TOML parsed."""
        meta = dict(self.metadata.get("scenario", {}))
        out: dict[str, Any] = dict(meta)
        if "toml" in meta:
            out["resolved"] = tomllib.loads(meta["toml"])
        return out

    @property
    def report(self) -> dict[str, Any] | None:
        """The run's ``report.json``, where the recording carries it as an attachment."""
        data = self.attachments.get("report.json")
        return None if data is None else json.loads(data)

    # -- messages ---------------------------------------------------------------------------
    def messages(self, topics: Iterable[str] | None = None) -> Iterator[Recorded]:
        """Every message of ``topics`` (all when None), decoded, in log-time order."""
        wanted = list(topics) if topics is not None else None
        if wanted is not None:
            unknown = set(wanted) - set(self.channels)
            if unknown:
                raise RecordingError(f"no channel {sorted(unknown)}; has {sorted(self.channels)}")
        for _schema, ch, m in self._reader.iter_messages(topics=wanted):
            yield self._decode(self._by_id[ch.id], m.data, m.log_time, m.publish_time,
                               m.sequence)

    def frames(self, topic: str = "frame") -> Iterator[RecordedFrame]:
        if not self.channels.get(topic, None) or not self.channels[topic].is_frame:
            raise RecordingError(f"{topic!r} is not a frame channel of this recording")
        for f in self.messages([topic]):
            assert isinstance(f, RecordedFrame)
            yield f

    def table(self, topic: str) -> np.ndarray:
        """Every message of a message topic as one structured array (a copy)."""
        ch = self.channels[topic]
        if ch.is_frame or ch.layout is None:
            raise RecordingError(f"{topic!r} is not a message channel of glint structs")
        dt = self.layouts.dtype(ch.layout.name)
        chunks = [m.data for m in self.messages([topic])]
        return np.frombuffer(b"".join(chunks), dtype=dt).copy()

    def _decode(self, ch: Channel, data: bytes, log_time: int, publish_time: int,
                sequence: int) -> Recorded:
        if ch.layout is None:
            if ch.message_encoding == "json":
                return RecordedJson(ch.topic, log_time, publish_time, sequence,
                                    json.loads(data), data)
            return RecordedRaw(ch.topic, log_time, publish_time, sequence, data)
        dt = self.layouts.dtype(ch.layout.name)
        if len(data) < dt.itemsize:
            raise RecordingError(f"{ch.topic}: a {len(data)}-byte message, its type is "
                                 f"{dt.itemsize}")
        value = View(np.frombuffer(data, dtype=dt, count=1)[0])
        if not ch.is_frame:
            if len(data) != dt.itemsize:
                raise RecordingError(f"{ch.topic}: {len(data)} bytes for a {dt.itemsize}-byte "
                                     "message")
            return RecordedMessage(ch.topic, log_time, publish_time, sequence, value, data)
        w, h = int(value.width_px), int(value.height_px)
        if len(data) != dt.itemsize + 2 * w * h:
            raise RecordingError(f"{ch.topic}: {len(data)} bytes for a {w}x{h} frame")
        pixels = np.frombuffer(data, dtype="<u2", count=w * h, offset=dt.itemsize).reshape(h, w)
        return RecordedFrame(ch.topic, log_time, publish_time, sequence, value, pixels, data)

    # -- closing ----------------------------------------------------------------------------
    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["Channel", "LayoutError", "Recorded", "RecordedFrame", "RecordedJson",
           "RecordedMessage", "RecordedRaw", "Recording", "RecordingError"]
