"""The end of a recording a killed recorder left (``tail_of``): what its restarted successor must
not write twice, and when the predecessor's last message was.

A killed recorder's file has no summary, so it is walked from the start, record by record, by the
lengths the records give: a chunk's head (its first and last log time) is read, its compressed
records are not. Only the chunks that end at or after ``since_ns`` are decompressed for their
messages. The channels those messages name are then looked up in the chunks from the start (a
channel is declared in the chunk of its first message, or the one before), stopping once each is
found. So the read grows with the number of records, not with their bytes, and a long recording is
not parsed message by message (the mcap library's reader makes an object of each).

The walk ends where the file is cut (a record running past its end, as a killed writer leaves it)
or stops being MCAP. A damaged chunk is skipped: its messages cannot be known, so what the
publishers' caches send again from it is written again, never lost.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel

from seaway.recording.chunks import chunk_body
from seaway.recording.layout import CHUNK_HEAD, MAGIC, MESSAGE_HEAD, RECORD_HEAD

_KNOWN_OPCODES = frozenset(int(op) for op in Opcode)
_CHANNEL, _MESSAGE, _CHUNK = int(Opcode.CHANNEL), int(Opcode.MESSAGE), int(Opcode.CHUNK)
_END = frozenset((int(Opcode.DATA_END), int(Opcode.FOOTER)))
_BUFFER = 1 << 20
"""The read buffer [bytes]: many records' heads per system call."""


@dataclass
class Tail:
    """The end of a recording a recorder left (killed): its last log time [ns], and the messages it
    holds from ``since_ns`` on, as (topic, bytes)."""

    last_log_ns: int = 0
    messages: set[tuple[str, bytes]] = field(default_factory=set)


@dataclass
class _Walk:
    """What the walk over the top-level records found: the chunks (start byte, end byte, last log
    time), and the channels and messages outside any chunk (id -> topic; (id, log time, data))."""

    chunks: list[tuple[int, int, int]] = field(default_factory=list)
    topics: dict[int, str] = field(default_factory=dict)
    loose: list[tuple[int, int, bytes]] = field(default_factory=list)


def tail_of(src: Path, since_ns: int) -> Tail:
    """``Tail`` of ``src`` from ``since_ns`` [ns, log time] on, read as far as the file is whole.

    Read through a buffer, not mapped: a file cut short while it is read gives a short read (the
    end), where a mapping would kill the process."""
    tail = Tail()
    with open(src, "rb", buffering=_BUFFER) as fh:
        if fh.read(len(MAGIC)) != MAGIC:
            return tail
        walk = _walk(fh, fh.seek(0, io.SEEK_END))
        found: list[tuple[int, int, bytes]] = [m for m in walk.loose if m[1] >= since_ns]
        tail.last_log_ns = max((m[1] for m in walk.loose), default=0)
        old: list[tuple[int, int]] = []
        for start, end, end_ns in walk.chunks:
            if end_ns < since_ns:
                old.append((start, end))
                tail.last_log_ns = max(tail.last_log_ns, end_ns)
                continue
            records = _records(fh, start, end)
            if records is None:
                continue  # damaged: its times are not to be trusted either
            tail.last_log_ns = max(tail.last_log_ns, end_ns)
            found += _scan(records, walk.topics, since_ns)
        wanted = {cid for cid, _, _ in found} - walk.topics.keys()
        for start, end in old:
            if not wanted:
                break
            records = _records(fh, start, end)
            if records is not None:
                _scan(records, walk.topics, None)
                wanted -= walk.topics.keys()
    tail.messages = {(walk.topics[cid], payload) for cid, _, payload in found if cid in walk.topics}
    return tail


def _walk(fh: BinaryIO, size: int) -> _Walk:
    """The top-level records of ``fh`` from after the magic, until the data section ends, a
    record runs past the file's end (``size`` bytes), or an opcode is not MCAP's. Each record's
    head is read and the rest skipped (a seek within the buffer costs no system call)."""
    out = _Walk()
    pos, head = len(MAGIC), RECORD_HEAD.size
    fh.seek(pos)
    read, seek, unpack = fh.read, fh.seek, RECORD_HEAD.unpack
    while pos + head <= size:
        raw = read(head)
        if len(raw) < head:
            break
        op, length = unpack(raw)
        end = pos + head + length
        if end > size or op not in _KNOWN_OPCODES or op in _END:
            break
        if op == _CHUNK:
            raw = read(CHUNK_HEAD.size)
            if length < CHUNK_HEAD.size or len(raw) < CHUNK_HEAD.size:
                break
            out.chunks.append((pos, end, CHUNK_HEAD.unpack(raw)[1]))
        elif op in (_CHANNEL, _MESSAGE):  # outside a chunk (a writer without chunks)
            seek(pos)
            out.loose += _scan(read(end - pos), out.topics, 0)
        seek(end)
        pos = end
    return out


def _records(fh: BinaryIO, start: int, end: int) -> bytes | None:
    """The uncompressed records of the chunk at bytes ``[start, end)``, or None where it is
    damaged (it does not decompress, its CRC differs, its head lies, the file ends in it)."""
    fh.seek(start)
    try:
        return chunk_body(fh.read(end - start))
    except Exception:  # struct, decompression, text, CRC: each a damaged chunk
        return None


def _scan(records: bytes, topics: dict[int, str], since_ns: int | None
          ) -> list[tuple[int, int, bytes]]:
    """Add the channels among ``records`` to ``topics``, and return the messages logged at or
    after ``since_ns`` (None: none) as (channel id, log time [ns], data). Records are skipped by
    their lengths; one that runs past the end ends the scan."""
    out: list[tuple[int, int, bytes]] = []
    pos, end, head = 0, len(records), RECORD_HEAD.size
    while pos + head <= end:
        op, length = RECORD_HEAD.unpack_from(records, pos)
        body = pos + head
        pos = body + length
        if pos > end:
            break
        if op == _CHANNEL:
            try:
                channel = Channel.read(ReadDataStream(io.BytesIO(records[body:pos])))
            except (McapError, ValueError, UnicodeDecodeError, EOFError):
                continue  # a channel that cannot be read names no message
            topics[channel.id] = channel.topic
        elif op == _MESSAGE and since_ns is not None and length >= MESSAGE_HEAD.size:
            cid, _, log_ns, _ = MESSAGE_HEAD.unpack_from(records, body)
            if log_ns >= since_ns:
                out.append((cid, log_ns, records[body + MESSAGE_HEAD.size:pos]))
    return out
