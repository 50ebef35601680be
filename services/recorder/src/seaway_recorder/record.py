"""``seaway record``: every sample on ``seaway/**`` into MCAP; ``seaway record recover IN OUT``.

The process (also ``seaway-recorder``) subscribes to the bus; Zenoh's delivery threads only append
``(key, bytes, encoding, receive time)`` to a bounded queue (a full queue drops the sample and counts
it), and one writer thread drains the queue into ``RecordingWriter``. The writer flushes at least every
``--flush-interval`` (default 50 ms: a SIGKILL loses less than 100 ms), rotates files on
``--max-bytes`` / ``--max-seconds``, logs counts every ``--status-interval`` and, on SIGINT or SIGTERM,
writes what is queued and finishes a fully indexed file. The last line on stdout is a JSON summary.
It also copies the launcher's events (``--events``) and the run's log files (``--logs``) into the
recording as they grow. Log times follow ``timebase`` (sim time on the run's epoch in lockstep).
"""

from __future__ import annotations

import argparse
import collections
import datetime as dt
import json
import logging
import os
import socket
import sys
import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import zenoh
from seaway.contract import bundle, keys
from seaway.contract.config import ConfigError
from seaway.contract.messages import LOCKSTEP_SERVICES, LogRecord, MessageError, PeriodDone
from seaway.recording import runinfo
from seaway.recording.recover import recover, tail_of
from seaway.recording.timebase import RecordingTime, parse_epoch, stamp_of
from seaway.runtime import memory
from seaway.runtime import run as runs
from seaway.runtime.argtypes import positive_float, positive_int
from seaway.runtime.bus import REJOIN_HISTORY_S, Bus, RawSample
from seaway.runtime.lockstep import Member, Period, classify
from seaway.runtime.run import RunDescription
from seaway.runtime.service import base_parser, configure_logging, resolve_run, run_service
from seaway.runtime.timeline import Timeline
from seaway.runtime.zenoh_bus import ENV_CONFIG
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin

from seaway_recorder import attachments
from seaway_recorder.logtail import FileTail, LogTail, log_record
from seaway_recorder.writer import LIBRARY, RUN_METADATA, AttachmentSpec, RecordingWriter

log = logging.getLogger("seaway.recorder")
DEFAULT_FLUSH_S = 0.05


def default_out() -> Path:
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path("runs") / stamp / "recording.mcap"


def out_path(text: str | None) -> Path:
    if not text:
        return default_out()
    p = Path(text)
    return p if p.suffix == ".mcap" else p / "recording.mcap"


def parse_meta(items: Sequence[str]) -> dict[str, str]:
    out = {}
    for item in items:
        k, sep, v = item.partition("=")
        if not sep or not k:
            raise SystemExit(f"seaway record: --meta wants KEY=VALUE, got {item!r}")
        out[k] = v
    return out


def parse_size(text: str) -> int:
    units = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30}
    t = text.strip().lower().removesuffix("b").removesuffix("i")
    mult = units.get(t[-1:], 1)
    return int(float(t[:-1] if t[-1:] in units else t) * mult)


