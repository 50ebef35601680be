"""Reading recordings back: messages in log-time order, attachments, metadata, typed decoding.

A recording is one MCAP file or a rotated series (``recording-000.mcap``, ``-001``, ...): ``open_paths``
takes files or folders and returns the files in order. Attachments and metadata repeat in every file
of a series; the first copy wins.
"""

from __future__ import annotations

import heapq
import io
import struct
import tempfile
import threading
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Attachment,
    AttachmentIndex,
    Channel,
    ChunkIndex,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
)
from mcap.summary import Summary

from seaway.contract import keys
from seaway.contract.keys import KeySpec
from seaway.contract.messages import Message, MessageError
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
from seaway.recording.recover import RECOVER_METADATA, recover, repaired_copy
from seaway.runtime import memory


@dataclass(frozen=True)
class RecordedMessage:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes
    schema_name: str
    message_encoding: str
    channel_metadata: dict[str, str]


@dataclass
class RecordingInfo:
    files: list[Path]
    attachments: dict[str, bytes] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    message_count: int = 0
    start_ns: int = 0
    end_ns: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    recovered: dict[str, dict[str, str]] = field(default_factory=dict)
    """Per repaired copy read (its path): its ``seaway.recover`` metadata (source, reason, ...)."""
    summaries: dict[Path, Summary] = field(default_factory=dict, repr=False)
    """Each file's summary as read here, for ``decode_vessel`` not to read it again."""


MCAP_MAGIC = MAGIC
"""The bytes an MCAP file starts and ends with (the mcap library's)."""


def finished(path: Path) -> bool:
    """Whether an MCAP file ends as a finished one does (a recorder killed mid-write leaves none)."""
    with open(path, "rb") as fh:
        fh.seek(0, 2)
        if fh.tell() < 2 * len(MCAP_MAGIC):
            return False
        fh.seek(-len(MCAP_MAGIC), 2)
        return fh.read() == MCAP_MAGIC


RECOVER_HINT = "`seaway record recover IN OUT` rebuilds what is readable of a cut file"


class UnreadableRecordingError(ValueError):
    """A recording that cannot be read, even through a repaired copy; the text says why and how."""


def readable(path: Path) -> Path:
    """``path``, or for an unfinished file (cut by a crash, or still being written) a repaired copy
    of it as it is now, carrying a ``seaway.recover`` metadata record saying what was kept.

    The copy is never written beside the file (its run folder may be live): ``recover.repaired_copy``
    keeps it in ``recover.repair_dir()``, whole and never rewritten, so several readers at once
    each read a complete copy. When that folder cannot be written the copy goes to a new temporary
    folder.

    Raises ``UnreadableRecordingError`` when nothing can be rebuilt from it.
    """
    path = Path(path)
    if finished(path):
        return path
    try:
        return repaired_copy(path)
    except ValueError as err:  # not an MCAP file at all: nothing to rebuild
        raise UnreadableRecordingError(f"{path}: not finished, and nothing can be rebuilt from it: "
                                       f"{err}") from None
    except OSError:
        pass  # no cache folder to write (a read-only home): a temporary folder instead
    fixed = Path(tempfile.mkdtemp(prefix="seaway-recovered-")) / f"{path.stem}.recovered.mcap"
    try:
        recover(path, fixed)
    except (OSError, ValueError) as err:
        raise UnreadableRecordingError(f"{path}: not finished (cut short by a crash?) and it could not "
                                       f"be repaired: {err}; {RECOVER_HINT}") from None
    return fixed


