"""MCAP read at the byte level, faster than the mcap library's record classes: the summary
(``read_summary``) and the messages of indexed chunks (``chunked_messages``), each chunk checked
against the CRC it was written with; and where a second recording starts in a file that holds
several joined (``next_recording``). The layout is MCAP's (mcap.dev/spec), spelt in
``seaway.recording.layout``. Offsets and sizes in bytes from the start of the file.
"""

from __future__ import annotations

import io
import struct
import threading
import zlib
from collections.abc import Iterable, Iterator
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import (
    AttachmentIndex,
    Channel,
    ChunkIndex,
    MetadataIndex,
    Schema,
    Statistics,
)
from mcap.summary import Summary

from seaway.recording.layout import (
    CHUNK_HEAD,
    CHUNK_INDEX_HEAD,
    FOOTER,
    MAGIC,
    MESSAGE_HEAD,
    RECORD_HEAD,
    U32,
    U64,
)

RECORDING_START = MAGIC + bytes([Opcode.HEADER])
"""The bytes a recording starts with: the magic, then its header record's opcode."""
_DATA_END = RECORD_HEAD.size + 4
"""A Data End record's size: its head and its data section CRC."""


class JoinedRecordingsError(McapError):
    """A file holding more than one recording, one after another (files joined with ``cat``):
    its summary describes one of them at most. ``at``: the byte where the second starts."""

    def __init__(self, at: int) -> None:
        super().__init__(f"it holds more than one recording: a second one starts at byte {at}")
        self.at = at


_SUMMARY_RECORDS: dict[int, Any] = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel,
                                     Opcode.STATISTICS: Statistics,
                                     Opcode.ATTACHMENT_INDEX: AttachmentIndex,
                                     Opcode.METADATA_INDEX: MetadataIndex}
"""The summary's other records, read by the mcap library's own record classes."""


def read_summary(fh: Any) -> Summary | None:
    """The summary section of the MCAP file ``fh`` (open for binary reading), as the mcap reader's
    ``get_summary`` gives it; None when the file has none. McapError when it is damaged;
    ``JoinedRecordingsError`` when the file holds several recordings joined.

    Why not the reader's: a lockstep recording has a chunk a period, so its summary is mostly
    chunk indexes (18,345 for a study stack's 8 runs), and the reader parsed each field by field in
    Python: 0.29 s a file, read twice for a report. Here a chunk index is one ``struct`` call or two;
    the other records (schemas, channels, statistics, attachment and metadata indexes) are still
    read by the library's classes. The layout is MCAP's (mcap.dev/spec: Footer, Chunk Index)."""
    try:
        return _read_summary(fh)
    except McapError:
        # A footer that does not describe the file: a second recording after the first is the one
        # cause worth naming (its footer is the one at the end, its offsets its own).
        second = next_recording(fh, len(MAGIC))
        if second is not None:
            raise JoinedRecordingsError(second) from None
        raise


