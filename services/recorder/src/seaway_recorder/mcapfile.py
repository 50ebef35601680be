"""The recorder's MCAP writer: the file ``mcap.writer.Writer`` writes, for a fraction of the work.

A lockstep recorder ends a chunk every simulated period (the sim moves on only once a period is on
disk), some 20 messages a chunk. Through the mcap library's ``Writer`` each message is a
``Message`` dataclass written field by field (a ``struct.pack`` and a buffer write per field, a
seek back for the length) and each chunk a dozen records built the same way, a large share of the
recorder's Python time in lockstep. Here the four
records written per message or per chunk (Message, Chunk, MessageIndex, ChunkIndex) are each one
``struct.pack``, and the chunk's bytes are joined once. Everything else (header, schemas, channels,
attachments, metadata, the summary and footer) is written by the mcap library's own record classes.

The output is byte for byte the output of ``mcap.writer.Writer`` with its defaults (every index,
schemas and channels repeated in the summary, statistics, summary offsets, chunk CRCs, no data
section CRC) given the same calls: ``tests/unit/recorder/test_mcapfile.py`` holds the two to the
same bytes over random call sequences, for each compression. The chunk indexes, one per chunk, wait
for the summary in an anonymous temporary file as their record bytes, so the recorder's memory does
not grow with the number of chunks (it did by 19 MB over a 600 s soak while they were Python
objects).

A disk that fills up (``disk_full``) loses nothing already handed over: each chunk, with its message
indexes, is one write, and every piece of the writer's state changes only once its write is done. A
chunk that found no room stays in memory, whole, and goes out at the next ``flush`` (a chunk that
grows past ``chunk_size`` while the disk is full is tried again at the next ``flush``, not at every
message); ``finish`` writes the summary and footer in one write, so a file it could not finish is
the same as before, and can be finished later. The stream must write all of a write or none of it
(``seaway.runtime.disk.AllOrNothing``): a partial write would leave bytes this writer does not know of.

Units: every time is ns on the caller's timeline (MCAP's log and publish times); sizes in bytes.
"""

from __future__ import annotations

import functools
import struct
import tempfile
import zlib
from collections.abc import Callable
from typing import IO

import lz4.frame
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)
from seaway.recording.layout import (
    CHUNK_HEAD,
    CHUNK_INDEX_HEAD,
    MAGIC,
    MESSAGE_HEAD,
    RECORD_HEAD,
    U32,
    U64,
)
from seaway.runtime.disk import AllOrNothing, disk_full

COMPRESSIONS = ("zstd", "lz4", "none")
"""Chunk compressions: the names of the MCAP spec ("" in the file for none)."""

# The per-message and per-chunk records packed whole (``seaway.recording.layout`` spells each part).
_MESSAGE = struct.Struct(RECORD_HEAD.format + MESSAGE_HEAD.format[1:])
"""A Message's record head and fields in one call (the writer's hot path)."""
_CHUNK = struct.Struct(RECORD_HEAD.format + CHUNK_HEAD.format[1:] + "I")
"""A Chunk's record head, fields and the compression name's length in one call."""
_pack_message = _MESSAGE.pack
_MESSAGE_OPCODE = int(Opcode.MESSAGE)
_MESSAGE_HEAD_SIZE = MESSAGE_HEAD.size
_MESSAGE_SIZE = _MESSAGE.size


@functools.lru_cache(maxsize=256)
def _message_index(n: int) -> struct.Struct:
    """A MessageIndex record of ``n // 2`` (log time, offset) pairs, head included, in one call."""
    return struct.Struct(f"<BQHI{n}Q")


@functools.lru_cache(maxsize=256)
def _chunk_index(k: int) -> struct.Struct:
    """A ChunkIndex's fields up to its compression name, with ``k`` message index offsets."""
    return struct.Struct(f"{CHUNK_INDEX_HEAD.format}{'HQ' * k}Q")


def check_compression(compression: str) -> str:
    """``compression`` if it is one of ``COMPRESSIONS``; else ValueError naming them."""
    if compression not in COMPRESSIONS:
        raise ValueError(f"compression {compression!r}: use one of {', '.join(COMPRESSIONS)}")
    return compression


def _compressor(compression: str) -> tuple[str, Callable[[bytes], bytes] | None]:
    """The name written into each chunk and the function compressing its records (None: none).
    zstd at level 3 and lz4's frame defaults, as ``mcap.writer.Writer`` compresses; one zstd
    context for the file, not one per chunk (the same bytes)."""
    if check_compression(compression) == "zstd":
        return "zstd", zstandard.ZstdCompressor(level=3).compress
    if compression == "lz4":
        return "lz4", lz4.frame.compress
    return "", None


def _record(write: Callable[[RecordBuilder], None]) -> bytes:
    builder = RecordBuilder()
    write(builder)
    return builder.end()


