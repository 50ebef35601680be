"""A recording cut into the live stream's frames, so the page draws live and recorded data with the
same code (pure: messages in, frames out; no files, no clock).

The recorded messages of the kinds the ground station shows (``gateway.TOPICS``) go, in log-time
order, into a ``Fleet`` of their own with the log time as the receive time, and every
``1 / rate_hz`` of recorded time the frames the live stream would have sent then are taken from it
(``Fleet.changes``: per vessel, the latest of each kind that changed). So a replayed frame is
exactly a live frame, with its time ``t_s`` from the start of the recording; ages and the stale
flag are those a live client would have seen (a gap in the recording shows as stale).
"""

from __future__ import annotations

import bisect
import json
from collections.abc import Iterable
from dataclasses import dataclass

from seaway.contract.messages import Message

from seaway_groundstation.fleet import Fleet, Kind


@dataclass(frozen=True)
class ReplayFrame:
    t_s: float
    """Recorded time of the frame since the recording's start [s]."""
    frame: str
    """The frame's JSON text, as the live stream sends it."""


def cut_frames(messages: Iterable[tuple[int, str, Kind, Message]], start_ns: int, rate_hz: float,
               stale_after_s: float) -> list[ReplayFrame]:
    """Frames of ``(log_time_ns, vessel, kind, message)`` in log-time order, at most ``rate_hz``
    per second of recorded time, each timed at the end of its period since ``start_ns``."""
    if rate_hz <= 0:
        raise ValueError(f"rate_hz must be > 0, got {rate_hz}")
    period_ns = max(1, round(1e9 / rate_hz))
    fleet = Fleet(stale_after_s)
    seen: dict[tuple[str, str], int] = {}
    out: list[ReplayFrame] = []
    cut_ns: int | None = None

    def emit(at_ns: int) -> None:
        t_s = at_ns / 1e9
        out.extend(ReplayFrame(t_s, f) for f in fleet.changes(seen, None, t_s))

    for log_ns, vessel, kind, msg in messages:
        t_ns = max(0, log_ns - start_ns)
        if cut_ns is not None and t_ns >= cut_ns:
            emit(cut_ns)
            cut_ns = None
        if cut_ns is None:
            cut_ns = (t_ns // period_ns + 1) * period_ns
        fleet.on_message(vessel, kind, msg, t_ns / 1e9)
    if cut_ns is not None:
        emit(cut_ns)
    return out


def window(frames: list[ReplayFrame], start_s: float, end_s: float,
           times: list[float] | None = None) -> tuple[str, int]:
    """The frames with ``start_s <= t_s < end_s`` as a JSON array text of ``{"t_s", "frame"}``, and
    how many there are (the texts are joined, not parsed again). ``times``: the frames' ``t_s``,
    if the caller keeps them."""
    times = times if times is not None else [f.t_s for f in frames]
    lo, hi = bisect.bisect_left(times, start_s), bisect.bisect_left(times, end_s)
    parts = [f'{{"t_s":{json.dumps(f.t_s)},"frame":{f.frame}}}' for f in frames[lo:hi]]
    return "[" + ",".join(parts) + "]", hi - lo
