"""``seaway replay FILE``: republish a recording on Zenoh, at its pace, faster, or as fast as possible.

Only bus topics (``seaway/...``) are republished; the recorder's own channels (``foxglove/...``,
``recorder/malformed``) are not. ``--only`` and ``--exclude`` take key expressions (``seaway/*/sim/truth``,
or the short form ``sim/truth`` for every vessel) so that a live service can produce the keys left out:
feed recorded sensors to a live estimator with ``--exclude nav/state``, recorded states to a live
controller with ``--only nav/state``. Each sample goes out with its recorded bytes and encoding,
in recorded order; with ``--rate X`` the gaps between receive times are divided by X; ``--fast`` does not
wait at all (publishers block rather than drop, so nothing is lost). ``--lockstep`` replays a lockstep
recording as its sim would: each period waits for the live members' answers
(``seaway.runtime.lockstep_replay``), so live services get every period, as fast as they go.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field

import zenoh
from seaway.contract import bundle, keys
from seaway.contract.messages import JSON_ENCODING, MessageError, PeriodDone
from seaway.recording import reader
from seaway.runtime.argtypes import non_negative_float, positive_float
from seaway.runtime.bus import Bus
from seaway.runtime.bus_raw import RawPublisher
from seaway.runtime.credentials import ENV_IDENTITY
from seaway.runtime.lockstep_replay import SIM_ANSWER_SUFFIX, LockstepPacer
from seaway.runtime.node import Period
from seaway.runtime.service import (
    DEFAULT_VESSEL,
    add_log_level_option,
    add_zenoh_config_option,
    configure_logging,
    install_stop_signals,
)

BUS_ROOT = f"{keys.ROOT}/"

log = logging.getLogger("seaway_recorder.replay")


def normalise(expr: str) -> str:
    """``sim/truth`` -> ``seaway/*/sim/truth``; full key expressions are kept."""
    return expr if expr.startswith(BUS_ROOT) or expr.startswith("**") else f"{BUS_ROOT}*/{expr}"


class KeyFilter:
    """Which recorded topics to republish: bus topics, within ``only`` (if any), outside ``exclude``."""

    def __init__(self, only: Iterable[str] = (), exclude: Iterable[str] = ()) -> None:
        self.only = [zenoh.KeyExpr(normalise(e)) for e in only]
        self.exclude = [zenoh.KeyExpr(normalise(e)) for e in exclude]
        self._cache: dict[str, bool] = {}

    def __call__(self, topic: str) -> bool:
        ok = self._cache.get(topic)
        if ok is None:
            ok = self._decide(topic)
            self._cache[topic] = ok
        return ok

    def _decide(self, topic: str) -> bool:
        if not topic.startswith(BUS_ROOT):
            return False
        try:
            k = zenoh.KeyExpr(topic)
        except Exception:  # not a valid key expression: it cannot have come from the bus
            return False
        if self.only and not any(e.intersects(k) for e in self.only):
            return False
        return not any(e.intersects(k) for e in self.exclude)


@dataclass
class ReplayStats:
    published: int = 0
    skipped: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)
    max_late_s: float = 0.0
    elapsed_s: float = 0.0
    recorded_span_s: float = 0.0
    periods: int = 0
    """Lockstep: recorded periods every live member answered."""
    error: str | None = None
    """Why the replay stopped before the recording's end (a damaged chunk), or None."""