def parser() -> argparse.ArgumentParser:
    p = base_parser(
        "recorder", prog="seaway record [run]",
        description="Two commands. 'seaway record [run] [options]' (the default) records every "
                    "sample on the bus to MCAP until Ctrl-C: bytes unchanged, with their JSON "
                    "Schemas, flushed at least every --flush-interval so a crash loses little; the "
                    "launcher starts it as the recorder. 'seaway record recover IN [OUT]' rebuilds a "
                    "fully indexed file from one a crash cut short (seaway record recover --help).")
    p.add_argument("--out", default=None,
                   help="output folder or .mcap file (default runs/<UTC time>/recording.mcap)")
    p.add_argument("--vessels", default="",
                   help="comma-separated vessels to record (default: every vessel, seaway/**)")
    p.add_argument("--key-expr", action="append", default=[],
                   help="record this key expression instead (repeatable)")
    p.add_argument("--profile", default=None, help="launcher profile (name or file) to attach")
    p.add_argument("--mission", default=None, help="mission file to attach (MissionRequest JSON or TOML)")
    p.add_argument("--attach", action="append", default=[], metavar="[ROLE=]FILE",
                   help=f"attach a file (repeatable); roles: {', '.join(runinfo.ROLES)} (default config)")
    p.add_argument("--meta", action="append", default=[], metavar="KEY=VALUE",
                   help="add to the seaway.run metadata record (repeatable)")
    p.add_argument("--flush-interval", type=positive_float, default=DEFAULT_FLUSH_S,
                   help=f"seconds between flushes, at most 0.1 (default {DEFAULT_FLUSH_S})")
    p.add_argument("--max-bytes", type=parse_size, default=None, help="rotate after this size (e.g. 512M)")
    p.add_argument("--max-seconds", type=positive_float, default=None, help="rotate after this many seconds")
    p.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd",
                   help="chunk compression (default zstd; none writes fastest, files are larger)")
    p.add_argument("--chunk-size", type=parse_size, default=4 << 20,
                   help="end a chunk early past this many bytes (default 4M)")
    p.add_argument("--queue", type=positive_int, default=200_000,
                   help="samples buffered between Zenoh and the writer before drops (default 200000)")
    p.add_argument("--no-validate", action="store_true",
                   help="do not check samples against their types (faster; nothing counts as malformed)")
    p.add_argument("--no-foxglove", action="store_true",
                   help="do not add the derived Foxglove channels (map positions, mission, frames, "
                        "3D scene); log lines (--logs) are still recorded")
    p.add_argument("--status-interval", type=positive_float, default=5.0, help="seconds between status lines")
    p.add_argument("--events", type=Path, default=None, metavar="FILE",
                   help="a launcher's events log (events.jsonl) to copy into the recording as it "
                        "grows, on launcher/events")
    p.add_argument("--logs", action="append", default=[], metavar="GLOB|DIR",
                   help="log files to copy into the recording as they grow, each line a "
                        "foxglove.Log on foxglove/log (repeatable; a folder means its *.log; the "
                        "launcher's profiles pass '<run>/logs/*.log')")
    p.add_argument("--sim-epoch", default=None, metavar="TIME",
                   help="lockstep: the wall-clock time simulated time 0 is logged at, ISO 8601 "
                        "(2026-05-01T09:00:00Z) or Unix seconds (default: when the run started, "
                        "i.e. the --run file was written, else now; whole seconds)")
    return p


LATE_NS = 500_000_000
"""A sample received this long after it was published came from a publisher's cache (or waited
that long in a queue): logged at its publication time, and looked up among a predecessor's."""


def newest_recording(base: Path) -> Path | None:
    """The newest of ``base`` and its ``.restart-<k>`` siblings (``writer.free_path``) that exists:
    the recording a recorder restarted into the same run folder takes over from."""
    found = [p for p in [base, *base.parent.glob(f"{base.stem}.restart-*{base.suffix}")] if p.is_file()]
    return max(found, key=lambda p: p.stat().st_mtime_ns) if found else None


class SampleQueue:
    """Bounded hand-over from the bus's threads to the writer; overflow is counted, never blocks."""

    def __init__(self, capacity: int) -> None:
        self.capacity = capacity
        self.items: collections.deque[tuple[str, bytes, str, int]] = collections.deque()
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
        if len(self.items) >= self.capacity:
            with self._lock:
                self.dropped += 1
            return
        # A sample a publisher's cache gave late (to a recorder that restarted) is logged when it
        # was published, where it belongs on the timeline.
        self.items.append((sample.key, sample.payload, sample.encoding,
                           sample.published_ns if late else now_ns))
        if self.timeline is not None and "/lockstep/" in sample.key:
            # Its arrival, not when it is written (seaway.runtime.timeline: the recorder's "heard").
            stamp = stamp_of(sample.payload)
            if stamp is not None:
                self.timeline.mark("heard", stamp, sample.key.rsplit("/", 1)[1])
        if self.wake_on_any or "/lockstep/" in sample.key:
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