def _read_summary(fh: Any) -> Summary | None:
    fh.seek(0, 2)
    size = fh.tell()
    tail = FOOTER.size + len(MAGIC)
    if size < tail + len(MAGIC):
        raise McapError("too short to have a footer")
    fh.seek(size - tail)
    op, _, summary_start, _, _ = FOOTER.unpack(fh.read(FOOTER.size))
    if op != Opcode.FOOTER:
        raise McapError(f"expected a footer at byte {size - tail}, found opcode {op:#x}")
    if summary_start == 0:
        return None
    # The summary section starts right after the data end record: where it does not, the footer's
    # offsets are not this file's (damage, or another recording's footer).
    fh.seek(max(summary_start - _DATA_END, 0))
    head = fh.read(RECORD_HEAD.size)
    if (summary_start < _DATA_END or len(head) != RECORD_HEAD.size
            or RECORD_HEAD.unpack(head) != (Opcode.DATA_END, 4)):
        raise McapError(f"the footer's summary start (byte {summary_start}) does not follow a "
                        "data end record")
    fh.seek(summary_start)
    data = fh.read(size - tail - summary_start)
    summary = Summary()
    pos = 0
    try:
        while pos < len(data):
            op, length = RECORD_HEAD.unpack_from(data, pos)
            at, body, pos = pos, pos + RECORD_HEAD.size, pos + RECORD_HEAD.size + length
            if pos > len(data) or op in (Opcode.FOOTER, MAGIC[0]):  # past the section's end
                raise McapError(f"the summary's record at byte {summary_start + at} (opcode "
                                f"{op:#x}, {length} bytes) runs past the footer")
            if op == Opcode.CHUNK_INDEX:
                summary.chunk_indexes.append(_chunk_index(data, body, pos))
            elif (kind := _SUMMARY_RECORDS.get(op)) is not None:
                record = kind.read(ReadDataStream(io.BytesIO(data[body:pos])))
                if kind is Statistics:
                    summary.statistics = record
                elif kind is Schema:
                    summary.schemas[record.id] = record
                elif kind is Channel:
                    summary.channels[record.id] = record
                elif kind is AttachmentIndex:
                    summary.attachment_indexes.append(record)
                else:
                    summary.metadata_indexes.append(record)
    except (struct.error, UnicodeDecodeError) as err:
        raise McapError(f"the summary's record at byte {summary_start + pos} is damaged "
                        f"({type(err).__name__}: {err})") from None
    return summary


