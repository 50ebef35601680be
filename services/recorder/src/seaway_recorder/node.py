"""The recorder's node: what it hears (every sample of its key expressions, taken off the bus's
threads into ``SampleQueue``), and the writer's loop that drains it into ``RecordingWriter``,
flushes at least every ``--flush-interval``, rotates, copies the launcher's events and the run's
logs in, and, in lockstep, answers each period once it is on disk (the runtime's
``seaway.runtime.lockstep_witness.LockstepWitness``). In lockstep the thread that delivers a
member's answer writes the period itself (``RecorderNode.write_on_arrival``), as the other members
answer on arrival, so that a period needs no thread switch (composed, the sim would wait for it).
``seaway_recorder.main`` configures it.

A disk with no room (``seaway.runtime.disk.disk_full``) does not stop the recorder: it keeps what it holds,
takes no more from its queue, says so, and tries again every ``ROOM_RETRY_S``; once there is room
it writes on where it stopped. Meanwhile the queue fills to its bounds and then counts its drops
(real time); in lockstep no period is answered, so the sim waits and nothing is lost.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import zenoh
from seaway.contract import bundle, keys
from seaway.contract.messages import LOCKSTEP_SERVICES, LogRecord, PeriodDone
from seaway.recording.timebase import stamp_of
from seaway.runtime.bus_raw import RawSample
from seaway.runtime.clock import WallStepWatch
from seaway.runtime.disk import disk_full
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.node import Node
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.timeline import Timeline

from seaway_recorder.core import RecordingWriter
from seaway_recorder.logtail import FileTail, LogTail, log_record
from seaway_recorder.syncer import Syncer

log = logging.getLogger("seaway.recorder")
clock_log = logging.getLogger("seaway.recorder.clock")
"""A step of the wall clock under the recording (``RecorderNode._look_at_wall_clock``)."""

DRAIN_BATCH = 2000
"""Samples written at most per tick: the flush and the status line come between batches."""
IDLE_WAIT_S = 0.005
"""How long an idle recorder waits for a sample before it looks again (real time; in lockstep a
sample wakes it at once) [s]."""

ROOM_RETRY_S = 1.0
"""How often a recorder whose disk has no room tries to write again [s]: a try that fails costs one
chunk's write, cut off again."""
NO_ROOM_SAY_S = 10.0
"""How often a recorder still waiting for room says so again [s]."""

LATE_NS = 500_000_000
"""A sample received this long after it was published came from a publisher's cache (or waited
that long in a queue): logged at its publication time, and looked up among a predecessor's."""


DEFAULT_QUEUE_BYTES = 256 << 20
"""Payload bytes queued between the bus and the writer before drops [bytes]: the count alone
(``--queue``) let 200,000 samples of a megabyte each (the bus takes far larger) hold 200 GB."""