class LockstepWitness:
    """The recorder as a lockstep member (``seaway.runtime.lockstep``): it answers a period once
    every member's bundle for it is written (its messages on their own keys) and flushed to disk.

    So a SIGKILL never loses a period the sim has moved past; a restarted recorder catches up from the
    repeat its arrival causes. Repeats (the same bytes again on a key) are not written twice. A bundle
    carries every message its answer lists (``seaway.contract.bundle``), and its answer is noted
    after them: an answer noted is complete, there is nothing else to wait for.
    """

    def __init__(self, bus: Bus, vessel: str, exprs: Sequence[str]) -> None:
        self.member = Member(bus, "recorder", watched=(), subscribe=False, consumed=False)
        self.answer_keys = {keys.lockstep_spec(s).key(vessel) for s in LOCKSTEP_SERVICES if s != "recorder"}
        self.sim_key = keys.lockstep_spec("sim").key(vessel)
        self.prefix = f"{keys.ROOT}/{vessel}/"
        self._recent: dict[str, tuple[collections.deque[bytes], set[bytes]]] = \
            collections.defaultdict(lambda: (collections.deque(maxlen=REPEAT_MEMORY), set()))
        self._covered: dict[str, int] | None = None
        self.repeats_skipped = 0
        # A new episode repeats the old one's first messages byte for byte (deterministic): those
        # are new messages, to be written again.
        self.member.on_restart = lambda _before, _now: self._recent.clear()

    def heard(self, key: str, payload: bytes) -> PeriodDone | None:
        """The last sample a bus sample stands for (``RecordingWriter.unpack``: a bundle's answer),
        about to be written after the rest: the answer decoded if it is another member's (None: it
        is not, or it is malformed, which is logged and then written as malformed), so that neither
        the writer nor ``written`` decodes it again. A sim answer from a restarted world (another
        episode, or time gone back) forgets the payloads remembered first: the new episode's first
        messages repeat the old one's byte for byte, and come in its bundle before the answer that
        would tell the ledger (a sim killed at 12 s restarted without its t_0 in the recording)."""
        if key not in self.answer_keys:
            return None
        try:
            answer = PeriodDone.decode(payload)
        except MessageError as err:
            self.member.ratelog.warning(("malformed answer", key),
                                        "lockstep answer on %s ignored: %s", key, err)
            return None
        if key == self.sim_key and not answer.resent:
            with self.member.changed:
                current = self.member.ledger.period
            if classify(current, Period.of(answer)) == "restart":
                self._recent.clear()
        return answer

    def admit(self, key: str, payload: bytes) -> bool:
        """Whether to write this sample: not when it repeats bytes just written on its key."""
        if not key.startswith(self.prefix):
            return True
        recent, known = self._recent[key]
        if payload in known:
            self.repeats_skipped += 1
            return False
        if len(recent) == recent.maxlen:
            known.discard(recent[0])  # the one this append pushes out
        recent.append(payload)
        known.add(payload)
        return True

    def written(self, answers: list[tuple[str, PeriodDone]]) -> None:
        """Note the answers just written (or skipped as repeats of what was), after what they list."""
        for key, answer in answers:
            if not answer.resent:  # a copy of an earlier one: its messages are written, no news
                self.member.on_answer(key, answer)

    def lacking(self) -> bool:
        """Whether the writer must wake for every sample, not only for answers: before the first
        period (a bundle carries what its answer lists, so after that nothing is ever lacking)."""
        with self.member.changed:
            return self.member.ledger.period is None

    def covers(self) -> tuple[Period, int, dict[str, int]] | None:
        """(period, period_ns, covers) when the current period is all written, else None."""
        member = self.member
        with member.changed:
            ledger = member.ledger
            tick = ledger.answer("sim")
            if tick is None or not ledger.complete(tick):
                return None
            covers = {"sim": tick.seq}
            for m in tick.members:
                if m == "recorder":
                    continue
                ans = ledger.answer(m)
                if ans is None or not ledger.complete(ans):
                    return None
                covers[m] = ans.seq
            return Period.of(tick), tick.period_ns, covers

    def maybe_answer(self, writer: RecordingWriter) -> bool:
        """Flush and answer if the current period is complete and not yet answered as it is."""
        ready = self.covers()
        if ready is None or ready[2] == self._covered:
            return False
        period, period_ns, covers = ready
        writer.flush()  # on disk (the OS has it) before we say so
        self.member.answer(period, period_ns, covers=covers)
        self._covered = covers
        return True