class McapWriter:
    """Writes one MCAP file to ``stream`` (opened for binary writing; not closed here).

    ``chunk_size``: a chunk ends once its records exceed this many bytes, and at every ``flush``.
    The calls are ``mcap.writer.Writer``'s: ``start``, ``register_schema``, ``register_channel``,
    ``add_message``, ``add_attachment``, ``add_metadata``, ``flush``, ``finish``.
    """

    def __init__(self, stream: IO[bytes], chunk_size: int = 1024 * 1024,
                 compression: str = "zstd") -> None:
        self._stream = stream
        self._chunk_size = chunk_size
        self._compression, self._compress = _compressor(compression)
        self._name = self._compression.encode()
        self._index_tail = U32.pack(len(self._name)) + self._name
        """A chunk index's compression name (length-prefixed), before its two sizes."""
        # The chunk in progress: its records' bytes, their length, and each channel's (log time,
        # offset) pairs flat, in the order the channels first appear in it.
        self._parts: list[bytes] = []
        self._length = 0
        self._index: dict[int, list[int]] = {}
        self._chunk_indexes = AllOrNothing(tempfile.TemporaryFile(buffering=0))  # noqa: SIM115 - closed in finish()/close()
        self._schemas: dict[int, Schema] = {}
        self._channels: dict[int, Channel] = {}
        self._attachment_indexes: list[AttachmentIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._stats = Statistics(attachment_count=0, channel_count=0, channel_message_counts={},
                                 chunk_count=0, message_count=0, message_end_time=0,
                                 message_start_time=0, metadata_count=0, schema_count=0)
        self._counts = self._stats.channel_message_counts
        self.deferred: OSError | None = None
        """The disk-full error that kept a chunk past ``chunk_size`` in memory (``add_message``);
        cleared once a chunk is written. ``flush`` raises it anew if there is still no room."""

    def start(self, profile: str = "", library: str = "") -> None:
        self._stream.write(MAGIC)
        self._stream.write(_record(Header(profile, library).write))

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas[schema.id] = schema
        self._stats.schema_count += 1
        self._add_to_chunk(_record(schema.write))
        return schema.id

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str] | None = None) -> int:
        channel = Channel(id=len(self._channels) + 1, topic=topic,
                          message_encoding=message_encoding, schema_id=schema_id,
                          metadata=dict(metadata or {}))
        self._channels[channel.id] = channel
        self._stats.channel_count += 1
        self._add_to_chunk(_record(channel.write))
        return channel.id

    def _add_to_chunk(self, record: bytes) -> None:
        """A schema or channel record, into the chunk in progress (as the mcap Writer does)."""
        self._parts.append(record)
        self._length += len(record)
        if self._length > self._chunk_size and self.deferred is None:
            self._end_chunk_if_room()

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int,
                    sequence: int = 0) -> None:
        # The statistics and the chunk's times are taken from its index when it ends: nothing
        # per message but the index entry and the record.
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = []
        length = self._length
        index += (log_time, length)
        self._parts += (_pack_message(_MESSAGE_OPCODE, _MESSAGE_HEAD_SIZE + len(data), channel_id,
                                      sequence, log_time, publish_time), data)
        self._length = length = length + _MESSAGE_SIZE + len(data)
        if length > self._chunk_size and self.deferred is None:
            self._end_chunk_if_room()

    def _end_chunk_if_room(self) -> None:
        """End the chunk grown past its size; with the disk full, keep it (and the error) for the
        next ``flush``: a message handed over is never refused, and never half written."""
        try:
            self._end_chunk()
        except OSError as err:
            if not disk_full(err):
                raise
            self.deferred = err

    def add_attachment(self, create_time: int, log_time: int, name: str, media_type: str,
                       data: bytes) -> None:
        offset = self._stream.tell()
        attachment = Attachment(create_time=create_time, log_time=log_time, name=name,
                                media_type=media_type, data=data)
        record = _record(attachment.write)
        self._stream.write(record)  # first: a write that fails changes nothing here
        self._stats.attachment_count += 1
        self._attachment_indexes.append(AttachmentIndex(
            offset=offset, length=len(record), create_time=create_time, log_time=log_time,
            data_size=len(data), name=name, media_type=media_type))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        offset = self._stream.tell()
        record = _record(Metadata(name=name, metadata=data).write)
        self._stream.write(record)  # first: a write that fails changes nothing here
        self._stats.metadata_count += 1
        self._metadata_indexes.append(MetadataIndex(offset=offset, length=len(record), name=name))

    def _end_chunk(self) -> None:
        """Write the chunk in progress (if it has a message), its message indexes, and keep its
        chunk index for the summary: each in one write. Nothing changes here before both writes
        are done: if either fails (a full disk), the chunk is still the chunk in progress."""
        index = self._index
        if not index:
            return
        start_ns = end_ns = -1
        per_channel: list[tuple[int, int]] = []
        for channel_id, pairs in index.items():
            times = pairs[0::2]
            lo, hi = min(times), max(times)
            if start_ns < 0 or lo < start_ns:
                start_ns = lo
            if hi > end_ns:
                end_ns = hi
            per_channel.append((channel_id, len(times)))
        raw = b"".join(self._parts)
        data = self._compress(raw) if self._compress is not None else raw
        name = self._name
        chunk_start = self._stream.tell()
        chunk_length = _CHUNK.size + len(name) + U64.size + len(data)
        out = [_CHUNK.pack(Opcode.CHUNK, chunk_length - RECORD_HEAD.size, start_ns, end_ns,
                           len(raw), zlib.crc32(raw), len(name)), name, U64.pack(len(data)), data]
        index_start = at = chunk_start + chunk_length
        offsets: list[int] = []
        for channel_id, pairs in index.items():
            n = len(pairs)
            record = _message_index(n).pack(Opcode.MESSAGE_INDEX, 2 + 4 + 8 * n, channel_id,
                                            8 * n, *pairs)
            offsets += (channel_id, at)
            at += len(record)
            out.append(record)
        k = len(offsets) // 2
        body = _chunk_index(k).pack(start_ns, end_ns, chunk_start, chunk_length, 10 * k, *offsets,
                                    at - index_start)
        spill = self._chunk_indexes
        spilled_to = spill.tell()
        spill.write(b"".join((
            RECORD_HEAD.pack(Opcode.CHUNK_INDEX, len(body) + len(self._index_tail) + 16), body,
            self._index_tail, U64.pack(len(data)), U64.pack(len(raw)))))
        try:
            self._stream.write(b"".join(out))
        except BaseException:
            spill.cut(spilled_to)  # the chunk index of a chunk not written
            raise
        stats, counts = self._stats, self._counts
        messages = 0
        for channel_id, n in per_channel:
            counts[channel_id] = counts.get(channel_id, 0) + n
            messages += n
        if stats.message_count == 0 or start_ns < stats.message_start_time:
            stats.message_start_time = start_ns
        if end_ns > stats.message_end_time:
            stats.message_end_time = end_ns
        stats.message_count += messages
        stats.chunk_count += 1
        self._parts.clear()
        self._length = 0
        self._index = {}
        self.deferred = None

    def flush(self) -> None:
        """End the chunk in progress and hand everything written to the OS (no fsync)."""
        self._end_chunk()
        self._stream.flush()

    def finish(self, metadata: tuple[str, dict[str, str]] | None = None) -> None:
        """End the last chunk and write the data end, the summary (schemas, channels, statistics,
        chunk, attachment and metadata indexes, each group with its summary offset) and the footer.
        ``metadata``: a last metadata record (name, map), written before the data end, as
        ``add_metadata`` then ``finish`` would. All that follows the last chunk is one write: with no
        room for it, the file and this writer stay as they were, and ``finish`` can be called again."""
        self._end_chunk()
        stream = self._stream
        stats = self._stats
        last = b""
        metadata_indexes = self._metadata_indexes
        if metadata is not None:
            last = _record(Metadata(name=metadata[0], metadata=metadata[1]).write)
            metadata_indexes = [*metadata_indexes,
                                MetadataIndex(offset=stream.tell(), length=len(last), name=metadata[0])]
            stats.metadata_count += 1
        try:
            data_end = _record(DataEnd(0).write)
            summary_start = stream.tell() + len(last) + len(data_end)
            groups = [
                (Opcode.SCHEMA, b"".join(_record(r.write) for r in self._schemas.values())),
                (Opcode.CHANNEL, b"".join(_record(r.write) for r in self._channels.values())),
                (Opcode.STATISTICS, _record(stats.write)),
                (Opcode.CHUNK_INDEX, self._chunk_indexes.read_all()),
                (Opcode.ATTACHMENT_INDEX, b"".join(_record(r.write) for r in self._attachment_indexes)),
                (Opcode.METADATA_INDEX, b"".join(_record(r.write) for r in metadata_indexes)),
            ]
            summary = bytearray()
            offsets = []
            for opcode, data in groups:
                offsets.append(SummaryOffset(group_opcode=opcode,
                                             group_start=summary_start + len(summary),
                                             group_length=len(data)))
                summary += data
            offset_start = summary_start + len(summary)
            summary += b"".join(_record(o.write) for o in offsets)
            crc = zlib.crc32(summary)
            crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                         offset_start), crc)
            stream.write(b"".join((last, data_end, summary, _record(Footer(
                summary_start=summary_start, summary_offset_start=offset_start,
                summary_crc=crc).write), MAGIC)))
        except BaseException:
            if metadata is not None:
                stats.metadata_count -= 1
            raise
        self._metadata_indexes = metadata_indexes
        self.close()

    def close(self) -> None:
        """Drop the spilled chunk indexes (``finish`` does; a writer given up calls it alone)."""
        self._chunk_indexes.close()
