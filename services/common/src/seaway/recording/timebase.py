"""The time a recording's messages are logged at: the one convention (pure; no clock read here).

* **Real time** (``clock = "wall"``): a message's MCAP log time is when the recorder received it
  (wall clock, ns since the Unix epoch), as before; its ``stamp_ns`` is wall time too, so a derived
  Foxglove message's own ``timestamp`` is its source's ``stamp_ns`` unchanged.
* **Lockstep**: a message's log time is its simulated time on the run's **epoch**,
  ``epoch_ns + stamp_ns`` (``stamp_ns`` stays sim time from zero inside the bytes), so Foxglove's
  timeline, plots and dates read as in a real-time recording of the same run, and a derived
  Foxglove message's ``timestamp`` is that same instant. What is not stamped in sim time (a log
  line, a launcher event, a message from a process not on the sim clock) is logged at the simulated
  time the run had reached when it happened: its wall time is mapped through the recorder's own
  receipt of sim-stamped samples (``anchor``). A new lockstep episode (a scenario loaded, time back
  to 0) continues the timeline: its offset is the previous episode's end plus one period.

The publish time of every message stays the wall time it was received at, so nothing about the
machine's own timing is lost (``seaway bench`` and gap checks can use it).

The epoch: ``--sim-epoch`` (a scenario's start time, when one is given), else the time the run
started (the launcher's run description file is written then; a restarted recorder reads the same
file, so every file of a run shares one epoch), else the recorder's start; whole seconds. It is
stored in each file's ``seaway.time`` metadata record (``TIME_METADATA``).
"""

from __future__ import annotations

import bisect
import collections
import datetime as dt
import functools
import re

from seaway.contract import keys
from seaway.runtime.stamps import LOCKSTEP_AHEAD_PERIODS

TIME_METADATA = "seaway.time"
"""Metadata record: ``log_time`` (``receive`` or ``sim``), ``epoch_ns``, ``epoch_utc``,
``epoch_source``."""
EPISODE_METADATA = "seaway.time.episode-{index}"
"""Metadata record written when a lockstep episode starts after the first: its ``offset_ns``
(log time = ``offset_ns + stamp_ns``) and ``episode`` index."""

LOG_TIME_RECEIVE = "receive"
LOG_TIME_SIM = "sim"

SIM_STAMP_LIMIT_NS = 10**17
"""A lockstep stamp at or above this (about 3.2 years of simulated time) is a wall-clock stamp of a
process that is not on the sim clock: no lockstep run is that long, and every wall time since 1973
is above it."""

ANCHORS = 20_000
"""(wall, log) pairs kept to place wall-timed records: one per simulated period heard, so about
2000 s of simulated time at 0.1 s, far more than a log line or event can lag."""

_STAMP = re.compile(rb'"stamp_ns":\s*(\d+)')


def stamp_of(payload: bytes) -> int | None:
    """A message's ``stamp_ns`` read from its JSON bytes without decoding them (it is the first
    field every message writes; None if it is not there)."""
    m = _STAMP.search(payload, 0, 64)
    return int(m.group(1)) if m is not None else None


@functools.lru_cache(maxsize=1024)
def _sim_produced(key: str) -> bool:
    """Whether the sim publishes on ``key`` (asked of every sample a lockstep recorder writes)."""
    spec = keys.spec_for_key(key)
    return spec is not None and (spec.producer == "sim" or "sim" in spec.also)


def utc_text(t_ns: int) -> str:
    return dt.datetime.fromtimestamp(t_ns / 1e9, dt.UTC).isoformat(timespec="milliseconds")


def parse_epoch(text: str) -> int:
    """``--sim-epoch``: ISO 8601 (``2026-05-01T09:00:00Z``; no zone means UTC) or Unix seconds;
    returns ns since the Unix epoch. ValueError names what is allowed."""
    t = text.strip()
    try:
        return round(float(t) * 1e9)
    except ValueError:
        pass
    try:
        when = dt.datetime.fromisoformat(t.replace("Z", "+00:00"))
    except ValueError:
        raise ValueError(f"--sim-epoch {text!r}: give an ISO 8601 time (2026-05-01T09:00:00Z) or "
                         "Unix seconds") from None
    if when.tzinfo is None:
        when = when.replace(tzinfo=dt.UTC)
    return round(when.timestamp() * 1e9)


