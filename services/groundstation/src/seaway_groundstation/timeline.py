"""A recording's frames, cut progressively by a background thread, so the page has the first ones
at once and the rest as they are cut (the replay view's loading; ``replay.py`` cuts).

The loader reads the files' chunks in the order of their first log time (the MCAP summary's chunk
indexes say where each is and which channels it holds: a chunk with none of the shown kinds is not
read), keeps their messages in a heap and hands on, in log-time order, every message logged before
the next unread chunk's first log time: the order a merge of the whole recording gives, with only
a chunk or two in memory. ``loaded_to_s`` says up to when (recorded time since the start) the
frames are final; ``window`` answers a span with the frames that are, at most ``max_bytes`` of them.
The frames themselves are kept on disk, compressed (``framestore.py``): they are some 50 times the
recording's size, too much to hold for the few recordings a ground station keeps open.

A file written without chunk indexes is read whole through the shared reader
(``seaway.recording.reader``) instead.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcap.summary import Summary
from seaway.contract import keys
from seaway.contract.messages import Message, MessageError

from seaway_groundstation import replay
from seaway_groundstation.fleet import Kind
from seaway_groundstation.framestore import FrameStore
from seaway_groundstation.gateway import TOPICS

log = logging.getLogger("seaway_groundstation.timeline")

_SUFFIX_KIND: dict[str, Kind] = {spec.suffix: kind for kind, spec in TOPICS.items()}


def shown_topic(topic: str) -> tuple[str, Kind] | None:
    """(vessel, kind) of a recorded topic the page shows, else None."""
    spec = keys.spec_for_key(topic)
    kind = None if spec is None else _SUFFIX_KIND.get(spec.suffix)
    if kind is None or not topic.startswith(keys.ROOT + "/"):
        return None
    return topic.split("/", 2)[1], kind


def _decode(kind: Kind, data: bytes) -> Message | None:
    try:
        return TOPICS[kind].message.decode(data)  # type: ignore[union-attr]
    except MessageError:
        return None


def _chunked(files: list[Path], summaries: dict[Path, Summary]
             ) -> Iterator[tuple[int, str, bytes] | int]:
    """(log time, topic, data) of the shown topics' messages in log-time order; between them, an
    int: a log time before which every message has been yielded."""
    from seaway.recording.reader import RECOVER_HINT, UnreadableRecordingError, chunked_messages

    # (first log time, file, chunk, its file's shown channels: id -> topic, and their ids)
    wanted: list[tuple[int, Path, Any, dict[int, str], set[int]]] = []
    for f in files:
        s = summaries[f]
        ids = {cid: ch.topic for cid, ch in s.channels.items() if shown_topic(ch.topic) is not None}
        id_set = set(ids)
        wanted += [(ci.message_start_time, f, ci, ids, id_set) for ci in s.chunk_indexes
                   if not ci.message_index_offsets or not id_set.isdisjoint(ci.message_index_offsets)]
    wanted.sort(key=lambda w: w[0])
    heap: list[tuple[int, int, str, bytes]] = []
    order = itertools.count()
    handles: dict[Path, Any] = {}
    try:
        for i, (_, f, ci, ids, id_set) in enumerate(wanted):
            fh = handles.get(f) or handles.setdefault(f, open(f, "rb"))  # noqa: SIM115 - closed below
            try:
                for cid, log_ns, data in chunked_messages(fh, [ci], id_set):
                    heapq.heappush(heap, (log_ns, next(order), ids[cid], data))
            except Exception as err:  # McapError, a decompressor's: say which file, and the repair
                raise UnreadableRecordingError(f"{f}: {err}; {RECOVER_HINT}") from None
            horizon = wanted[i + 1][0] if i + 1 < len(wanted) else None
            while heap and (horizon is None or heap[0][0] < horizon):
                log_ns, _, topic, data = heapq.heappop(heap)
                yield log_ns, topic, data
            if horizon is not None:
                yield horizon
    finally:
        for fh in handles.values():
            fh.close()


def _whole(files: list[Path]) -> Iterator[tuple[int, str, bytes] | int]:
    from seaway.recording.reader import iter_messages

    for m in iter_messages(files):
        if shown_topic(m.topic) is not None:
            yield m.log_time_ns, m.topic, m.data


class Timeline:
    """The frames of ``files`` (a recording's, in series order, with their ``summaries``), cut by
    ``start()``'s thread; see the module's description. Thread-safe."""

    def __init__(self, files: list[Path], summaries: dict[Path, Summary], start_ns: int,
                 rate_hz: float, stale_after_s: float) -> None:
        self.files, self.summaries = files, summaries
        self.cutter = replay.Cutter(start_ns, rate_hz, stale_after_s, _decode)
        self.start_ns = start_ns
        self.frames = FrameStore()
        self.loaded_to_s = 0.0
        """Frames before this recorded time [s since the start] are all cut (inf: every one)."""
        self.error: str | None = None
        self.duplicates = 0
        self._cond = threading.Condition()
        self._cancelled = False
        self._thread = threading.Thread(target=self._run, name="replay-timeline", daemon=True)

    @property
    def complete(self) -> bool:
        return math.isinf(self.loaded_to_s)

    @property
    def undecodable(self) -> int:
        return self.cutter.undecodable

    def start(self) -> Timeline:
        self._thread.start()
        return self

    def cancel(self) -> None:
        self._cancelled = True

    def _add(self, frames: list[replay.ReplayFrame], loaded_to_s: float | None) -> None:
        with self._cond:
            self.frames.append(frames)
            if loaded_to_s is not None:
                self.loaded_to_s = max(self.loaded_to_s, loaded_to_s)
            self._cond.notify_all()

    def _run(self) -> None:
        indexed = all(self.summaries.get(f) is not None and self.summaries[f].chunk_indexes
                      for f in self.files)
        messages = _chunked(self.files, self.summaries) if indexed else _whole(self.files)
        seen: set[tuple[str, int]] = set()
        several = len(self.files) > 1
        shown: dict[str, tuple[str, Kind]] = {}
        try:
            for item in messages:
                if self._cancelled:
                    return
                if isinstance(item, int):
                    self._add(self.cutter.advance(item), (item - self.start_ns) / 1e9)
                    continue
                log_ns, topic, data = item
                if several:  # a period a restarted recorder wrote into both files: read once
                    ident = (topic, hash(data))
                    if ident in seen:
                        self.duplicates += 1
                        continue
                    seen.add(ident)
                where = shown.get(topic)
                if where is None:
                    where = shown[topic] = shown_topic(topic)  # type: ignore[assignment]
                vessel, kind = where
                new = self.cutter.add(log_ns, vessel, kind, data)
                if new:
                    self._add(new, None)
            self._add(self.cutter.finish(), math.inf)
        except Exception as err:  # a damaged chunk: what came before stays, the page says why
            log.warning("replay: %s", err)
            with self._cond:
                self.error = f"{type(err).__name__}: {err}"
            self._add([], math.inf)

    def wait(self, until_s: float, timeout_s: float) -> None:
        """Until the frames before ``until_s`` are all cut, at most ``timeout_s``."""
        with self._cond:
            self._cond.wait_for(lambda: self.loaded_to_s >= until_s, timeout=timeout_s)

    def window(self, start_s: float, end_s: float, max_bytes: int) -> tuple[bytes, int, float]:
        """The final frames with ``start_s <= t_s < end_s`` as a JSON array of ``{"t_s", "frame"}``,
        how many, and the time up to which that answer is whole [s]: ``end_s`` once the frames are
        cut that far and are no more than ``max_bytes`` [bytes] (``FrameStore.window``)."""
        with self._cond:
            upto = min(end_s, self.loaded_to_s)
        if upto <= start_s:
            return b"[]", 0, max(start_s, upto)
        return self.frames.window(start_s, upto, max_bytes)
