"""Rebuild a fully indexed MCAP file from a truncated or damaged one (a recorder killed with
SIGKILL, a disk error).

The file is read record by record from the start. Every complete record is kept: the header,
attachments, metadata, and each chunk whose bytes decompress and match its CRC (its schemas,
channels and messages). A chunk that does not is skipped by its length (its start is noted) and
the copy goes on; the first record that is cut short or unreadable ends the data. A file holding
several recordings one after another (files joined) has each copied in turn into the one output.
The kept records are written again through the mcap Writer, which adds the chunk and message
indexes, the statistics and the summary. Message times, sequence numbers, channel topics and
metadata and schema bytes are kept unchanged; schema and channel ids may be renumbered.

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
from mcap.summary import Summary
from mcap.writer import CompressionType, Writer

from seaway.recording.chunks import next_recording, read_summary
from seaway.recording.layout import MAGIC
from seaway.runtime.private import open_private

RECOVER_METADATA = "seaway.recover"
ENV_REPAIR_DIR = "SEAWAY_REPAIR_DIR"
"""Where readers keep repaired copies of unfinished files (default ``~/.cache/seaway/recovered``)."""
REPAIR_KEEP_S = 600.0
"""A repaired copy not made or used for this long is removed [s] (a reader that opened it has long
finished; the next reader makes it again)."""
_NAMED_CHUNKS = 5
"""Damaged chunks the reason names one by one; the metadata lists every one."""


@dataclass
class RecoverResult:
    messages: int = 0
    chunks: int = 0
    attachments: int = 0
    metadata: int = 0
    bad_chunks: int = 0
    bad_chunk_offsets: list[int] = field(default_factory=list)
    """Where each damaged chunk skipped starts [byte in the input]."""
    recordings: int = 0
    """Recordings found in the input: more than one where files were joined one after another."""
    complete: bool = False
    """Every record of the input kept: each recording read to its data end, no chunk skipped."""
    stopped_at_offset: int = 0
    reason: str = ""
    topics: dict[str, int] = field(default_factory=dict)

    def line(self) -> str:
        tail = (f"the input was complete{'; ' + self.reason if self.reason else ''}" if self.complete
                else f"not all of the input was kept: {self.reason}")
        return (f"recovered {self.messages:,} messages in {self.chunks} chunks, "
                f"{self.attachments} attachments, {self.metadata} metadata; {tail}")


class _Copier:
    """Schemas, channels and messages of the input into ``out``, the input's ids mapped to the
    output's; ``known``: the input's summary, for a channel whose record was in a damaged chunk."""

    def __init__(self, out: Writer, known: Summary | None) -> None:
        self.out = out
        self.known = known
        self.started = False
        """Whether ``out`` has its header: the input's first recording's."""
        self.schema_ids: dict[int, int] = {}
        self.channel_ids: dict[int, int] = {}
        self.topic_of: dict[int, str] = {}
        self.topics: dict[str, int] = {}
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._channels: dict[tuple[str, str, int, tuple[tuple[str, str], ...]], int] = {}

    def next_recording(self) -> None:
        """Another recording of the input from here on: its ids are its own."""
        self.schema_ids.clear()
        self.channel_ids.clear()
        self.topic_of.clear()
        self.known = None

    def schema(self, s: Schema) -> None:
        if s.id not in self.schema_ids:
            key = (s.name, s.encoding, bytes(s.data))
            if key not in self._schemas:  # a joined file's next recording: the same output schema
                self._schemas[key] = self.out.register_schema(s.name, s.encoding, s.data)
            self.schema_ids[s.id] = self._schemas[key]

    def channel(self, c: Channel) -> None:
        if c.id not in self.channel_ids:
            if c.schema_id and c.schema_id not in self.schema_ids and self.known is not None \
                    and c.schema_id in self.known.schemas:
                self.schema(self.known.schemas[c.schema_id])
            sid = self.schema_ids.get(c.schema_id, 0) if c.schema_id else 0
            key = (c.topic, c.message_encoding, sid, tuple(sorted(c.metadata.items())))
            if key not in self._channels:
                self._channels[key] = self.out.register_channel(c.topic, c.message_encoding, sid,
                                                                dict(c.metadata))
            self.channel_ids[c.id] = self._channels[key]
            self.topic_of[c.id] = c.topic

    def message(self, m: Message) -> bool:
        if m.channel_id not in self.channel_ids and self.known is not None \
                and m.channel_id in self.known.channels:  # declared in a chunk skipped
            self.channel(self.known.channels[m.channel_id])
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


def _known(src: Path) -> Summary | None:
    """The summary of ``src`` where it has a readable one (a finished file), else None."""
    try:
        with open(src, "rb") as fh:
            fh.seek(0, 2)
            if fh.tell() < 2 * len(MAGIC):
                return None
            fh.seek(-len(MAGIC), 2)
            if fh.read() != MAGIC:  # cut: no footer to look for
                return None
            return read_summary(fh)
    except (McapError, OSError):
        return None


def recover(src: Path, dst: Path, compression: CompressionType = CompressionType.ZSTD,
            chunk_size: int = 4 * 1024 * 1024) -> RecoverResult:
    """Copy every complete record of ``src`` into a new, fully indexed ``dst`` (module docstring);
    what was kept and skipped goes into ``dst``'s ``seaway.recover`` metadata too."""
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise ValueError("recover writes a new file: OUT must differ from IN")
    res = RecoverResult()
    bad: list[str] = []
    ends: list[str] = []
    with open(src, "rb") as fin, open_private(dst) as fout:
        out = Writer(fout, chunk_size=chunk_size, compression=compression)
        copier = _Copier(out, _known(src))
        at: int | None = 0
        all_ended = True
        while at is not None:
            if res.recordings:
                copier.next_recording()
            res.recordings += 1
            ended, at = _copy_recording(fin, at, out, copier, res, bad, ends)
            all_ended = all_ended and ended
        if not copier.started:
            raise ValueError(f"{src}: not an MCAP file (no complete header)")
        res.complete = all_ended and not res.bad_chunks
        res.reason = _reason(res, bad, ends)
        out.add_metadata(RECOVER_METADATA, {
            "source": src.name, "complete": str(res.complete).lower(), "reason": res.reason,
            "messages": str(res.messages), "chunks": str(res.chunks),
            "stopped_at_offset": str(res.stopped_at_offset), "recordings": str(res.recordings),
            "bad_chunks": str(res.bad_chunks),
            "bad_chunk_offsets": ",".join(map(str, res.bad_chunk_offsets)),
        })
        out.finish()
    res.topics = dict(copier.topics)
    return res


