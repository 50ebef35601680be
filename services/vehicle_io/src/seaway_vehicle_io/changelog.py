"""Lines saying that the autopilot's state changed (its mode and arming, its health, the hold
reason), written at once but never as a flood.

Each such line is news and is normally rare: an operator reads every one, in order, so
``RateLimitedLog``'s one line per key per interval would hide a second real change (armed, then
MANUAL a second later). An autopilot flapping its state at the rate it can send HEARTBEATs (one
locked, signed autopilot sending 10,000 a second, alternating two modes) would write a line per
message. So each key (the kind of change) writes up to ``burst`` lines per ``every_s`` at once; the
ones beyond are counted, and when the window ends (at the next line of that key or at ``flush``,
called from the core's tick) the latest of them is written with the count, at the most severe
level among them: the log always ends on the state the autopilot last said.

Pure: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

import logging
from collections.abc import Hashable
from dataclasses import dataclass

BURST = 10
"""Lines of one key written at once per window."""
EVERY_S = 5.0
"""The window [s]."""


@dataclass
class _Window:
    start_ns: int
    written: int = 0
    held: int = 0
    level: int = logging.NOTSET  # the most severe level held back
    latest: str = ""  # the latest line held back


class ChangeLog:
    """State-change lines, at most ``burst`` per key per ``every_s`` (see the module docstring)."""

    def __init__(self, logger: logging.Logger, burst: int = BURST, every_s: float = EVERY_S) -> None:
        if burst < 1 or not every_s > 0:
            raise ValueError("burst must be >= 1 and every_s > 0")
        self.logger = logger
        self.burst = burst
        self.every_ns = round(every_s * 1e9)
        self.held_total = 0
        self._windows: dict[Hashable, _Window] = {}

    def log(self, key: Hashable, level: int, text: str, now_ns: int) -> bool:
        """Write ``text`` at ``level`` unless ``burst`` lines of ``key`` were written in this
        window (then it is held back, counted). True if written."""
        w = self._windows.get(key)
        if w is not None and now_ns - w.start_ns >= self.every_ns:
            self._close(w)
            w = None
        if w is None:
            w = self._windows[key] = _Window(now_ns)
        if w.written < self.burst:
            w.written += 1
            self.logger.log(level, "%s", text)
            return True
        w.held += 1
        w.level = max(w.level, level)
        w.latest = text
        self.held_total += 1
        return False

    def flush(self, now_ns: int) -> None:
        """Close every window that has ended: its held-back lines become one, the latest."""
        for key in [k for k, w in self._windows.items() if now_ns - w.start_ns >= self.every_ns]:
            self._close(self._windows.pop(key))

    def _close(self, w: _Window) -> None:
        if w.held:
            self.logger.log(w.level, "%s (%d changes like it in %.0f s not logged one by one; "
                            "this is the latest)", w.latest, w.held, self.every_ns / 1e9)
