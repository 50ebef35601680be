"""The recorder's core: bus samples in, MCAP files out. No Zenoh here; time is passed in.

``RecordingWriter.write(key, payload, encoding, receive_ns)`` stores the payload's bytes unchanged on
the key's channel (with the key's JSON Schema), after checking that they decode as the key's message
type, at the log time the recording's time convention gives (``timebase.RecordingTime``: the receive
time in real time, the sim time on the run's epoch in lockstep). Bytes that do not decode go,
unchanged, to ``recorder/malformed`` inside an envelope that says why, and are counted. Derived
Foxglove channels (``derive.py``) are written next to their source, at its log time; ``write_log``
and ``write_event`` add the run's log lines and the launcher's events.

``flush()`` ends the chunk in progress and writes it with its message indexes;
the recorder's loop calls it at least every flush interval, which bounds what a SIGKILL can lose.
A disk with no room fails a ``flush``, an ``open`` or a ``close`` (``seaway.runtime.disk.disk_full``) without
changing what is on disk or in hand: each can be called again once there is room (``resume``).
``close()`` writes the summary (statistics, chunk/attachment/metadata indexes) so the file is fully
indexed. Rotation (``max_bytes``, ``max_seconds``) closes a file the same way and opens the next,
numbered one; every file carries the attachments and run metadata again, so each stands alone.
"""

from __future__ import annotations

import json
import logging
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from seaway.contract import bundle
from seaway.contract.messages import MessageError, PeriodDone
from seaway.recording.timebase import EPISODE_METADATA, TIME_METADATA, RecordingTime, stamp_of
from seaway.runtime.private import private_folder
from seaway.runtime.ratelog import RateLimitedLog
from seaway.tools.launch.events import ProcessEvent
from seaway.vessel.frames import GeoOrigin

from seaway_recorder import derive, schemas
from seaway_recorder.logtail import LogLine
from seaway_recorder.mcapfile import check_compression
from seaway_recorder.openfile import OpenFile, free_path

log = logging.getLogger("seaway.recorder")

SUMMARY_METADATA = "seaway.recorder.summary"
RUN_METADATA = "seaway.run"


@dataclass(frozen=True)
class AttachmentSpec:
    """A file stored in every recording: ``name`` is ``<role>/<file name>`` (``scenario/paper-c1.toml``)."""

    name: str
    media_type: str
    data: bytes
    create_time_ns: int = 0


@dataclass
class RecorderStats:
    """What the recorder has done; printed as it goes and stored in each file's summary metadata."""

    messages: int = 0
    bytes: int = 0
    malformed: int = 0
    unregistered: int = 0
    derived: int = 0
    underived: int = 0
    """Messages recorded whose Foxglove view could not be derived (e.g. a stamp past 2106)."""
    events: int = 0
    logs: int = 0
    dropped: int = 0
    flushes: int = 0
    lost_files: int = 0
    """Files deleted, replaced or truncated by someone else while being written: what they held
    is gone; the recording went on in a new file."""
    no_room: int = 0
    """Times the disk had no room for the recording: the recorder waited for room each time."""
    no_room_s: float = 0.0
    """Time spent waiting for room on the disk [s]."""
    files: list[str] = field(default_factory=list)
    by_topic: Counter[str] = field(default_factory=Counter)
    last_error: str = ""

    def as_metadata(self) -> dict[str, str]:
        out = {k: str(getattr(self, k)) for k in
               ("messages", "bytes", "malformed", "unregistered", "derived", "underived", "events",
                "logs", "dropped", "flushes", "lost_files", "no_room")}
        out["no_room_s"] = f"{self.no_room_s:.3f}"
        out["last_error"] = self.last_error
        return out

    def line(self) -> str:
        return (f"messages {self.messages:,}, bytes {self.bytes:,}, malformed {self.malformed:,}, "
                f"dropped {self.dropped:,}, unregistered {self.unregistered:,}, "
                f"derived {self.derived:,}, files {len(self.files)}")


def media_type_for(path: Path) -> str:
    return {".toml": "application/toml", ".json": "application/json", ".json5": "application/json5",
            ".yaml": "application/yaml", ".yml": "application/yaml", ".txt": "text/plain",
            ".csv": "text/csv"}.get(path.suffix.lower(), "application/octet-stream")