def replay(messages: Iterator[reader.RecordedMessage], bus: Bus, keep: KeyFilter,
           rate: float | None, stop: threading.Event, clock=time.monotonic,
           pacer: LockstepPacer | None = None) -> ReplayStats:
    """Publish ``messages`` (in log-time order) on ``bus``, paced by their log times (``rate``; None:
    no waiting) or, with ``pacer``, by the live lockstep members' answers to each recorded sim answer
    of ``bus.vessel`` (which the pacer sends, naming the live members); returns what was done. Bytes
    and encodings go out as recorded: nothing else is decoded here. A recording that cannot be read
    to its end (``reader.UnreadableRecordingError``) ends the replay there, said in ``error``: what
    was read before it has been published."""
    stats = ReplayStats()
    pubs: dict[str, RawPublisher] = {}
    start_wall: float | None = None
    t0_log: int | None = None
    last_log = 0
    clock_key = f"{BUS_ROOT}{bus.vessel}/{SIM_ANSWER_SUFFIX}"
    period: list[reader.RecordedMessage] = []  # lockstep: kept since the last sim answer
    # lockstep: the answer to play next, with its other samples' publication and its bundle lines
    pending: tuple[PeriodDone, Callable[[], None], list[tuple[str, bytes]]] | None = None

    def put(m: reader.RecordedMessage) -> None:
        pub = pubs.get(m.topic)
        if pub is None:
            enc = m.channel_metadata.get("zenoh_encoding") or (
                f"{JSON_ENCODING};{m.schema_name}" if m.schema_name else JSON_ENCODING)
            pub = bus.raw_publisher(m.topic, enc, block=True)
            pubs[m.topic] = pub
        pub.put(m.data)

    def publish(batch: list[reader.RecordedMessage]) -> None:
        for m in batch:
            put(m)

    sim_prefix = f"{BUS_ROOT}{bus.vessel}/"

    def bundled(batch: list[reader.RecordedMessage]
                ) -> tuple[list[tuple[str, bytes]], list[reader.RecordedMessage]]:
        """A period's recorded samples as (the sim's bundle lines, the rest): a lockstep sim sends
        its messages in its bundle (``seaway.contract.bundle``), and so does its replay."""
        lines, rest = [], []
        for m in batch:
            spec = keys.spec_for_key(m.topic) if m.topic.startswith(sim_prefix) else None
            if spec is not None and bundle.bundled_by(spec) == "sim":
                lines.append((spec.suffix, m.data))
            else:
                rest.append(m)
        return lines, rest

    def count(batch: list[reader.RecordedMessage]) -> None:
        for m in batch:
            stats.published += 1
            stats.by_topic[m.topic] = stats.by_topic.get(m.topic, 0) + 1

    for m in _readable(messages, stats):
        if stop.is_set():
            break
        if not keep(m.topic):
            stats.skipped += 1
            continue
        if pacer is not None and m.topic == clock_key and bundle.is_resent(m.data):
            # A copy of an earlier answer, sent again for a restarted recorder: no period of its
            # own (played, it was a period no member takes, sent again for ever).
            stats.skipped += 1
            continue
        if t0_log is None:
            t0_log = m.log_time_ns
            start_wall = clock()
        last_log = m.log_time_ns
        if pacer is not None:
            period.append(m)
            if m.topic != clock_key:
                continue
            batch, period = period, []
            count(batch)
            try:
                answer = PeriodDone.decode(m.data)
            except MessageError as err:  # a damaged answer closes no period: sent as it is
                log.warning("recorded lockstep answer at log time %d is malformed (%s): sent "
                            "without waiting for the members", m.log_time_ns, err)
                answer = None
            # A period is played once the recording's next answer is known: the controller's hold
            # (no mission yet) is waited past only where the recording goes on to a later period;
            # where it repeats the period or ends, the hold is the mission's end.
            if pending is not None:
                repeated = answer is not None and Period.of(answer) == Period.of(pending[0])
                if not pacer.play(*pending, hold_ends=repeated):
                    pending = None
                    break
            pending = None
            if answer is None:
                publish(batch)
            else:
                lines, rest = bundled(batch[:-1])
                pending = (answer, lambda b=rest: publish(b), lines)
            continue
        if rate is not None:
            due = start_wall + (m.log_time_ns - t0_log) / 1e9 / rate  # type: ignore[operator]
            delay = due - clock()
            if delay > 0:
                if stop.wait(delay):
                    break
            else:
                stats.max_late_s = max(stats.max_late_s, -delay)
        put(m)
        count([m])
    if pending is not None and not stop.is_set():
        pacer.play(*pending, hold_ends=True)  # type: ignore[union-attr]
    if period and not stop.is_set():  # after the last answer: nothing waits for these
        publish(period)
        count(period)
    if pacer is not None:
        stats.periods = pacer.periods
    if start_wall is not None:
        stats.elapsed_s = clock() - start_wall
        stats.recorded_span_s = (last_log - (t0_log or last_log)) / 1e9
    for p in pubs.values():
        p.undeclare()
    return stats


def _readable(messages: Iterator[reader.RecordedMessage], stats: ReplayStats
              ) -> Iterator[reader.RecordedMessage]:
    """``messages`` until one cannot be read: its error goes into ``stats.error``."""
    try:
        yield from messages
    except reader.UnreadableRecordingError as err:
        stats.error = str(err)