REPEAT_MEMORY = 256
"""Payloads per key a lockstep recorder remembers, to write a repeat (the same bytes again) once. A
repeat carries what a member kept of its last periods (``lockstep.KEPT_PERIODS``); with the 32 of
before, a key of more than about ten samples a period was written twice when the sim repeated."""


def key_exprs(args: argparse.Namespace) -> list[str]:
    if args.key_expr:
        return list(args.key_expr)
    vessels = [v.strip() for v in args.vessels.split(",") if v.strip()]
    return [keys.vessel_wildcard(v) for v in vessels] or [keys.vessel_wildcard()]


def build_run_info(args: argparse.Namespace, exprs: list[str], run: RunDescription):
    """Attachments (the run description, its scenario, vessel files, ...) and metadata of a recording."""
    atts = [AttachmentSpec(runinfo.RUN_ATTACHMENT, "application/json", run.encode(), time.time_ns())]
    origin = None
    scenario_name = ""
    if run.scenario:
        s_atts, scenario = attachments.scenario_attachments(run.scenario, with_vessel=False)
        atts += s_atts
        scenario_name = scenario.name
    if run.origin is not None:
        origin = GeoOrigin.from_degrees(run.origin.lat_deg, run.origin.lon_deg, run.origin.alt_m)
    atts.append(attachments.attachment("vessel", runinfo.vessel_path(run.model_vessel_file)))
    if run.plant_vessel_file is not None:
        atts.append(attachments.attachment("plant-vessel", runinfo.vessel_path(run.plant_vessel_file)))
    if args.profile:
        atts.append(attachments.attachment("profile", runinfo.profile_path(args.profile)))
    if args.mission:
        atts.append(attachments.attachment("mission", Path(args.mission)))
    zcfg = args.zenoh_config or os.environ.get(ENV_CONFIG)
    if zcfg:
        atts.append(attachments.attachment("zenoh", Path(zcfg)))
    atts += [attachments.parse_attach_arg(a) for a in args.attach]
    meta = {
        "recorder": LIBRARY,
        "started_utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"),
        "host": socket.gethostname(),
        "key_exprs": ",".join(exprs),
        "scenario": scenario_name,
        "run_id": run.run_id,
        "control_period_s": f"{run.control_period_s:g}",
        "clock": run.clock,
        "profile": Path(args.profile).stem if args.profile else "",
        "flush_interval_s": f"{args.flush_interval:g}",
        "command": " ".join(sys.argv),
        "attachments": ",".join(a.name for a in atts),
        **parse_meta(args.meta),
    }
    return atts, {RUN_METADATA: meta}, origin


def recording_time(args: argparse.Namespace, run: RunDescription, now_ns: int) -> RecordingTime:
    """The recording's time convention (``timebase``): the run's clock and, in lockstep, its epoch:
    ``--sim-epoch``, else when the run started (the launcher writes ``--run`` then, and a restarted
    recorder reads the same file), else ``now_ns``; whole seconds."""
    if not run.lockstep:
        return RecordingTime.real_time()
    if args.sim_epoch:
        epoch_ns, source = parse_epoch(args.sim_epoch), "--sim-epoch"
    elif (started := runs.started_ns(args.run)) is not None:
        epoch_ns, source = started, f"run started ({args.run} written)"
    else:
        epoch_ns, source = now_ns, "recorder started"
    return RecordingTime(lockstep=True, epoch_ns=epoch_ns - epoch_ns % 1_000_000_000,
                         epoch_source=source, gap_ns=run.control_period_ns)