class RecordingTime:
    """Log times of one recording (see the module's text). ``lockstep``: sim time on ``epoch_ns``;
    ``gap_ns``: the control period (the step between one episode's end and the next's start)."""

    def __init__(self, lockstep: bool = False, epoch_ns: int = 0, epoch_source: str = "",
                 gap_ns: int = 100_000_000) -> None:
        if epoch_ns < 0:
            raise ValueError(f"epoch_ns must be >= 0, got {epoch_ns}")
        self.lockstep = lockstep
        self.epoch_ns = epoch_ns
        self.epoch_source = epoch_source
        self.gap_ns = gap_ns
        self.offset_ns = epoch_ns if lockstep else 0
        """Added to a sim stamp for the current episode's log time."""
        self.episode = 0
        self._episode_max_ns = 0
        """The newest sim stamp of the episode [ns] (only the sim's samples move it)."""
        self._last_sim: dict[str, int] = {}
        self._anchor_wall: collections.deque[int] = collections.deque(maxlen=ANCHORS)
        self._anchor_log: collections.deque[int] = collections.deque(maxlen=ANCHORS)
        self.new_episodes: list[dict[str, str]] = []
        """Episode records to write as metadata (the writer takes them)."""

    @classmethod
    def real_time(cls) -> RecordingTime:
        return cls(lockstep=False)

    def metadata(self) -> dict[str, str]:
        if not self.lockstep:
            return {"log_time": LOG_TIME_RECEIVE, "epoch_ns": "0", "epoch_utc": "",
                    "epoch_source": "", "convention": "log time = wall-clock receive time; "
                    "stamp_ns is wall-clock time"}
        return {"log_time": LOG_TIME_SIM, "epoch_ns": str(self.epoch_ns),
                "epoch_utc": utc_text(self.epoch_ns), "epoch_source": self.epoch_source,
                "convention": "log time = epoch_ns + stamp_ns (sim time from 0); publish time = "
                              "wall-clock receive time; later episodes: seaway.time.episode-<k>"}

    # -- the three kinds of time ----------------------------------------------------------------

    def bus(self, key: str, stamp_ns: int | None, receive_ns: int, copy: bool = False) -> int:
        """The log time of a bus sample stamped ``stamp_ns`` (None: no stamp found), received at
        ``receive_ns`` (wall). ``copy``: it came in a lockstep bundle sent again for a restarted
        recorder (``resent``), stamped up to two periods before what this recorder may have
        written: its own time in this episode, never the sign of a new one. (Every repeat of the
        sim for another member made a live recorder start an episode there, shifting every later
        log time by the time flown so far.)"""
        if not self.lockstep:
            return receive_ns
        if stamp_ns is None or stamp_ns >= SIM_STAMP_LIMIT_NS:
            return self.wall(receive_ns)
        if copy:
            return self.offset_ns + stamp_ns
        if not _sim_produced(key):
            # A member's message is stamped with a period the sim has published, at most
            # LOCKSTEP_AHEAD_PERIODS ahead of the newest sim sample heard (bundles come on
            # different connections). A stamp beyond is no sim time (an insider's absurd stamp,
            # 3 years ahead): logged at the time reached, and it moves neither the episode's end,
            # which offsets every later episode, nor the anchors that place wall-timed records.
            if stamp_ns > self._episode_max_ns + LOCKSTEP_AHEAD_PERIODS * self.gap_ns:
                return self.wall(receive_ns)
            return self.offset_ns + stamp_ns
        last = self._last_sim.get(key)
        if last is not None and stamp_ns < last:
            self._new_episode()
        self._last_sim[key] = stamp_ns
        self._episode_max_ns = max(self._episode_max_ns, stamp_ns)
        log_ns = self.offset_ns + stamp_ns
        if not self._anchor_log or log_ns > self._anchor_log[-1]:
            self._anchor_wall.append(receive_ns)
            self._anchor_log.append(log_ns)
        return log_ns

    def foxglove_ns(self, stamp_ns: int) -> int:
        """A derived Foxglove message's ``timestamp`` [ns since the Unix epoch] for a source
        stamped ``stamp_ns``: the same instant as its log time."""
        if not self.lockstep or stamp_ns >= SIM_STAMP_LIMIT_NS:
            return stamp_ns
        return self.offset_ns + stamp_ns

    def wall(self, wall_ns: int) -> int:
        """The log time of something that happened at ``wall_ns`` (wall clock): itself in real
        time; in lockstep the simulated time reached by then (the epoch before the sim starts)."""
        if not self.lockstep:
            return wall_ns
        i = bisect.bisect_right(self._anchor_wall, wall_ns)
        # Before the first sim sample heard: the episode's start (the epoch at first).
        return self._anchor_log[i - 1] if i else self.offset_ns

    def _new_episode(self) -> None:
        self.offset_ns += self._episode_max_ns + self.gap_ns
        self.episode += 1
        self._episode_max_ns = 0
        self._last_sim.clear()
        self.new_episodes.append({"episode": str(self.episode), "offset_ns": str(self.offset_ns),
                                  "offset_utc": utc_text(self.offset_ns)})