def lockstep_vessel(info: reader.RecordingInfo, keep: KeyFilter) -> str:
    """The one vessel whose recorded sim answers are kept: the lockstep replay's clock.

    Raises ValueError when there is none (not a lockstep recording, or the answers filtered out) or
    several (a fleet recording: pick one with ``--only seaway/<vessel>/...``)."""
    vessels = sorted({t.split("/")[1] for t in info.topics
                      if t.startswith(BUS_ROOT) and t.endswith(f"/{SIM_ANSWER_SUFFIX}") and keep(t)
                      and t.count("/") == 3})
    if not vessels:
        raise ValueError(f"--lockstep needs the sim's lockstep answers ({SIM_ANSWER_SUFFIX}), and "
                         "none are kept: the recording was not made in lockstep, or --only/--exclude "
                         "leave them out (use --rate or --fast)")
    if len(vessels) > 1:
        raise ValueError(f"--lockstep paces one vessel, and the recording has lockstep answers of "
                         f"{', '.join(vessels)}: keep one with --only {BUS_ROOT}<vessel>/...")
    return vessels[0]


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="seaway replay", description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="+", help="recording file(s) or folder(s)")
    pace = p.add_mutually_exclusive_group()
    pace.add_argument("--rate", type=positive_float, default=1.0,
                      help="speed-up factor (default 1: original pace)")
    pace.add_argument("--fast", action="store_true", help="as fast as possible")
    pace.add_argument("--lockstep", action="store_true",
                      help="a lockstep recording, each period held until the live estimator, "
                           "controller and recorder have answered it (as fast as they go; nothing "
                           "lost)")
    p.add_argument("--only", action="append", default=[], metavar="KEYEXPR",
                   help=f"republish only these keys (repeatable; '{keys.SIM_TRUTH.suffix}' means "
                        f"{keys.SIM_TRUTH.wildcard()})")
    p.add_argument("--exclude", action="append", default=[], metavar="KEYEXPR",
                   help="do not republish these keys: a live service produces them (repeatable)")
    p.add_argument("--wait", type=non_negative_float, default=1.0,
                   help="seconds to wait after joining the bus before the first sample (default 1)")
    add_zenoh_config_option(p)
    add_log_level_option(p)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(list(sys.argv[1:] if argv is None else argv))
    configure_logging("replay", args.log_level)
    vessel = DEFAULT_VESSEL
    try:
        files = reader.open_paths(args.files)
        keep = KeyFilter(args.only, args.exclude)
        info = reader.read_info(files)
        notes = reader.repaired(info)
        if args.lockstep:
            vessel = lockstep_vessel(info, keep)
    except (FileNotFoundError, ValueError) as err:
        print(f"seaway replay: {err}", file=sys.stderr)
        return 2
    for note in notes:
        print(f"seaway replay: NOTE: {note}", file=sys.stderr)
    stop = threading.Event()
    install_stop_signals(stop)
    # Raw publishing ignores the bus's vessel (recorded keys name their own); in lockstep it is the
    # vessel whose members pace the replay. A replay publishes what the recorded producers did: its
    # own identity, which the access rules let stand in for them (a launcher profile may name it
    # otherwise through the environment).
    bus = Bus.open(vessel, args.zenoh_config, identity=os.environ.get(ENV_IDENTITY) or "replay")
    try:
        pacer = LockstepPacer(bus, stop) if args.lockstep else None
        pace = ("in lockstep with the live members of " + vessel if args.lockstep
                else "as fast as possible" if args.fast else f"rate {args.rate:g}")
        print(f"replaying {', '.join(map(str, files))} ({pace})", flush=True)
        stop.wait(args.wait)
        stats = replay(reader.iter_messages(files), bus, keep,
                       None if args.fast or args.lockstep else args.rate, stop, pacer=pacer)
    finally:
        bus.close()
    lockstep = ({"periods": stats.periods, "repeats": pacer.repeats, "holds": pacer.holds}
                if pacer is not None else {})
    print(json.dumps({"published": stats.published, "skipped": stats.skipped, **lockstep,
                      "elapsed_s": round(stats.elapsed_s, 3),
                      "recorded_span_s": round(stats.recorded_span_s, 3),
                      "max_late_s": round(stats.max_late_s, 4), "by_topic": stats.by_topic,
                      **({"error": stats.error} if stats.error else {})}), flush=True)
    if stats.error:
        print(f"seaway replay: stopped after {stats.published} messages "
              f"({stats.recorded_span_s:.3f} s of the recording) were published: {stats.error}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