def run(argv: Sequence[str]) -> int:
    args = parser().parse_args(list(argv))
    if not 0 < args.flush_interval <= 0.1:
        raise SystemExit("seaway record: --flush-interval must be in (0, 0.1] s")
    exprs = key_exprs(args)
    run = resolve_run(args, "recorder", load_scenario)
    try:
        atts, meta, origin = build_run_info(args, exprs, run)
        rec_time = recording_time(args, run, time.time_ns())
    except (ConfigError, ValueError, OSError) as err:
        print(f"seaway record: {err}", file=sys.stderr)
        return 2
    writer = RecordingWriter(out_path(args.out), chunk_size=args.chunk_size, compression=args.compression,
                             max_bytes=args.max_bytes, max_seconds=args.max_seconds, attachments=atts,
                             metadata=meta, validate=not args.no_validate, foxglove=not args.no_foxglove,
                             default_origin=origin, time=rec_time)
    queue = SampleQueue(args.queue)
    # The recorder records whatever runs (a shore recorder sees a boat launched elsewhere), so it
    # does not take part in the run agreement; its run only describes the recording.
    with run_service("recorder", args, run=run, agree=False) as ctx:
        started_ns = time.time_ns()
        previous = None if run.lockstep or writer.rotating else newest_recording(writer.base)
        path = writer.open(started_ns)
        print(f"recording {', '.join(exprs)} to {path}", flush=True)
        # In lockstep the recorder is a member: the sim does not move on until it is on disk.
        witness = None
        kept = KeptKeys(exprs)
        if run.lockstep:
            exprs = lockstep_exprs(exprs, args.vessel)
            witness = LockstepWitness(ctx.bus, args.vessel, exprs)
            if witness.member.timeline.marks is not None:
                queue.timeline = witness.member.timeline
        if previous is not None:
            # Restarted into a run folder: what the publishers' caches give back that the
            # predecessor wrote already is not written twice; the time nothing can be asked for
            # is said in the file (schemas.RESTART_SCHEMA).
            asked_from_ns = started_ns - round(REJOIN_HISTORY_S * 1e9)
            tail = tail_of(previous, asked_from_ns - LATE_NS)
            queue.already = tail.messages
            writer.write_restart({
                "stamp_ns": started_ns, "previous_file": previous.name,
                "previous_last_ns": tail.last_log_ns, "asked_from_ns": asked_from_ns,
                "gap_unrecovered_s": max(0, asked_from_ns - tail.last_log_ns) / 1e9}, started_ns)
            log.info("restarted after %s (last message at %.3f s before this start): asking the "
                     "publishers for their last %.0f s", previous.name,
                     (started_ns - tail.last_log_ns) / 1e9, REJOIN_HISTORY_S)
        for e in exprs:
            # Real time: also what was published up to REJOIN_HISTORY_S before (the publishers'
            # caches), which a recorder restarted by the launcher was away for.
            ctx.bus.subscribe_raw(e, queue.on_sample, inline=run.lockstep,
                                  history_s=0.0 if run.lockstep else REJOIN_HISTORY_S)
        ctx.ready()
        if witness is not None:
            witness.member.join()
        print("READY", flush=True)
        tails = Tails(FileTail(args.events) if args.events else None,
                      LogTail(args.logs) if args.logs else None,
                      ctx.bus.publisher(keys.LOG_LINE).put if args.logs else None)
        try:
            _loop(writer, queue, ctx.stop, args.flush_interval, args.status_interval, witness, tails,
                  kept)
            queue.accepting = False
            _drain(writer, queue, limit=None, kept=kept)
            tails.copy(writer)
        except OSError as err:  # disk full, file removed, ...: finish what can be finished
            log.error("writing failed: %s; finishing the file", err)
            queue.accepting = False
            failed = True
        else:
            failed = False
        writer.count_dropped(queue.dropped - writer.stats.dropped)
        try:
            files = writer.close()
        except OSError as err:
            log.error("could not finish %s: %s (try 'seaway record recover')", writer.path, err)
            return 1
    summary = {"files": files, **writer.stats.as_metadata(), "by_topic": dict(writer.stats.by_topic),
               "repeats_not_written": queue.repeats}
    log.info("recorder finished: %s", writer.stats.line())
    print(f"recording finished: {', '.join(files)}", flush=True)
    print(json.dumps(summary), flush=True)
    return 1 if failed else 0