def _chunk_index(data: bytes, pos: int, end: int) -> ChunkIndex:
    """The chunk index whose fields are ``data[pos:end]``; McapError if they do not fill it."""
    start_ns, end_ns, offset, length, map_len = CHUNK_INDEX_HEAD.unpack_from(data, pos)
    if map_len % 10:
        raise McapError(f"a chunk index's map of {map_len} bytes is not whole entries of 10")
    pos += CHUNK_INDEX_HEAD.size
    pairs = struct.unpack_from("<" + "HQ" * (map_len // 10), data, pos)
    pos += map_len
    (index_len,) = U64.unpack_from(data, pos)
    (n,) = U32.unpack_from(data, pos + 8)
    compression = data[pos + 12:pos + 12 + n].decode()
    compressed, uncompressed = struct.unpack_from("<QQ", data, pos + 12 + n)
    if pos + 12 + n + 16 != end:
        raise McapError(f"a chunk index's fields end at {pos + 12 + n + 16 - end:+d} bytes from "
                        f"its record's end")
    return ChunkIndex(chunk_length=length, chunk_start_offset=offset, compression=compression,
                      compressed_size=compressed, message_end_time=end_ns,
                      message_index_length=index_len,
                      message_index_offsets=dict(zip(pairs[0::2], pairs[1::2], strict=True)),
                      message_start_time=start_ns, uncompressed_size=uncompressed)


def next_recording(fh: Any, start: int, end: int | None = None) -> int | None:
    """The byte, at or after ``start`` and before ``end`` (None: the file's end), where a
    recording starts (its magic and header), or None. Read in blocks: this is for a file already
    found wrong, not for every read."""
    block = 1 << 22
    pos = start
    while end is None or pos < end:
        fh.seek(pos)
        want = block if end is None else min(block, end - pos + len(RECORDING_START) - 1)
        data = fh.read(want)
        at = data.find(RECORDING_START)
        if at >= 0 and (end is None or pos + at < end):
            return pos + at
        if len(data) < want or len(data) < len(RECORDING_START):
            return None
        pos += len(data) - len(RECORDING_START) + 1  # a start across two blocks is still found
    return None


_local = threading.local()


def _zstd() -> Any:
    """This thread's zstd decompressor (one per chunk cost more than the decompression; an
    instance is not to be shared between threads, and a study reports two stacks at once)."""
    d = getattr(_local, "zstd", None)
    if d is None:
        import zstandard

        d = _local.zstd = zstandard.ZstdDecompressor()
    return d


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        return _zstd().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.decompress(data)
    raise McapError(f"unsupported chunk compression {compression!r}")


def chunked_messages(fh: Any, chunk_indexes: Iterable[ChunkIndex], channel_ids: set[int]
                     ) -> Iterator[tuple[int, int, bytes]]:
    """(channel id, log time, data) of every message on ``channel_ids`` in the chunks the summary
    indexes, in file order: what the mcap reader's ``iter_messages(topics, log_time_order=False)``
    yields (it too reads only the indexed chunks), without making a record object of every message.
    McapError naming the chunk (the byte it starts at) where one is damaged: its CRC (when written)
    is checked, so a flipped bit that still decompresses is found too.

    Why: a lockstep recorder ends a chunk every period, some 20 messages of every topic each, and
    the mcap reader parses all of them field by field in Python to hand on the few wanted, most of
    a report's decode. Here a chunk whose index names none of ``channel_ids`` is not read, and a
    message on another channel is skipped by its length. A chunk written without message indexes
    says nothing of its channels: it is read, as the reader does."""
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        if ci.message_index_offsets and channel_ids.isdisjoint(ci.message_index_offsets):
            continue
        data = chunk_records(fh, ci)
        try:
            found = _chunk_messages(data, channel_ids)
        except struct.error as err:
            raise McapError(f"the chunk at byte {ci.chunk_start_offset} is damaged (a record runs "
                            f"past its end: {err})") from None
        yield from found


def chunk_records(fh: Any, ci: ChunkIndex) -> bytes:
    """The records of the chunk ``ci`` indexes, uncompressed and checked against the chunk's CRC
    (none written: 0, not checked); McapError naming the chunk where it is damaged."""
    try:
        return _chunk_records(fh, ci)
    except Exception as err:  # struct, decompression, text, CRC: a damaged chunk, said where
        raise McapError(f"the chunk at byte {ci.chunk_start_offset} is damaged "
                        f"({type(err).__name__}: {err})") from None


def _chunk_records(fh: Any, ci: ChunkIndex) -> bytes:
    fh.seek(ci.chunk_start_offset)
    return chunk_body(fh.read(ci.chunk_length))


def chunk_body(rec: bytes) -> bytes:
    """The records of the Chunk record ``rec`` (from its opcode on), uncompressed and checked
    against its CRC (none written: 0, not checked). Raises McapError, struct.error or a
    decompressor's error where it is damaged (``chunk_records`` says which chunk)."""
    op, _ = RECORD_HEAD.unpack_from(rec, 0)
    if op != Opcode.CHUNK:
        raise McapError(f"opcode {op:#x}, not a chunk's")
    _, _, size, crc = CHUNK_HEAD.unpack_from(rec, RECORD_HEAD.size)
    pos = RECORD_HEAD.size + CHUNK_HEAD.size
    (n,) = U32.unpack_from(rec, pos)
    compression = rec[pos + 4:pos + 4 + n].decode()
    pos += 4 + n
    (records_len,) = U64.unpack_from(rec, pos)
    data = _decompress(compression, rec[pos + 8:pos + 8 + records_len], size)
    if len(data) != size:
        raise McapError(f"its records are {len(data)} bytes, and it says {size}")
    if crc and (actual := zlib.crc32(data)) != crc:
        raise McapError(f"its records' CRC is {actual:#010x}, and it says {crc:#010x}")
    return data


def _chunk_messages(data: bytes, channel_ids: set[int]) -> list[tuple[int, int, bytes]]:
    """(channel id, log time, data) of the messages on ``channel_ids`` among a chunk's records."""
    out = []
    pos, end = 0, len(data)
    while pos < end:
        op, length = RECORD_HEAD.unpack_from(data, pos)
        body = pos + RECORD_HEAD.size
        pos = body + length
        if op == Opcode.MESSAGE:
            cid, _, log_ns, _ = MESSAGE_HEAD.unpack_from(data, body)
            if cid in channel_ids:
                out.append((cid, log_ns, data[body + MESSAGE_HEAD.size:pos]))
    return out


def first_damaged_chunk(fh: Any, chunk_indexes: Iterable[ChunkIndex]) -> McapError | None:
    """The error of the first chunk (in file order) that ``chunk_records`` refuses, or None: where
    another reader (the mcap library's) failed without saying which chunk."""
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        try:
            chunk_records(fh, ci)
        except McapError as err:
            return err
    return None