def _copy_recording(fin: BinaryIO, at: int, out: Writer, copier: _Copier, res: RecoverResult,
                    bad: list[str], ends: list[str]) -> tuple[bool, int | None]:
    """Copy the recording starting at byte ``at`` of ``fin`` (its magic) into ``out``, noting in
    ``bad`` each damaged chunk skipped and in ``ends`` how it ended where not at its data end.
    Returns whether it was read to its data end, and where a next recording starts (None: none)."""
    fin.seek(at)
    tracked = _Tracking(fin)
    reader = StreamReader(tracked, emit_chunks=True, record_size_limit=1 << 31)  # type: ignore[arg-type]
    start = at + len(MAGIC)  # the record being read starts here [byte]
    try:
        for record in reader.records:
            end = tracked.tell()
            if isinstance(record, Header):
                if not copier.started:  # a joined file's next recording: the output has its own
                    out.start(profile=record.profile, library=record.library)
                    copier.started = True
            elif not copier.started:
                raise McapError("no header record")
            elif isinstance(record, Chunk):
                try:
                    inner = breakup_chunk(record, validate_crc=True)
                except Exception as err:  # corrupt compressed data or CRC mismatch
                    # A chunk cut short where another recording starts: this one ends there.
                    if (nxt := next_recording(fin, start + 1, end)) is not None:
                        ends.append(f"the chunk at byte {start} is cut short by another recording")
                        return False, nxt
                    fin.seek(end)  # its length is whole: on after it
                    res.bad_chunks += 1
                    res.bad_chunk_offsets.append(start)
                    bad.append(f"the chunk at byte {start} ({type(err).__name__}: {err})")
                    start = res.stopped_at_offset = end
                    continue
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
                # Everything after is summary, which the Writer rebuilds; then maybe another
                # recording (files joined).
                res.stopped_at_offset = end
                return True, next_recording(fin, end)
            elif isinstance(record, Footer):
                break
            start = res.stopped_at_offset = end
    except (McapError, struct.error, EOFError, ValueError, UnicodeDecodeError) as err:
        if not copier.started:
            return False, None
        ends.append(f"{type(err).__name__} in the record at byte {start}: {err}")
        return False, next_recording(fin, max(start, at + 1))
    ends.append(f"no data end record before byte {res.stopped_at_offset}")
    return False, next_recording(fin, max(res.stopped_at_offset, at + 1))


def _copy(copier: _Copier, r: object, res: RecoverResult) -> None:
    if isinstance(r, Schema):
        copier.schema(r)
    elif isinstance(r, Channel):
        copier.channel(r)
    elif isinstance(r, Message) and copier.message(r):
        res.messages += 1


def _reason(res: RecoverResult, bad: list[str], ends: list[str]) -> str:
    """What ``recover`` did not keep, and why: the damaged chunks skipped (their starts), how the
    data ended early, and how many recordings the input held; empty when it kept everything."""
    parts = []
    if bad:
        more = len(bad) - _NAMED_CHUNKS
        parts.append(f"skipped {len(bad)} damaged chunk(s): " + "; ".join(bad[:_NAMED_CHUNKS])
                     + (f"; and {more} more (metadata bad_chunk_offsets)" if more > 0 else ""))
    parts += ends
    if res.recordings > 1:
        parts.append(f"the input holds {res.recordings} recordings one after another (files "
                     "joined): each was copied in turn")
    return "; ".join(parts)
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
