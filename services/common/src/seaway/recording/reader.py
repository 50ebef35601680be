"""Reading recordings back: messages in log-time order, attachments, metadata, typed decoding.

A recording is one MCAP file or a rotated series (``recording-000.mcap``, ``-001``, ...): ``open_paths``
takes files or folders and returns the files in order. Attachments and metadata repeat in every file
of a series; the first copy wins. A file that is damaged (a chunk whose bytes do not match its CRC
or do not decompress, several recordings joined) is refused with ``UnreadableRecordingError``
naming it and what is wrong. ``read_summary`` and ``chunked_messages`` are ``seaway.recording.chunks``'s.
"""

from __future__ import annotations

import heapq
import io
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Attachment, Channel, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.summary import Summary

from seaway.contract import keys
from seaway.contract.keys import KeySpec
from seaway.contract.messages import Message, MessageError
from seaway.recording.chunks import (
    JoinedRecordingsError,
    chunked_messages,
    first_damaged_chunk,
    read_summary,
)
from seaway.recording.layout import MAGIC, RECORD_HEAD
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


class Attachments(Mapping[str, bytes]):
    """A recording's attachments by name (the first copy in a series), each read from its file when
    looked up: a report or a listing reads the few small documents it needs, not every attachment
    (a scenario's data or a configuration can be hundreds of MB)."""

    def __init__(self) -> None:
        self._where: dict[str, tuple[Path, int, int]] = {}
        self.size_bytes: dict[str, int] = {}
        """Each attachment's data size [bytes], from its index (nothing read)."""

    def add(self, name: str, path: Path, offset: int, length: int, size_bytes: int) -> None:
        """The attachment record at ``offset`` of ``path``, unless one of that name came first."""
        if name not in self._where:
            self._where[name] = (path, offset, length)
            self.size_bytes[name] = size_bytes

    def __getitem__(self, name: str) -> bytes:
        path, offset, length = self._where[name]
        with open(path, "rb") as fh:
            return bytes(_indexed_record(fh, offset, length, Attachment).data)

    def __iter__(self) -> Iterator[str]:
        return iter(self._where)

    def __len__(self) -> int:
        return len(self._where)


@dataclass
class RecordingInfo:
    files: list[Path]
    attachments: Attachments = field(default_factory=Attachments)
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


RECOVER_HINT = "`seaway record recover IN OUT` rebuilds what is readable of a cut or damaged file"


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
    """Files named, and every ``*.mcap`` file in folders named, in name order; raises if none. A
    file that a crash left truncated, or that is still being written, is read through a repaired
    copy (``readable``); ``repaired`` says which were."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():  # a sub-folder named *.mcap is not a recording
            out += [readable(q) for q in sorted(p.glob("*.mcap"))
                    if q.is_file() and not q.name.endswith(".recovered.mcap")]
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
               else f"not all of it was kept: {meta.get('reason') or 'no data-end record'}")
        lines.append(f"{meta.get('source', '?')} was not finished (its recorder was killed or is "
                     f"still writing): read through the repaired copy {name} ({kept}; {why}); "
                     f"{RECOVER_HINT}")
    return lines


def _indexed_record(fh: Any, offset: int, length: int, kind: Any) -> Any:
    """The Attachment or Metadata record an index points at, read by the library's class."""
    fh.seek(offset)
    return kind.read(ReadDataStream(io.BytesIO(fh.read(length)[RECORD_HEAD.size:])))


JOINED_HINT = ("`seaway record recover IN OUT` copies the recordings it holds into one file, one "
               "after another")


def summary_of(path: Path, fh: Any) -> Summary | None:
    """``read_summary`` of the file ``path`` open as ``fh``; UnreadableRecordingError naming the
    file, what is wrong and how to repair it where it cannot be read."""
    try:
        return read_summary(fh)
    except JoinedRecordingsError as err:
        raise UnreadableRecordingError(f"{path}: {err}; its summary describes one of them at most, "
                                       f"so it is not read; {JOINED_HINT}") from None
    except McapError as err:
        raise UnreadableRecordingError(f"{path}: cannot read its summary ({type(err).__name__}: "
                                       f"{err}); {RECOVER_HINT}") from None


def read_info(files: list[Path]) -> RecordingInfo:
    info = RecordingInfo(files=list(files))
    starts, ends = [], []
    for f in files:
        with open(f, "rb") as fh:
            summary = summary_of(f, fh)
            if summary is None or summary.statistics is None:
                raise UnreadableRecordingError(f"{f}: no summary (not finished?); {RECOVER_HINT}")
            info.summaries[f] = summary
            for ai in summary.attachment_indexes:
                info.attachments.add(ai.name, f, ai.offset, ai.length, ai.data_size)
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