def open_paths(paths: Iterable[str | Path]) -> list[Path]:
    """Files named, and every ``*.mcap`` in folders named, in name order; raises if none. A file
    that a crash left truncated, or that is still being written, is read through a repaired copy
    (``readable``); ``repaired`` says which were."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            out += [readable(q) for q in sorted(p.glob("*.mcap"))
                    if not q.name.endswith(".recovered.mcap")]
        elif p.is_file():
            out.append(readable(p))
        else:
            raise FileNotFoundError(f"{p}: no such file or folder")
    if not out:
        raise FileNotFoundError("no .mcap files in " + ", ".join(map(str, paths)))
    return out


def repaired(info: RecordingInfo) -> list[str]:
    """One line per file of ``info`` read through a repaired copy: what was cut and what was kept."""
    lines = []
    for name, meta in info.recovered.items():
        kept = f"{int(meta.get('messages', 0)):,} messages kept"
        why = ("the input was complete" if meta.get("complete") == "true"
               else f"it ends early: {meta.get('reason') or 'no data-end record'}")
        lines.append(f"{meta.get('source', '?')} was not finished (its recorder was killed or is "
                     f"still writing): read through the repaired copy {name} ({kept}; {why}); "
                     f"{RECOVER_HINT}")
    return lines


_SUMMARY_RECORDS: dict[int, Any] = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel,
                                     Opcode.STATISTICS: Statistics,
                                     Opcode.ATTACHMENT_INDEX: AttachmentIndex,
                                     Opcode.METADATA_INDEX: MetadataIndex}
"""The summary's other records, read by the mcap library's own record classes."""


def read_summary(fh: Any) -> Summary | None:
    """The summary section of the MCAP file ``fh`` (open for binary reading), as the mcap reader's
    ``get_summary`` gives it; None when the file has none. McapError when it is damaged.

    Why not the reader's: a lockstep recording has a chunk a period, so its summary is mostly
    chunk indexes (18,345 for a study stack's 8 runs), and the reader parsed each field by field in
    Python: 0.29 s a file, read twice for a report. Here a chunk index is one ``struct`` call or two;
    the other records (schemas, channels, statistics, attachment and metadata indexes) are still
    read by the library's classes. The layout is MCAP's (mcap.dev/spec: Footer, Chunk Index)."""
    fh.seek(0, 2)
    size = fh.tell()
    tail = FOOTER.size + len(MCAP_MAGIC)
    if size < tail + len(MCAP_MAGIC):
        raise McapError("too short to have a footer")
    fh.seek(size - tail)
    op, _, summary_start, _, _ = FOOTER.unpack(fh.read(FOOTER.size))
    if op != Opcode.FOOTER:
        raise McapError(f"expected a footer at byte {size - tail}, found opcode {op:#x}")
    if summary_start == 0:
        return None
    fh.seek(summary_start)
    data = fh.read(size - tail - summary_start)
    summary = Summary()
    pos = 0
    try:
        while pos < len(data):
            op, length = RECORD_HEAD.unpack_from(data, pos)
            body, pos = pos + RECORD_HEAD.size, pos + RECORD_HEAD.size + length
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


def _indexed_record(fh: Any, offset: int, length: int, kind: Any) -> Any:
    """The Attachment or Metadata record an index points at, read by the library's class."""
    fh.seek(offset)
    return kind.read(ReadDataStream(io.BytesIO(fh.read(length)[RECORD_HEAD.size:])))


def read_info(files: list[Path]) -> RecordingInfo:
    info = RecordingInfo(files=list(files))
    starts, ends = [], []
    for f in files:
        with open(f, "rb") as fh:
            try:
                summary = read_summary(fh)
            except McapError as err:
                raise UnreadableRecordingError(f"{f}: cannot read its summary ({type(err).__name__}: "
                                          f"{err}); {RECOVER_HINT}") from None
            if summary is None or summary.statistics is None:
                raise UnreadableRecordingError(f"{f}: no summary (not finished?); {RECOVER_HINT}")
            info.summaries[f] = summary
            for ai in summary.attachment_indexes:
                a = _indexed_record(fh, ai.offset, ai.length, Attachment)
                info.attachments.setdefault(a.name, bytes(a.data))
            for mi in summary.metadata_indexes:
                m = _indexed_record(fh, mi.offset, mi.length, Metadata)
                info.metadata.setdefault(m.name, dict(m.metadata))
                if m.name == RECOVER_METADATA:
                    info.recovered[str(f)] = dict(m.metadata)
            st = summary.statistics
            info.message_count += st.message_count
            if st.message_count:
                starts.append(st.message_start_time)
                ends.append(st.message_end_time)
            for cid, n in st.channel_message_counts.items():
                topic = summary.channels[cid].topic
                info.topics[topic] = info.topics.get(topic, 0) + n
    info.start_ns = min(starts, default=0)
    info.end_ns = max(ends, default=0)
    return info


def _iter_file(path: Path, topics: list[str] | None) -> Iterator[RecordedMessage]:
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        for schema, channel, msg in reader.iter_messages(topics=topics, log_time_order=True):
            yield RecordedMessage(channel.topic, msg.log_time, msg.publish_time, msg.sequence,
                                  bytes(msg.data), schema.name if schema else "",
                                  channel.message_encoding, dict(channel.metadata))


def iter_messages(files: list[Path], topics: list[str] | None = None) -> Iterator[RecordedMessage]:
    """Every message of the files in log-time order (merged across a rotated series)."""
    streams = [_iter_file(f, topics) for f in files]
    yield from heapq.merge(*streams, key=lambda m: m.log_time_ns)


@dataclass
class Decoded:
    """Typed bus messages by key suffix (``sim/truth``), each list in log-time order, with their
    log times (``log_ns``, the same order)."""

    by_suffix: dict[str, list[Message]] = field(default_factory=dict)
    log_ns: dict[str, list[int]] = field(default_factory=dict)
    vessels: set[str] = field(default_factory=set)
    undecodable: int = 0
    duplicates: int = 0
    """Messages recorded twice (the same bytes on the same topic): a lockstep period repeated for a
    restarted recorder can sit in the file it left and in the one it started. Read once."""

    def get(self, suffix: str) -> list[Message]:
        return self.by_suffix.get(suffix, [])

    def between(self, start_ns: int, end_ns: int | None) -> Decoded:
        """The messages logged in [start_ns, end_ns) (to the end if None)."""
        out = Decoded(vessels=set(self.vessels), undecodable=self.undecodable,
                      duplicates=self.duplicates)
        for suffix, msgs in self.by_suffix.items():
            logs = self.log_ns[suffix]
            keep = [i for i, t in enumerate(logs) if t >= start_ns and (end_ns is None or t < end_ns)]
            out.by_suffix[suffix] = [msgs[i] for i in keep]
            out.log_ns[suffix] = [logs[i] for i in keep]
        return out


def _wanted_topics(summary: Summary | None, wanted: set[str] | None, vessels: set[str]
                   ) -> set[str] | None:
    """The topics of a file worth reading (registered, typed, and of a ``wanted`` suffix when there
    are some), noting in ``vessels`` the vessel of every registered topic with messages; None when
    the file has no summary to tell (read everything)."""
    if summary is None or summary.statistics is None or not summary.chunk_indexes:
        return None
    out: set[str] = set()
    counts = summary.statistics.channel_message_counts
    for cid, channel in summary.channels.items():
        spec = keys.spec_for_key(channel.topic)
        if spec is None or spec.message is None or not counts.get(cid):
            continue
        vessels.add(channel.topic.split("/", 2)[1])
        if wanted is None or spec.suffix in wanted:
            out.add(channel.topic)
    return out


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

    Why: a lockstep recorder ends a chunk every period, some 20 messages of every topic each, and
    the mcap reader parses all of them field by field in Python to hand on the few wanted, most of
    a report's decode. Here a chunk
    whose index names none of ``channel_ids`` is not read, and a message on another channel is
    skipped by its length. The layout is MCAP's (mcap.dev/spec: Chunk, Message records). A chunk
    written without message indexes says nothing of its channels: it is read, as the reader does."""
    for ci in sorted(chunk_indexes, key=lambda c: c.chunk_start_offset):
        if ci.message_index_offsets and channel_ids.isdisjoint(ci.message_index_offsets):
            continue
        try:
            found = _chunk_records(fh, ci, channel_ids)
        except Exception as err:  # struct, decompression, text: a damaged chunk, said where
            raise McapError(f"the chunk at byte {ci.chunk_start_offset} is damaged "
                            f"({type(err).__name__}: {err})") from None
        yield from found


def _chunk_records(fh: Any, ci: ChunkIndex, channel_ids: set[int]) -> list[tuple[int, int, bytes]]:
    """One chunk's messages on ``channel_ids`` (``chunked_messages``)."""
    fh.seek(ci.chunk_start_offset)
    rec = fh.read(ci.chunk_length)
    op, _ = RECORD_HEAD.unpack_from(rec, 0)
    if op != Opcode.CHUNK:
        raise McapError(f"opcode {op:#x}, not a chunk's")
    _, _, size, _ = CHUNK_HEAD.unpack_from(rec, RECORD_HEAD.size)
    pos = RECORD_HEAD.size + CHUNK_HEAD.size
    (n,) = U32.unpack_from(rec, pos)
    compression = rec[pos + 4:pos + 4 + n].decode()
    pos += 4 + n
    (records_len,) = U64.unpack_from(rec, pos)
    data = _decompress(compression, rec[pos + 8:pos + 8 + records_len], size)
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


def _file_messages(fh: Any, summary: Summary | None, topics: set[str] | None
                   ) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of the file's messages on ``topics`` (None: all), in file order.
    UnreadableRecordingError, naming the file and the way to repair it, where it is damaged."""
    try:
        if summary is not None and summary.chunk_indexes and topics is not None:
            ids = {cid: ch.topic for cid, ch in summary.channels.items() if ch.topic in topics}
            for cid, log_ns, data in chunked_messages(fh, summary.chunk_indexes, set(ids)):
                yield ids[cid], log_ns, data
            return
        reader = make_reader(fh)
        for _schema, channel, msg in reader.iter_messages(topics=topics, log_time_order=False):
            yield channel.topic, msg.log_time, bytes(msg.data)
    except McapError as err:
        raise UnreadableRecordingError(f"{getattr(fh, 'name', 'the recording')}: {err}; "
                                       f"{RECOVER_HINT}") from None


def decode_vessel(files: list[Path], vessel: str | None = None,
                  suffixes: Iterable[str] | None = None,
                  summaries: dict[Path, Summary] | None = None) -> Decoded:
    """Decode the registered topics of one vessel (the only one, or the one named), all of them or
    only those whose key ends in one of ``suffixes`` (``sim/truth``). ``summaries``: the files'
    summaries already read (``RecordingInfo.summaries``); the others are read here.

    Each file is read in file order and only for the topics wanted (the chunks' index says where
    they are), then each key's messages are put in log-time order: a stable sort, so messages logged
    at the same time stay in file order, and a rotated series in name order, as a merge of the
    files in log-time order gives (``iter_messages``), without merging every topic through the
    reader's ordering heap, which would be most of a report's time."""
    out = Decoded()
    wanted = None if suffixes is None else set(suffixes)
    # suffix -> [(log time, topic, bytes)] in file order, files in name order
    raw: dict[str, list[tuple[int, str, bytes]]] = {}
    specs: dict[str, KeySpec | None] = {}
    into: dict[str, list[tuple[int, str, bytes]] | None] = {}
    """topic -> its list in ``raw``; None: a topic not decoded (not a message, not wanted)."""
    # Tens of thousands of messages and their bytes kept, with no cycles among them: the collector
    # would walk them all again every few hundred (seaway.runtime.memory.collection_paused).
    with memory.collection_paused():
        for path in files:
            with open(path, "rb") as fh:
                try:
                    summary = (summaries or {}).get(path) or read_summary(fh)
                except McapError as err:
                    raise UnreadableRecordingError(f"{path}: cannot read its summary ({err}); "
                                                   f"{RECOVER_HINT}") from None
                topics = _wanted_topics(summary, wanted, out.vessels)
                if topics is not None and not topics:
                    continue
                for topic, log_ns, data in _file_messages(fh, summary, topics):
                    if topic not in into:  # where a topic's messages go, found once per topic
                        spec = specs[topic] = keys.spec_for_key(topic)
                        into[topic] = None
                        if spec is not None and spec.message is not None:
                            v = topic.split("/", 2)[1]
                            out.vessels.add(v)
                            if ((wanted is None or spec.suffix in wanted)
                                    and (vessel is None or v == vessel)):
                                into[topic] = raw.setdefault(spec.suffix, [])
                    kept = into[topic]
                    if kept is not None:
                        kept.append((log_ns, topic, data))
        into.clear()  # ``raw`` alone holds the bytes: each key's are freed once decoded
        _decode_raw(raw, specs, len(files) > 1, out)
    if vessel is None and len(out.vessels) > 1:
        raise ValueError(f"the recording has several vessels ({', '.join(sorted(out.vessels))}): "
                         "choose one with --vessel")
    return out


def _decode_raw(raw: dict[str, list[tuple[int, str, bytes]]], specs: dict[str, KeySpec | None],
                several_files: bool, out: Decoded) -> None:
    """``raw``'s messages (suffix -> [(log time, topic, bytes)]) decoded into ``out``, each key's in
    log-time order, and taken out of ``raw``; a message met again in another file is counted in
    ``out.duplicates``, not kept."""
    seen: set[tuple[str, int]] = set()
    for suffix in list(raw):
        items = raw.pop(suffix)  # its bytes freed once decoded: one key's at a time held twice
        items.sort(key=lambda item: item[0])  # stable: ties keep file order
        message = specs[items[0][1]].message  # type: ignore[union-attr]  # one suffix, one type
        msgs: list[Message] = []
        logs: list[int] = []
        for log_ns, topic, data in items:
            if several_files:
                ident = (topic, hash(data))
                if ident in seen:
                    out.duplicates += 1
                    continue
                seen.add(ident)
            try:
                msgs.append(message.decode(data))
            except MessageError:
                out.undecodable += 1
                continue
            logs.append(log_ns)
        if msgs:
            out.by_suffix[suffix] = msgs
            out.log_ns[suffix] = logs