class SampleQueue:
    """Bounded hand-over from the bus's threads to the writer; overflow is counted, never blocks.

    Bounded twice: ``capacity`` samples and ``max_bytes`` of their payloads [bytes]; a sample
    larger than ``max_bytes`` is still taken when nothing is queued (memory stays below
    ``max_bytes`` plus one sample). A consumer that takes items adds their payload sizes to
    ``out_bytes`` (only it writes that; the bus's threads write ``in_bytes``)."""

    def __init__(self, capacity: int, max_bytes: int = DEFAULT_QUEUE_BYTES) -> None:
        self.capacity = capacity
        self.max_bytes = max_bytes
        self.in_bytes = 0
        self.out_bytes = 0
        self.dropped_bytes = 0
        self.items: collections.deque[tuple[str, bytes, str, int, Any]] = collections.deque()
        """(key, bytes, encoding, receive time [ns], what the bytes were encoded from in process
        (``RawSample.carried``) or None)."""
        self.dropped = 0
        self.accepting = True
        self.arrived = threading.Event()  # wakes a lockstep writer at once (no polling delay)
        self.wake_on_any = True
        """Whether any sample wakes the writer, else only a lockstep answer: a lockstep writer has
        nothing to decide before an answer comes, unless one it has lacks listed messages
        (``LockstepWitness.lacking``). Woken for each of the ~20 samples of a period, it cost a
        thread hand-over each."""
        self._lock = threading.Lock()
        self.timeline: Timeline | None = None  # a lockstep recorder's, when tracing
        self.already: set[tuple[str, bytes]] = set()
        """(key, bytes) a predecessor's recording holds (a restarted recorder): not queued again."""
        self.repeats = 0
        self.on_wake: Callable[[], None] | None = None
        """Called instead of waking the writer's loop (``arrived``): in lockstep, the node's
        ``write_on_arrival``, which writes on the delivering thread."""

    def on_sample(self, sample: RawSample) -> None:
        # Called on the bus's delivery threads: keep it short (the bytes are already our own copy).
        if not self.accepting:
            return
        now_ns = time.time_ns()
        late = sample.published_ns is not None and now_ns - sample.published_ns > LATE_NS
        if late and (sample.key, sample.payload) in self.already:
            with self._lock:
                self.repeats += 1
            return
        size = len(sample.payload)
        with self._lock:  # the bus may deliver on several threads: in_bytes must not lose a count
            queued = self.in_bytes - self.out_bytes
            if len(self.items) >= self.capacity or (queued + size > self.max_bytes and queued > 0):
                self.dropped += 1
                self.dropped_bytes += size
                return
            self.in_bytes += size
            # A sample a publisher's cache gave late (to a recorder that restarted) is logged
            # when it was published, where it belongs on the timeline.
            self.items.append((sample.key, sample.payload, sample.encoding,
                               sample.published_ns if late else now_ns, sample.carried))
        if self.timeline is not None and "/lockstep/" in sample.key:
            # Its arrival, not when it is written (seaway.runtime.timeline: the recorder's "heard").
            stamp = stamp_of(sample.payload)
            if stamp is not None:
                self.timeline.mark("heard", stamp, sample.key.rsplit("/", 1)[1])
        if self.wake_on_any or "/lockstep/" in sample.key:
            if self.on_wake is not None:
                self.on_wake()
            else:
                self.arrived.set()


class KeptKeys:
    """Which keys a recording keeps: those its key expressions include (Zenoh's own matching).
    Asked of each message a lockstep bundle carries: the bundle's key may be subscribed for
    lockstep alone (``lockstep_exprs``), its messages' keys not."""

    def __init__(self, exprs: Sequence[str]) -> None:
        self._exprs = [zenoh.KeyExpr(e) for e in exprs]
        self._kept: dict[str, bool] = {}

    def __call__(self, key: str) -> bool:
        kept = self._kept.get(key)
        if kept is None:
            kept = self._kept[key] = any(e.includes(key) for e in self._exprs)
        return kept


def recorded_suffixes(exprs: Sequence[str], vessel: str) -> set[str]:
    """The registered key suffixes of ``vessel`` that the key expressions ``exprs`` record."""
    kept = KeptKeys(exprs)
    return {spec.suffix for spec in keys.REGISTRY if kept(spec.key(vessel))}


def lockstep_exprs(exprs: list[str], vessel: str) -> list[str]:
    """``exprs`` plus the lockstep answers of ``vessel`` if they do not record them already: a
    recorder in lockstep must hear them to take part."""
    answers = {keys.lockstep_spec(s).suffix for s in LOCKSTEP_SERVICES}
    if answers <= recorded_suffixes(exprs, vessel):
        return exprs
    return [*exprs, f"{keys.ROOT}/{vessel}/lockstep/*"]


def carried_objects(samples: list[tuple[str, bytes, str]], carried: Any) -> list[Any]:
    """Per sample ``RecordingWriter.unpack`` made of one bus sample, what its bytes were encoded
    from if the in-process bus handed it along (``RawSample.carried``), else None: the writer
    then decodes the bytes (it takes an object only of its key's type)."""
    if type(carried) is bundle.Carried and len(carried.messages) + 1 == len(samples):
        return [*carried.messages, carried.answer]
    if carried is not None and len(samples) == 1 and type(carried) is not bundle.Carried:
        return [carried]
    return [None] * len(samples)