def iter_file_records(path: Path, topics: Iterable[str] | None = None, log_time_order: bool = True
                      ) -> Iterator[tuple[Schema | None, Channel, McapMessage]]:
    """The mcap reader's ``iter_messages`` of the file ``path``, each chunk checked against its CRC.
    UnreadableRecordingError, naming the file, the damaged chunk (the byte it starts at) when it is
    one, and the way to repair it, where the file cannot be read: whatever the library or its
    decompressors raise is said so, not passed on as their own error."""
    with open(path, "rb") as fh:
        try:
            yield from make_reader(fh, validate_crcs=True).iter_messages(
                topics=None if topics is None else list(topics), log_time_order=log_time_order)
        except Exception as err:  # McapError, zstd, lz4, struct, CRC (a ValueError): damage
            raise _unreadable(path, fh, err) from None


def _unreadable(path: Path | str, fh: Any, err: Exception) -> UnreadableRecordingError:
    """What is wrong with the file ``path`` (open as ``fh``) whose reading raised ``err``: the first
    damaged chunk's error where the summary indexes one, else ``err``."""
    found: Exception | None = None
    try:
        summary = read_summary(fh)
        if summary is not None:
            found = first_damaged_chunk(fh, summary.chunk_indexes)
    except McapError as summary_err:
        found = summary_err
    why = found or f"a record cannot be read ({type(err).__name__}{f': {err}' if str(err) else ''})"
    return UnreadableRecordingError(f"{path}: {why}; {RECOVER_HINT}")


def _iter_file(path: Path, topics: list[str] | None) -> Iterator[RecordedMessage]:
    for schema, channel, msg in iter_file_records(path, topics):
        yield RecordedMessage(channel.topic, msg.log_time, msg.publish_time, msg.sequence,
                              bytes(msg.data), schema.name if schema else "",
                              channel.message_encoding, dict(channel.metadata))


def iter_messages(files: list[Path], topics: list[str] | None = None) -> Iterator[RecordedMessage]:
    """Every message of the files in log-time order (merged across a rotated series).
    UnreadableRecordingError where a file is damaged (``iter_file_records``), once the messages
    before it have been yielded."""
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
    undecodable_by_topic: dict[str, int] = field(default_factory=dict)
    """Of ``undecodable``, how many on each topic: what a reader of the messages should be told
    it does not have."""
    duplicates: int = 0
    """Messages recorded twice (the same bytes on the same topic): a lockstep period repeated for a
    restarted recorder can sit in the file it left and in the one it started. Read once."""
    clock_steps: list[tuple[int, int, bool]] = field(default_factory=list)
    """(seen at [ns, the new clock], step [ns], bridged) for each step of the wall clock the
    recorder said: a bridged one's earlier wall times were moved on by it
    (``seaway_recorder.clock_bridge``)."""

    def get(self, suffix: str) -> list[Message]:
        return self.by_suffix.get(suffix, [])

    def between(self, start_ns: int, end_ns: int | None) -> Decoded:
        """The messages logged in [start_ns, end_ns) (to the end if None)."""
        out = Decoded(vessels=set(self.vessels), undecodable=self.undecodable,
                      undecodable_by_topic=dict(self.undecodable_by_topic),
                      duplicates=self.duplicates, clock_steps=list(self.clock_steps))
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


def _file_messages(fh: Any, summary: Summary | None, topics: set[str] | None
                   ) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of the file's messages on ``topics`` (None: all), in file order.
    UnreadableRecordingError, naming the file and the way to repair it, where it is damaged."""
    name = getattr(fh, "name", "the recording")
    if summary is not None and summary.chunk_indexes and topics is not None:
        ids = {cid: ch.topic for cid, ch in summary.channels.items() if ch.topic in topics}
        try:
            for cid, log_ns, data in chunked_messages(fh, summary.chunk_indexes, set(ids)):
                yield ids[cid], log_ns, data
        except McapError as err:  # it names the chunk
            raise UnreadableRecordingError(f"{name}: {err}; {RECOVER_HINT}") from None
        return
    try:
        reader = make_reader(fh, validate_crcs=True)
        for _schema, channel, msg in reader.iter_messages(topics=topics, log_time_order=False):
            yield channel.topic, msg.log_time, bytes(msg.data)
    except Exception as err:  # McapError, zstd, lz4, struct, CRC (a ValueError): damage
        raise _unreadable(name, fh, err) from None


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
                summary = (summaries or {}).get(path) or summary_of(path, fh)
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
                out.undecodable_by_topic[topic] = out.undecodable_by_topic.get(topic, 0) + 1
                continue
            logs.append(log_ns)
        if msgs:
            out.by_suffix[suffix] = msgs
            out.log_ns[suffix] = logs