class RecordingWriter:
    """Writes bus samples to one MCAP file, or a numbered series when rotating."""

    def __init__(
        self,
        path: Path,
        *,
        chunk_size: int = 4 * 1024 * 1024,
        compression: str = "zstd",
        max_bytes: int | None = None,
        max_seconds: float | None = None,
        attachments: list[AttachmentSpec] | None = None,
        metadata: dict[str, dict[str, str]] | None = None,
        validate: bool = True,
        foxglove: bool = True,
        default_origin: GeoOrigin | None = None,
        time: RecordingTime | None = None,
        durable: bool = False,
    ) -> None:
        check_compression(compression)
        self.base = Path(path)
        self.rotating = bool(max_bytes or max_seconds)
        self.chunk_size = chunk_size
        self.compression = compression
        self.max_bytes = max_bytes
        self.max_seconds = max_seconds
        self.attachments = list(attachments or [])
        self.metadata = dict(metadata or {})
        self.validate = validate
        self.durable = durable
        """Each file synced to the disk as it is closed (the recorder's ``--sync-interval`` on)."""
        self.stats = RecorderStats()
        self.time = time or RecordingTime.real_time()
        self._deriver = (derive.FoxgloveDeriver(default_origin, self.time.foxglove_ns) if foxglove
                         else None)
        self._derived_sources = {s.suffix for s in derive.FoxgloveDeriver.SOURCES}
        self._file: OpenFile | None = None
        self._open_failed: OSError | None = None
        """Why the last ``open`` failed (a full disk): ``flush`` says it again until a file opens."""
        self._file_index = 0
        self._file_opened_ns = 0
        self._channel_specs: dict[str, tuple[schemas.ChannelSpec, bool]] = {}
        """Per key: its channel, and whether ``FoxgloveDeriver`` derives channels from it
        (``SOURCES``)."""
        self._ratelog = RateLimitedLog(log)  # a flood of malformed samples: counted, not echoed
        self._events_spec = schemas.events_channel()

    # -- files ------------------------------------------------------------------------------

    def _next_path(self) -> Path:
        path = (self.base if not self.rotating else
                self.base.with_name(f"{self.base.stem}-{self._file_index:03d}{self.base.suffix}"))
        return free_path(path)

    def open(self, now_ns: int) -> Path:
        """Open the next file and write the attachments and run metadata into it."""
        path = self._next_path()
        if not path.parent.is_dir():  # a folder of its own (a run folder given may be shared)
            private_folder(path.parent)
        f = OpenFile(path, self.chunk_size, self.compression)
        try:
            for a in self.attachments:
                f.writer.add_attachment(a.create_time_ns, now_ns, a.name, a.media_type, a.data)
            for name, data in self.metadata.items():
                meta = dict(data)
                if name == RUN_METADATA and self.rotating:
                    meta["file_index"] = str(self._file_index)
                f.writer.add_metadata(name, meta)
            f.writer.add_metadata(TIME_METADATA, self.time.metadata())
            f.writer.flush()
        except BaseException as err:  # no room for its start (a full disk): no file, until ``resume``
            f.abandon()
            self._open_failed = err if isinstance(err, OSError) else None
            raise
        self._open_failed = None
        self._file = f
        self._file_opened_ns = now_ns
        self._file_index += 1
        self.stats.files.append(str(path))
        log.info("recording to %s", path)
        return path

    def fileno(self) -> int | None:
        """The descriptor of the file being written (None: none is open), for ``syncer``."""
        return self._file.stream.fileno() if self._file is not None else None

    @property
    def path(self) -> Path | None:
        return self._file.path if self._file else None

    def _close_file(self, now_ns: int) -> None:
        f = self._file
        if f is None:
            return
        f.writer.flush()  # the last chunk first: the summary's counts then hold whatever comes next
        summary = self.stats.as_metadata()
        summary.update({"file_messages": str(f.messages), "closed_at_ns": str(now_ns)})
        f.close((SUMMARY_METADATA, summary), durable=self.durable)
        self._file = None

    def maybe_rotate(self, now_ns: int) -> Path | None:
        """Start the next file if this one is over its size or age; returns the new path."""
        f = self._file
        if f is None or not self.rotating or f.messages == 0:
            return None
        too_big = self.max_bytes is not None and f.size() >= self.max_bytes
        too_old = (self.max_seconds is not None
                   and (now_ns - self._file_opened_ns) >= self.max_seconds * 1e9)
        if not (too_big or too_old):
            return None
        self._close_file(now_ns)
        return self.open(now_ns)

    def flush(self) -> None:
        """End the chunk in progress (with its message index) and hand the bytes to the OS. Raises
        while no file is open because the last could not start: nothing is on disk."""
        if self._file is None and self._open_failed is not None:
            err = self._open_failed  # a new error each time: one raised again keeps every traceback
            raise OSError(err.errno, err.strerror, err.filename)
        if self._file is not None:
            self._file.writer.flush()
            self.stats.flushes += 1

    def resume(self, now_ns: int) -> None:
        """After a full disk: open the next file if none is open (its start found no room), and
        write what is in hand. Raises as ``flush`` does while there is still no room."""
        if self._file is None:
            self.open(now_ns)
        self.flush()

    def check_file(self, now_ns: int) -> Path | None:
        """Before writing more: if the file being written was deleted, replaced or truncated by another
        process (``OpenFile.lost``), say so, count it (``lost_files``) and go on in a new file
        (the next free name, with the attachments and run metadata again); returns its path.
        Writing on into it would lose every later message too, silently: no write fails."""
        f = self._file
        if f is None:
            return None
        why = f.lost()
        if not why:
            return None
        self.stats.lost_files += 1
        self.stats.last_error = f"{f.path}: {why} while recording"
        log.error("%s was %s while recording: its %d messages are lost; recording on in a new "
                  "file", f.path, why, f.messages)
        self._close_file(now_ns)
        return self.open(now_ns)

    def close(self, now_ns: int | None = None) -> list[str]:
        """Finish the file (summary and indexes); returns every file written."""
        self._close_file(time.time_ns() if now_ns is None else now_ns)
        return list(self.stats.files)

    # -- samples ----------------------------------------------------------------------------

    def _spec(self, key: str, encoding: str) -> tuple[schemas.ChannelSpec, bool]:
        """The channel of ``key`` (the encoding of its first sample says it for an unregistered
        key), and whether the deriver takes it."""
        found = self._channel_specs.get(key)
        if found is None:
            derives = (self._deriver is not None
                       and key.split("/", 2)[-1] in self._derived_sources)
            found = self._channel_specs[key] = (schemas.channel_for_key(key, encoding), derives)
        return found

    def _put(self, spec: schemas.ChannelSpec, data: bytes, log_time_ns: int, publish_time_ns: int) -> None:
        f = self._file
        if f is None:
            raise RuntimeError("RecordingWriter.write before open()")
        topic = spec.topic
        cid = f.channels.get(topic)
        if cid is None:
            cid = f.channel(spec)
        sequence = f.sequence
        seq = sequence[cid] = sequence[cid] + 1
        f.writer.add_message(cid, log_time_ns, data, publish_time_ns, seq & 0xFFFFFFFF)
        f.messages += 1
        self.stats.by_topic[topic] += 1

    def write(self, key: str, payload: bytes, encoding: str, receive_ns: int,
              copy: bool = False, decoded: Any = None) -> bool:
        """Record one sample received at ``receive_ns`` (wall clock; the publish time); returns
        False if it was malformed (kept on the error channel). ``copy``: from a lockstep bundle sent
        again (``RecordingTime.bus``). ``decoded``: ``payload`` already decoded as its key's type
        by the caller (a lockstep answer the recorder's witness read, or what an in-process
        publisher encoded it from), not decoded again; of another type, it is not used."""
        found = self._channel_specs.get(key)
        spec, derives = found if found is not None else self._spec(key, encoding)
        stats = self.stats
        stats.bytes += len(payload)
        msg: Any = decoded if type(decoded) is spec.message_type else None
        if msg is None and spec.message_type is not None and (self.validate or derives):
            try:
                msg = spec.message_type.decode(payload)
            except MessageError as err:
                self._put_malformed(key, spec.schema_name, str(err), encoding, payload,
                                    self.time.wall(receive_ns), receive_ns)
                return False
        elif spec.message_type is None:
            stats.unregistered += 1
        stamp = None
        rec_time = self.time
        if rec_time.lockstep:
            stamp = msg.stamp_ns if msg is not None else stamp_of(payload)
        log_ns = rec_time.bus(key, stamp, receive_ns, copy)
        self._put(spec, payload, log_ns, receive_ns)
        stats.messages += 1
        if rec_time.new_episodes:
            self._write_episodes()
        if derives and msg is not None:
            assert self._deriver is not None
            try:
                views = [(derive.channel_spec(d), d.payload()) for d in self._deriver.feed(key, msg)]
            except (ValueError, OverflowError, ArithmeticError) as err:
                # A valid message whose values a Foxglove schema cannot hold (a stamp past 2106 in
                # a uint32 of seconds, a variance past a float): the message itself is recorded
                # above; only its view is left out, counted, and the recorder goes on.
                stats.underived += 1
                self._ratelog.warning(("underived", key), "no Foxglove view of a sample on %s: %s",
                                      key, err)
                return True
            for view_spec, data in views:
                self._put(view_spec, data, log_ns, receive_ns)
                stats.derived += 1
        return True

    def unpack(self, key: str, payload: bytes, encoding: str, receive_ns: int,
               carried: Any = None) -> list[tuple[str, bytes, str]]:
        """The samples one bus sample stands for, to ``write`` each: itself, or for a lockstep
        bundle (``seaway.contract.bundle``) its messages on their own keys, then its answer.
        A line of a key its member does not produce goes alone to the error channel, naming it,
        and the rest is written: the members drop that line and take the rest, answer included,
        so the recorder must write (and answer for) the same, or the sim waits on it for ever. A
        bundle whose framing does not read is kept whole on the error channel and stands for
        nothing (no member takes it either). ``carried``: what an in-process sender encoded it
        from (``bundle.parts``)."""
        if encoding != bundle.ENCODING:
            return [(key, payload, encoding)]
        foreign: list[tuple[str, bytes, str]] = []
        try:
            out = bundle.unpack(key, payload, carried, foreign)
        except MessageError as err:
            self._put_malformed(key, PeriodDone.SCHEMA, str(err), encoding, payload,
                                self.time.wall(receive_ns), receive_ns)
            return []
        for _suffix, line, why in foreign:
            self._put_malformed(key, PeriodDone.SCHEMA, f"line dropped, the rest written: {why}",
                                encoding, line, self.time.wall(receive_ns), receive_ns)
        return out

    def _write_episodes(self) -> None:
        """A new lockstep episode continues the timeline: say at which offset, in the file."""
        for meta in self.time.new_episodes:
            if self._file is not None:
                self._file.writer.add_metadata(EPISODE_METADATA.format(index=meta["episode"]), meta)
        self.time.new_episodes.clear()

    def write_log(self, process: str, line: LogLine) -> None:
        """Record one line of a process's log on ``foxglove/log`` (``foxglove.Log``), at the time
        it was logged (``line.wall_ns``; in lockstep the sim time reached then)."""
        wall_ns = line.wall_ns or 0
        log_ns = self.time.wall(wall_ns)
        d = derive.log_message(log_ns, line.level, process, line.logger, line.message)
        self._put(derive.channel_spec(d), d.payload(), log_ns, wall_ns)
        self.stats.logs += 1

    def write_event(self, line: bytes) -> bool:
        """Record one line of a launcher's events log on ``launcher/events`` at its own time;
        False (and a warning) for a line that is not a ``ProcessEvent``."""
        try:
            ev = ProcessEvent.model_validate_json(line)
        except ValueError as err:
            log.warning("events log line ignored (not a process event): %s", str(err)[:200])
            return False
        t_ns = int(ev.t_unix_s * 1e9)
        # Its own form (defaults left out), which the channel's schema says: a line written by
        # hand may carry a null the schema does not allow.
        self._put(self._events_spec, ev.line().rstrip("\n").encode(), self.time.wall(t_ns), t_ns)
        self.stats.events += 1
        return True

    def write_restart(self, record: dict[str, Any], log_ns: int) -> None:
        """Say in the recording that this recorder took over from one that stopped
        (``schemas.RESTART_SCHEMA``), at ``log_ns`` (wall clock)."""
        self._put(schemas.restart_channel(), json.dumps(record, sort_keys=True).encode(),
                  self.time.wall(log_ns), log_ns)

    def write_clock_step(self, stamp_ns: int, step_ns: int) -> None:
        """Say in the recording that the wall clock stepped by ``step_ns`` (seen at ``stamp_ns``,
        on the new clock; ``schemas.CLOCK_STEP_SCHEMA``): what a reader bridges
        (``clock_bridge``)."""
        record = {"stamp_ns": stamp_ns, "step_ns": step_ns}
        self._put(schemas.clock_step_channel(), json.dumps(record, sort_keys=True).encode(),
                  self.time.wall(stamp_ns), stamp_ns)

    def _put_malformed(self, key: str, schema: str, error: str, encoding: str, payload: bytes,
                       log_time_ns: int, publish_time_ns: int) -> None:
        self.stats.malformed += 1
        self.stats.last_error = f"{key}: {error}"[:500]
        self._ratelog.warning(("malformed", key), "malformed sample on %s kept on %s: %s", key,
                              schemas.MALFORMED_TOPIC, error)
        envelope = schemas.malformed_record(key, schema, error, encoding, payload, log_time_ns)
        self._put(schemas.malformed_channel(), envelope, log_time_ns, publish_time_ns)

    def count_dropped(self, n: int) -> None:
        """Samples lost before they reached the writer (queue overflow); stored in the summary."""
        self.stats.dropped += n
