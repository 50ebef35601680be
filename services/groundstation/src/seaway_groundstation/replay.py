"""A recording cut into the live stream's frames, so the page draws live and recorded data with the
same code (pure: messages in, frames out; no files, no clock).

The recorded messages of the kinds the ground station shows (``gateway.TOPICS``) go, in log-time
order, into a ``Fleet`` of their own with the log time as the receive time, and every
``1 / rate_hz`` of recorded time the frames the live stream would have sent then are taken from it
(``Fleet.changes``: per vessel, the latest of each kind that changed). So a replayed frame is
exactly a live frame, with its time ``t_s`` from the start of the recording; ages and the stale
flag are those a live client would have seen (a gap in the recording shows as stale).

Since a frame carries only the latest message of each kind, a ``Cutter`` fed raw messages decodes
only the last of each kind and vessel in each period (and an earlier one if that one does not
decode): a recording logged faster than the frame rate costs one decode per kind per frame.
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

from seaway.contract.messages import Message

from seaway_groundstation.fleet import Fleet, Kind


@dataclass(frozen=True)
class ReplayFrame:
    t_s: float
    """Recorded time of the frame since the recording's start [s]."""
    frame: str
    """The frame's JSON text, as the live stream sends it."""


def _as_message(_kind: Kind, msg: Any) -> Message | None:
    return msg


class Cutter:
    """Frames of messages fed in log-time order (``add``), cut every ``1 / rate_hz`` of recorded
    time since ``start_ns``, each timed at the end of its period. ``decode(kind, payload)``: the
    message of a payload as fed, None when it does not decode (counted in ``undecodable``)."""

    def __init__(self, start_ns: int, rate_hz: float, stale_after_s: float,
                 decode: Callable[[Kind, Any], Message | None] = _as_message) -> None:
        if rate_hz <= 0:
            raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
        self.start_ns, self.decode = start_ns, decode
        self.period_ns = max(1, round(1e9 / rate_hz))
        self.fleet = Fleet(stale_after_s)
        self.undecodable = 0
        self._seen: dict[tuple[str, str], int] = {}
        self._cut_ns: int | None = None
        # (vessel, kind) -> [(t_ns, payload)] of the current period, in log-time order
        self._pending: dict[tuple[str, Kind], list[tuple[int, Any]]] = {}

    def _emit(self) -> list[ReplayFrame]:
        assert self._cut_ns is not None
        for (vessel, kind), items in sorted(self._pending.items(), key=lambda kv: kv[1][-1][0]):
            for t_ns, payload in reversed(items):  # the latest that decodes
                msg = self.decode(kind, payload)
                if msg is not None:
                    self.fleet.on_message(vessel, kind, msg, t_ns / 1e9)
                    break
                self.undecodable += 1
        self._pending.clear()
        t_s = self._cut_ns / 1e9
        self._cut_ns = None
        return [ReplayFrame(t_s, f) for f in self.fleet.changes(self._seen, None, t_s)]

    def add(self, log_ns: int, vessel: str, kind: Kind, payload: Any) -> list[ReplayFrame]:
        """Feed one message; the frames it completes (those of the periods before it)."""
        t_ns = max(0, log_ns - self.start_ns)
        out = self._emit() if self._cut_ns is not None and t_ns >= self._cut_ns else []
        if self._cut_ns is None:
            self._cut_ns = (t_ns // self.period_ns + 1) * self.period_ns
        self._pending.setdefault((vessel, kind), []).append((t_ns, payload))
        return out

    def advance(self, horizon_ns: int) -> list[ReplayFrame]:
        """Every message logged before ``horizon_ns`` (log time) has been fed: the frame of a
        period that ends by then is complete."""
        t_ns = horizon_ns - self.start_ns
        return self._emit() if self._cut_ns is not None and self._cut_ns <= t_ns else []

    def finish(self) -> list[ReplayFrame]:
        """Every message has been fed: the last frame."""
        return self._emit() if self._cut_ns is not None else []


def cut_frames(messages: Iterable[tuple[int, str, Kind, Message]], start_ns: int, rate_hz: float,
               stale_after_s: float) -> list[ReplayFrame]:
    """Frames of ``(log_time_ns, vessel, kind, message)`` in log-time order, at most ``rate_hz``
    per second of recorded time, each timed at the end of its period since ``start_ns``."""
    cutter = Cutter(start_ns, rate_hz, stale_after_s)
    out: list[ReplayFrame] = []
    for log_ns, vessel, kind, msg in messages:
        out += cutter.add(log_ns, vessel, kind, msg)
    return out + cutter.finish()


def window(frames: list[ReplayFrame], start_s: float, end_s: float,
           times: list[float] | None = None) -> tuple[str, int]:
    """The frames with ``start_s <= t_s < end_s`` as a JSON array text of ``{"t_s", "frame"}``, and
    how many there are (the texts are joined, not parsed again). ``times``: the frames' ``t_s``,
    if the caller keeps them."""
    times = times if times is not None else [f.t_s for f in frames]
    lo, hi = bisect.bisect_left(times, start_s), bisect.bisect_left(times, end_s)
    parts = [f'{{"t_s":{json.dumps(f.t_s)},"frame":{f.frame}}}' for f in frames[lo:hi]]
    return "[" + ",".join(parts) + "]", hi - lo
