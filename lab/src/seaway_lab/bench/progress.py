"""A benchmark's progress on stderr, with the time it has taken and an estimate of what is left.

The one place for bench progress: stdout is the benchmark's table or JSON, so progress goes to
stderr, whether that is a terminal or not. On a terminal it is one line rewritten in place (at most
every ``REDRAW_S``); otherwise (a pipe, a CI log) a line per step the benchmark ends
(``Progress.step``), and one every ``HEARTBEAT_S`` within a long step, so that a log never stays
silent for minutes.

Work is counted in the benchmark's own units (``total``; ``done`` may be fractional, a part of a
step); the estimate of what is left assumes the rest goes at the pace so far (``eta_s``).
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from collections.abc import Callable
from typing import TextIO

REDRAW_S = 0.25
"""On a terminal: the shortest time between two rewrites of the line [s]."""

HEARTBEAT_S = 30.0
"""Not on a terminal: the longest time without a line while a step runs [s]."""


def eta_s(done: float, total: float, elapsed_s: float) -> float | None:
    """Seconds left if the remaining ``total - done`` units go at the pace of the ``done`` ones in
    ``elapsed_s``; None before any unit is done (no pace yet), 0 when all are."""
    if done >= total:
        return 0.0
    if done <= 0 or elapsed_s <= 0:
        return None
    return elapsed_s * (total - done) / done


def duration_text(seconds: float | None) -> str:
    """A duration for a person: ``42 s``, ``3 min 05 s``, ``1 h 02 min`` ('?' for None)."""
    if seconds is None:
        return "?"
    s = round(max(seconds, 0.0))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


class Progress:
    """The progress of ``total`` units of work, shown on ``out`` (default stderr).

    ``show(done, text)`` as work goes on, ``step(done, text)`` when a step ends (not on a terminal:
    the line printed), ``close()`` at the end. ``enabled`` False shows nothing (``--no-progress``)."""

    def __init__(
        self,
        total: float,
        enabled: bool = True,
        out: TextIO | None = None,
        clock: Callable[[], float] = time.monotonic,
        tty: bool | None = None,
    ) -> None:
        self.total = max(float(total), 1e-9)
        self.enabled = enabled
        self.out = out or sys.stderr
        self.tty = self.out.isatty() if tty is None else tty
        self.clock = clock
        self.start = clock()
        self._last_line = self.start  # when a line was last written (both kinds of output)
        self._drawn = False

    def line(self, done: float, text: str) -> str:
        """``37% ETA 1 min 45 s (1 min 02 s elapsed) | text``: the estimate first, so that a line
        cut to a narrow terminal keeps it."""
        elapsed = self.clock() - self.start
        pct = 100.0 * min(max(done, 0.0), self.total) / self.total
        return (
            f"{pct:3.0f}% ETA {duration_text(eta_s(done, self.total, elapsed))} "
            f"({duration_text(elapsed)} elapsed) | {text}"
        )

    def show(self, done: float, text: str) -> None:
        """Work goes on: on a terminal the line is rewritten (at most every ``REDRAW_S``); else a
        line only if none was written for ``HEARTBEAT_S``."""
        if not self.enabled:
            return
        if self.clock() - self._last_line >= (REDRAW_S if self.tty else HEARTBEAT_S):
            self._write(self.line(done, text))

    def step(self, done: float, text: str) -> None:
        """A step ended: the line is written now, on a terminal or not."""
        if self.enabled:
            self._write(self.line(done, text))

    def close(self) -> None:
        """On a terminal, clear the line (the table follows on stdout)."""
        if self.enabled and self.tty and self._drawn:
            self.out.write("\r\033[K")
            self.out.flush()
            self._drawn = False

    def _write(self, text: str) -> None:
        self._last_line = self.clock()
        if self.tty:  # within the width: a wrapped line would leave a row behind at each rewrite
            self.out.write("\r" + text[: self._columns() - 1] + "\033[K")
            self._drawn = True
        else:
            self.out.write(text + "\n")
        self.out.flush()

    def _columns(self) -> int:
        try:
            return os.get_terminal_size(self.out.fileno()).columns
        except (OSError, ValueError, AttributeError):
            return shutil.get_terminal_size().columns