def drain(writer: RecordingWriter, queue: SampleQueue, limit: int | None,
           witness: LockstepWitness | None = None, kept: KeptKeys | None = None) -> int:
    """Write up to ``limit`` queued samples (a lockstep bundle as the samples it stands for, those
    ``kept`` keeps); in lockstep, answer a period once it is on disk."""
    n = 0
    items = queue.items
    answers: list[tuple[str, PeriodDone]] = []
    while items and (limit is None or n < limit):
        sample_key, sample, sample_encoding, t_ns, carried = items.popleft()
        queue.out_bytes += len(sample)
        n += 1
        copy = sample_encoding == bundle.ENCODING and bundle.is_resent(sample, carried)
        samples = writer.unpack(sample_key, sample, sample_encoding, t_ns, carried)
        answer = None  # the answer comes last, on the bundle's own key
        if witness is not None and samples and samples[-1][0] == sample_key:
            answer = witness.heard(sample_key, samples[-1][1], bundle.carried_answer(carried))
        for (key, payload, encoding), obj in zip(samples, carried_objects(samples, carried),
                                                 strict=True):
            if key != sample_key and kept is not None and not kept(key):
                continue  # a bundle's message on a key this recording leaves out
            decoded = answer if key == sample_key and answer is not None else obj
            if answer is not None and decoded is answer:
                answers.append((key, answer))  # a repeat not written again is on disk all the same
            if witness is not None and not witness.admit(key, payload):
                continue
            writer.write(key, payload, encoding, t_ns, copy, decoded=decoded)
    if witness is not None:
        witness.written(answers)
        witness.maybe_answer(writer.flush)
        # Before the loop clears ``arrived`` and drains again, so no sample is left unwoken for.
        queue.wake_on_any = witness.lacking()
    return n


class Tails:
    """The files copied into the recording as they grow: the launcher's events, the run's logs.

    ``publish``: also put each log line on the bus (``keys.LOG_LINE``), for a viewer that is not
    on this machine (``seaway foxglove`` on the shore). A line that cannot be published (the
    session closing) is still recorded."""

    def __init__(self, events: FileTail | None, logs: LogTail | None,
                 publish: Callable[[LogRecord], None] | None = None) -> None:
        self.events = events
        self.logs = logs
        self.publish = publish

    def copy(self, writer: RecordingWriter) -> None:
        if self.events is not None:
            for line in self.events.poll():
                writer.write_event(line)
        if self.logs is not None:
            now_ns = time.time_ns()
            for process, line in self.logs.poll(now_ns):
                writer.write_log(process, line)
                if self.publish is not None:
                    try:
                        self.publish(log_record(process, line, now_ns))
                    except Exception as err:
                        log.debug("log line not published: %s", err)

    def close(self) -> None:
        """Let go of the files (after the last ``copy``)."""
        if self.events is not None:
            self.events.close()
        if self.logs is not None:
            self.logs.close()