def _drain(writer: RecordingWriter, queue: SampleQueue, limit: int | None,
           witness: LockstepWitness | None = None, kept: KeptKeys | None = None) -> int:
    """Write up to ``limit`` queued samples (a lockstep bundle as the samples it stands for, those
    ``kept`` keeps); in lockstep, answer a period once it is on disk."""
    n = 0
    items = queue.items
    answers: list[tuple[str, PeriodDone]] = []
    while items and (limit is None or n < limit):
        sample_key, sample, sample_encoding, t_ns = items.popleft()
        n += 1
        copy = sample_encoding == bundle.ENCODING and bundle.is_resent(sample)
        samples = writer.unpack(sample_key, sample, sample_encoding, t_ns)
        answer = None  # the answer comes last, on the bundle's own key
        if witness is not None and samples and samples[-1][0] == sample_key:
            answer = witness.heard(sample_key, samples[-1][1])
        for key, payload, encoding in samples:
            if key != sample_key and kept is not None and not kept(key):
                continue  # a bundle's message on a key this recording leaves out
            decoded = answer if key == sample_key else None
            if decoded is not None:
                answers.append((key, decoded))  # a repeat not written again is on disk all the same
            if witness is not None and not witness.admit(key, payload):
                continue
            writer.write(key, payload, encoding, t_ns, copy, decoded=decoded)
    if witness is not None:
        witness.written(answers)
        witness.maybe_answer(writer)
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


def _loop(writer: RecordingWriter, queue: SampleQueue, stop: threading.Event, flush_s: float,
          status_s: float, witness: LockstepWitness | None = None,
          tails: Tails | None = None,
          kept: KeptKeys | None = None) -> None:
    flush_ns = int(flush_s * 1e9)
    next_flush = time.monotonic_ns() + flush_ns
    next_status = time.monotonic_ns() + int(status_s * 1e9)
    last_messages = 0
    while not stop.is_set():
        queue.arrived.clear()
        n = _drain(writer, queue, limit=2000, witness=witness, kept=kept)
        now = time.monotonic_ns()
        if now >= next_flush:
            writer.count_dropped(queue.dropped - writer.stats.dropped)
            if tails is not None:
                tails.copy(writer)
            writer.flush()
            writer.maybe_rotate(time.time_ns())
            next_flush = now + flush_ns
        if now >= next_status:
            rate = (writer.stats.messages - last_messages) / status_s
            last_messages = writer.stats.messages
            log.info("%s; %.0f msg/s; queue %d; file %s", writer.stats.line(), rate,
                     len(queue.items), writer.path)
            next_status = now + int(status_s * 1e9)
        if n == 0:
            # Nothing queued: wait for a sample (lockstep answers at once) or a little, never past
            # the next flush.
            timeout = min(0.005, max(0.0, (next_flush - time.monotonic_ns()) / 1e9))
            if witness is not None:
                queue.arrived.wait(timeout)
            else:
                stop.wait(timeout)


def cmd_recover(argv: Sequence[str]) -> int:
    p = argparse.ArgumentParser(prog="seaway record recover",
                                description="Rebuild a fully indexed MCAP file from a truncated one.")
    p.add_argument("input", type=Path, help="the truncated .mcap file (it is not changed)")
    p.add_argument("output", type=Path, nargs="?", default=None,
                   help="where to write the repaired file (default: INPUT with .recovered.mcap)")
    args = p.parse_args(list(argv))
    out = args.output or args.input.with_suffix(".recovered.mcap")
    try:
        res = recover(args.input, out)
    except (OSError, ValueError) as err:
        print(f"seaway record recover: {err}", file=sys.stderr)
        return 2
    print(f"{res.line()}\nwrote {out}")
    print(json.dumps({"output": str(out), "messages": res.messages, "chunks": res.chunks,
                      "complete": res.complete, "reason": res.reason, "topics": res.topics}))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    # First, before any thread: the recorder hears every message of the run on the transport's
    # threads for as long as it lasts, off the control path (seaway.runtime.memory says why).
    memory.cap_malloc_arenas()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "recover":
        configure_logging("recorder")
        return cmd_recover(argv[1:])
    if argv and argv[0] == "run":
        argv = argv[1:]
    return run(argv)


if __name__ == "__main__":
    raise SystemExit(main())
