"""Rebuild a fully indexed MCAP file from a truncated one (a recorder killed with SIGKILL).

The file is read record by record from the start. Every complete record is kept: the header,
attachments, metadata, and each chunk whose bytes are all there and whose CRC matches (its schemas,
channels and messages); the first record that is cut short or corrupt ends the data. The kept
records are written again through the mcap Writer, which adds the chunk and message indexes, the
statistics and the summary. Message times, sequence numbers, channel topics and metadata and schema
bytes are kept unchanged; schema and channel ids may be renumbered.

``repaired_copy`` is what readers use: a repaired copy of a file as it is now, kept out of the
file's own folder (a live run's) in a cache, whole and never rewritten once there.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import struct
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

from mcap.exceptions import EndOfFile, McapError
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    DataEnd,
    Footer,
    Header,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from seaway.runtime.private import open_private

RECOVER_METADATA = "seaway.recover"
ENV_REPAIR_DIR = "SEAWAY_REPAIR_DIR"
"""Where readers keep repaired copies of unfinished files (default ``~/.cache/seaway/recovered``)."""
REPAIR_KEEP_S = 600.0
"""A repaired copy not made or used for this long is removed [s] (a reader that opened it has long
finished; the next reader makes it again)."""


@dataclass
class RecoverResult:
    messages: int = 0
    chunks: int = 0
    attachments: int = 0
    metadata: int = 0
    bad_chunks: int = 0
    complete: bool = False
    stopped_at_offset: int = 0
    reason: str = ""
    topics: dict[str, int] = field(default_factory=dict)

    def line(self) -> str:
        tail = "the input was complete" if self.complete else f"input ends early: {self.reason}"
        return (f"recovered {self.messages:,} messages in {self.chunks} chunks, "
                f"{self.attachments} attachments, {self.metadata} metadata; {tail}")


class _Copier:
    def __init__(self, out: Writer) -> None:
        self.out = out
        self.schema_ids: dict[int, int] = {}
        self.channel_ids: dict[int, int] = {}
        self.topic_of: dict[int, str] = {}
        self.topics: dict[str, int] = {}

    def schema(self, s: Schema) -> None:
        if s.id not in self.schema_ids:
            self.schema_ids[s.id] = self.out.register_schema(s.name, s.encoding, s.data)

    def channel(self, c: Channel) -> None:
        if c.id not in self.channel_ids:
            sid = self.schema_ids.get(c.schema_id, 0) if c.schema_id else 0
            self.channel_ids[c.id] = self.out.register_channel(c.topic, c.message_encoding, sid,
                                                               dict(c.metadata))
            self.topic_of[c.id] = c.topic

    def message(self, m: Message) -> bool:
        cid = self.channel_ids.get(m.channel_id)
        if cid is None:
            return False
        self.out.add_message(cid, m.log_time, m.data, m.publish_time, m.sequence)
        topic = self.topic_of[m.channel_id]
        self.topics[topic] = self.topics.get(topic, 0) + 1
        return True


class _Tracking:
    """A file wrapper that turns a short read (the file ends inside a record) into ``EndOfFile``."""

    def __init__(self, f: BinaryIO) -> None:
        self.f = f

    def read(self, n: int = -1) -> bytes:
        data = self.f.read(n)
        if n > 0 and len(data) < n:
            raise EndOfFile(f"file ends inside a record ({len(data)} of {n} bytes)")
        return data

    def tell(self) -> int:
        return self.f.tell()


def recover(src: Path, dst: Path, compression: CompressionType = CompressionType.ZSTD,
            chunk_size: int = 4 * 1024 * 1024) -> RecoverResult:
    """Copy every complete record of ``src`` into a new, fully indexed ``dst``."""
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise ValueError("recover writes a new file: OUT must differ from IN")
    res = RecoverResult()
    with open(src, "rb") as fin, open_private(dst) as fout:
        tracked = _Tracking(fin)
        reader = StreamReader(tracked, emit_chunks=True, record_size_limit=1 << 31)  # type: ignore[arg-type]
        out = Writer(fout, chunk_size=chunk_size, compression=compression)
        copier = _Copier(out)
        started = False
        try:
            for record in reader.records:
                res.stopped_at_offset = tracked.tell()
                if isinstance(record, Header):
                    out.start(profile=record.profile, library=record.library)
                    started = True
                elif not started:
                    raise McapError("no header record")
                elif isinstance(record, Chunk):
                    try:
                        inner = breakup_chunk(record, validate_crc=True)
                    except Exception as err:  # corrupt compressed data or CRC mismatch
                        res.bad_chunks += 1
                        res.reason = f"chunk at offset {res.stopped_at_offset}: {err}"
                        break
                    res.chunks += 1
                    for r in inner:
                        _copy(copier, r, res)
                elif isinstance(record, Schema | Channel | Message):
                    _copy(copier, record, res)
                elif isinstance(record, Attachment):
                    out.add_attachment(record.create_time, record.log_time, record.name,
                                       record.media_type, record.data)
                    res.attachments += 1
                elif isinstance(record, Metadata):
                    out.add_metadata(record.name, dict(record.metadata))
                    res.metadata += 1
                elif isinstance(record, DataEnd):
                    res.complete = True  # everything after is summary, which the Writer rebuilds
                    break
                elif isinstance(record, Footer):
                    break
        except (McapError, struct.error, EOFError, ValueError, UnicodeDecodeError) as err:
            res.reason = res.reason or f"{type(err).__name__} after offset {res.stopped_at_offset}"
        if not started:
            raise ValueError(f"{src}: not an MCAP file (no complete header)")
        if not res.complete and not res.reason:
            res.reason = "no data-end record"
        out.add_metadata(RECOVER_METADATA, {
            "source": src.name, "complete": str(res.complete).lower(), "reason": res.reason,
            "messages": str(res.messages), "chunks": str(res.chunks),
            "stopped_at_offset": str(res.stopped_at_offset),
        })
        out.finish()
    res.topics = dict(copier.topics)
    return res


def _copy(copier: _Copier, r: object, res: RecoverResult) -> None:
    if isinstance(r, Schema):
        copier.schema(r)
    elif isinstance(r, Channel):
        copier.channel(r)
    elif isinstance(r, Message) and copier.message(r):
        res.messages += 1


def repair_dir() -> Path:
    """``$SEAWAY_REPAIR_DIR`` or ``~/.cache/seaway/recovered``; OSError when neither is known."""
    env = os.environ.get(ENV_REPAIR_DIR)
    if env:
        return Path(env)
    try:
        return Path.home() / ".cache" / "seaway" / "recovered"
    except RuntimeError as err:  # no home known: the caller falls back as for an unwritable one
        raise OSError(f"no folder for repaired copies: {err}; set {ENV_REPAIR_DIR}") from None


def repaired_copy(src: Path) -> Path:
    """A repaired copy of ``src`` as it is now (``recover``), for reading.

    Made in ``repair_dir()`` (never beside ``src``: its folder may be a live run's), named by the
    path, size and modification time of ``src``, under a temporary name and then linked into
    place, so a copy once there never changes: readers at once of the same state share one copy
    or each make their own, and none reads one half-written; a file that grew gets a new copy.
    Copies not made or used for ``REPAIR_KEEP_S`` are removed. Raises ValueError when ``src`` is
    not MCAP, OSError when the cache cannot be written.
    """
    src = Path(src)
    st = src.stat()
    folder = repair_dir() / hashlib.sha256(str(src.resolve()).encode()).hexdigest()[:16]
    folder.mkdir(mode=0o700, parents=True, exist_ok=True)
    fixed = folder / f"{src.stem}.{st.st_size}-{st.st_mtime_ns}.recovered.mcap"
    if fixed.exists():
        os.utime(fixed)  # in use: not pruned under this reader
    else:
        fd, part_name = tempfile.mkstemp(prefix=f".{fixed.name}.", suffix=".part", dir=folder)
        os.close(fd)
        part = Path(part_name)
        try:
            recover(src, part)
            with contextlib.suppress(FileExistsError):  # never replaced: a reader may hold that copy
                os.link(part, fixed)
        finally:
            part.unlink(missing_ok=True)
    _prune_repairs(repair_dir(), fixed)
    return fixed


def _prune_repairs(root: Path, keep: Path) -> None:
    """Remove the copies under ``root`` not made or used for ``REPAIR_KEEP_S`` (but ``keep``), and
    the folders they leave empty."""
    now_s = time.time()

    def stale(p: Path) -> bool:
        return now_s - p.stat().st_mtime > REPAIR_KEEP_S

    for folder in root.iterdir():
        for old in [*folder.glob("*.recovered.mcap"), *folder.glob(".*.part")]:  # a killed reader's
            with contextlib.suppress(OSError):
                if old != keep and stale(old):
                    old.unlink()
        with contextlib.suppress(OSError):
            if folder != keep.parent and stale(folder):  # not one another reader just made
                folder.rmdir()  # only when empty


@dataclass
class Tail:
    """The end of a recording a recorder left (killed): its last log time, and the messages it
    holds from ``since_ns`` on, as (topic, bytes)."""

    last_log_ns: int = 0
    messages: set[tuple[str, bytes]] = field(default_factory=set)


def tail_of(src: Path, since_ns: int) -> Tail:
    """``Tail`` of ``src``, read as far as it is whole (a killed recorder's file has no summary).
    Every chunk is read: a channel is declared in the chunk of its first message."""
    tail = Tail()
    topics: dict[int, str] = {}
    with open(src, "rb") as fin:
        reader = StreamReader(_Tracking(fin), emit_chunks=True, record_size_limit=1 << 31)  # type: ignore[arg-type]
        try:
            for record in reader.records:
                if isinstance(record, Chunk):
                    tail.last_log_ns = max(tail.last_log_ns, record.message_end_time)
                    for r in breakup_chunk(record, validate_crc=True):
                        _note(r, topics, tail, since_ns)
                elif isinstance(record, DataEnd | Footer):
                    break
                else:
                    _note(record, topics, tail, since_ns)
        except (McapError, struct.error, EOFError, ValueError, UnicodeDecodeError):
            pass  # the file ends where the recorder was killed: what came before is the tail
    return tail


def _note(r: object, topics: dict[int, str], tail: Tail, since_ns: int) -> None:
    if isinstance(r, Channel):
        topics[r.id] = r.topic
    elif isinstance(r, Message):
        tail.last_log_ns = max(tail.last_log_ns, r.log_time)
        if r.log_time >= since_ns and r.channel_id in topics:
            tail.messages.add((topics[r.channel_id], bytes(r.data)))