class RecorderNode(Node):
    """The recorder as a paced node of the wall clock (``seaway.runtime.node``): each tick drains
    up to ``DRAIN_BATCH`` queued samples into the writer, flushes every ``flush_s`` (with the
    events and logs copied in), rotates, and logs its counts every ``status_s``; in lockstep the
    witness answers each period once it is on disk (``drain``), and a sample wakes it at once."""

    name = "recorder"
    paced = True

    def __init__(self, writer: RecordingWriter, queue: SampleQueue, flush_s: float,
                 status_s: float, witness: LockstepWitness | None = None,
                 tails: Tails | None = None, kept: KeptKeys | None = None,
                 syncer: Syncer | None = None) -> None:
        self.writer, self.queue, self.witness, self.tails, self.kept = (
            writer, queue, witness, tails, kept)
        self.syncer = syncer
        """Syncs the file to the disk every ``--sync-interval``, off this loop (``syncer``)."""
        self.flush_ns = int(flush_s * 1e9)
        self.status_s = status_s
        now = time.monotonic_ns()
        self._next_flush = now + self.flush_ns
        self._next_status = now + int(status_s * 1e9)
        self._last_messages = 0
        self._drained = 0
        self._looping = False  # the loop has ticked: writing on arrival may take over
        self.failed: OSError | None = None
        """The write that failed (not for room: a disk gone, a folder removed): the node stops, and
        finishes what it can."""
        self.no_room: OSError | None = None
        """Set while the disk has no room for the recording: the node waits for room (module doc)."""
        self._no_room_since = 0
        self._next_room_try = 0
        self._still_no_room = RateLimitedLog(log, NO_ROOM_SAY_S)
        self._wall = WallStepWatch()
        self._stop: threading.Event | None = None
        self._writing = threading.Lock()
        """Held while the writer is used: by the loop (``tick``, ``finish``), or by the thread that
        delivers a lockstep answer (``write_on_arrival``)."""
        self._raised: BaseException | None = None
        """What a write on a delivering thread raised: raised again in the loop, where the node's
        runtime handles a failure."""
        if witness is not None:
            queue.on_wake = self.write_on_arrival

    def write_on_arrival(self) -> None:
        """In lockstep, called on the thread that delivered a sample to wake the writer for: write
        what is queued and answer the period on that thread (composed, inside the sim's put). The
        loop takes over, woken as before, when it is writing itself (or this thread is inside its
        write: the answer it put completed a period, and the chain ran from there), before the
        loop's first tick, and once writing has failed. Once stopping (``finish``), it writes
        nothing: the loop writes what is queued, and the writer is closed after it."""
        stopping = not self.queue.accepting
        if (not self._looping or stopping or self.failed is not None or self._raised is not None
                or self.no_room is not None):
            self.queue.arrived.set()
            return
        if not self._writing.acquire(blocking=False):
            self.queue.arrived.set()
            return
        try:
            self._drained = drain(self.writer, self.queue, limit=DRAIN_BATCH,
                                  witness=self.witness, kept=self.kept)
        except OSError as err:
            self._failed(err)
            self.queue.arrived.set()  # the loop waits for room, or stops
        except Exception as err:  # not the bus's to handle: the loop raises it again
            self._raised = err
            self.queue.arrived.set()
        finally:
            self._writing.release()

    def attach(self, driver: Any) -> None:
        self._stop = driver.stop

    def joining(self) -> None:
        """A member before it is ready (``Node.joining``): the clock then repeats its period for
        us, and waits for us from then on."""
        if self.witness is not None:
            self.witness.member.join()

    def tick(self, now_ns: int, out: Any) -> None:
        if not self._looping:
            self._looping = True
            print("READY", flush=True)
        if self._raised is not None:
            raise self._raised
        try:
            with self._writing:
                self._write()
        except OSError as err:
            self._failed(err)

    def _failed(self, err: OSError) -> None:
        """A write failed: with no room on the disk, the node waits for room (``_room_again``);
        otherwise it stops, and ``finish`` finishes what can be finished."""
        if disk_full(err):
            now = time.monotonic_ns()
            if self.no_room is None:
                self._no_room_since = now
                self.writer.stats.no_room += 1
                # A key per wait: its first line always goes out, and starts the key's clock.
                self._still_no_room.log(
                    self._no_room_key(), logging.ERROR, "no room on the disk for the recording (%s): "
                    "%s; waiting for room, trying again every %g s; nothing is written meanwhile, "
                    "samples are queued (at most %d, %d MiB) and counted as dropped beyond that",
                    self.writer.path or self.writer.base, err, ROOM_RETRY_S, self.queue.capacity,
                    self.queue.max_bytes >> 20, now_ns=now)
            self.no_room = err
            self.writer.stats.last_error = f"no room on the disk: {err}"[:500]
            self._next_room_try = now + int(ROOM_RETRY_S * 1e9)
            return
        self.failed = err
        assert self._stop is not None
        self._stop.set()

    def _no_room_key(self) -> tuple[str, int]:
        return ("no room", self.writer.stats.no_room)

    def _look_at_wall_clock(self, mono_ns: int) -> None:
        """Say a step of the wall clock (``WallStepWatch``, at each flush): in real time every log
        time after it, and every service's stamps, are on the new clock (README, "A wall clock
        stepped while recording"); its own logger, so that a test or a reader finds it."""
        wall_ns = time.time_ns()
        step_ns = self._wall.look(wall_ns, mono_ns)
        if step_ns is not None:
            clock_log.warning("the wall clock stepped %+.3f s (NTP or GPS time setting it): log "
                              "times and stamps after this are on the new clock", step_ns / 1e9)
            if self.witness is None:  # in lockstep the recording's times are the simulation's
                self.writer.write_clock_step(wall_ns, step_ns)

    def _room_again(self) -> bool:
        """Waiting for room: try again if it is time; whether the disk took what was in hand."""
        now = time.monotonic_ns()
        if now < self._next_room_try:
            return False
        try:
            self.writer.resume(time.time_ns())
        except OSError as err:
            self._failed(err)
            if self.no_room is not None:
                self._still_no_room.log(
                    self._no_room_key(), logging.ERROR, "still no room on the disk after %.0f s: "
                    "%s; queue %d, dropped %d", (now - self._no_room_since) / 1e9, err,
                    len(self.queue.items), self.queue.dropped, now_ns=now)
            return False
        waited_s = (time.monotonic_ns() - self._no_room_since) / 1e9
        self.writer.stats.no_room_s += waited_s
        log.warning("room on the disk again after %.1f s: recording on in %s (%d samples queued, "
                    "%d dropped so far)", waited_s, self.writer.path, len(self.queue.items),
                    self.queue.dropped)
        self.no_room = None
        return True

    def _write(self) -> None:
        writer, queue = self.writer, self.queue
        queue.arrived.clear()
        if self.no_room is not None and not self._room_again():
            self._drained = 0
            return
        if time.monotonic_ns() >= self._next_flush:
            # Before this tick's samples go in: a file deleted or cut under us gets none of them.
            writer.check_file(time.time_ns())
        self._drained = drain(writer, queue, limit=DRAIN_BATCH, witness=self.witness,
                              kept=self.kept)
        now = time.monotonic_ns()
        if now >= self._next_flush:
            self._look_at_wall_clock(now)
            writer.count_dropped(queue.dropped - writer.stats.dropped)
            if self.tails is not None:
                self.tails.copy(writer)
            writer.flush()
            writer.maybe_rotate(time.time_ns())
            if self.syncer is not None:
                self.syncer.maybe(writer.fileno(), now)
            self._next_flush = now + self.flush_ns
        if now >= self._next_status:
            rate = (writer.stats.messages - self._last_messages) / self.status_s
            self._last_messages = writer.stats.messages
            log.info("%s; %.0f msg/s; queue %d; file %s", writer.stats.line(), rate,
                     len(queue.items), writer.path)
            self._next_status = now + int(self.status_s * 1e9)

    def wake_s(self) -> float:
        """At once while samples are queued; else a little, never past the next flush (waiting for
        room: never past the next try)."""
        if self.no_room is not None:
            return min(IDLE_WAIT_S * 20,
                       max(0.0, (self._next_room_try - time.monotonic_ns()) / 1e9))
        if self._drained:
            return 0.0
        return min(IDLE_WAIT_S, max(0.0, (self._next_flush - time.monotonic_ns()) / 1e9))

    def sleep(self, timeout_s: float, stop: threading.Event) -> None:
        if timeout_s <= 0:
            return
        if self.witness is not None:  # lockstep: a sample (an answer) wakes it at once
            self.queue.arrived.wait(timeout_s)
        else:
            stop.wait(timeout_s)

    def finish(self) -> None:
        """Stopping: what is queued written, the tails copied (unless writing failed)."""
        self.queue.accepting = False
        try:
            if self.failed is not None:
                log.error("writing failed: %s; finishing the file", self.failed)
                return
            if self.no_room is not None:
                self._next_room_try = 0  # a last try
                if not self._room_again():
                    log.error("stopping with no room on the disk: %d queued samples are not "
                              "written", len(self.queue.items))
                    self.failed = self.no_room
                    return
            with self._writing:  # after a write on arrival still under way
                drain(self.writer, self.queue, limit=None, kept=self.kept)
                if self.tails is not None:
                    self.tails.copy(self.writer)
        except OSError as err:
            self.failed = err
            log.error("writing failed: %s; finishing the file", err)
        finally:
            if self.tails is not None:
                self.tails.close()
