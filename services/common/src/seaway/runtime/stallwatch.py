"""A watch on a real-time loop's step: a step still running long after it should have ended is
logged, with where the loop's thread is, while it is still stuck.

A step that takes longer than the period can be named after it returns (the caller times it); a step
that does not return for seconds cannot, and a process restarted for it (the launcher's liveness)
leaves nothing in its log that says why. ``StallWatch`` runs a thread of its own: the loop calls
``begin`` and ``end`` around each step; a step running for more than ``after_s`` is logged once as
a WARNING with the loop thread's current stack (``sys._current_frames``), and again with the time
it took when it ends. Time is monotonic; the thread checks every ``after_s / 2``.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
import traceback


class StallWatch:
    """Logs a step of ``what`` that runs longer than ``after_s`` [s], with the loop's stack."""

    def __init__(self, log: logging.Logger, what: str, after_s: float, stop: threading.Event) -> None:
        if not after_s > 0:
            raise ValueError(f"after_s must be > 0 s, got {after_s}")
        self.log, self.what, self.after_s, self.stop = log, what, after_s, stop
        self.stalls = 0  # steps logged as stuck so far
        self._lock = threading.Lock()
        self._started: float | None = None  # the running step's start (monotonic s), or None
        self._thread_id: int | None = None  # the loop's thread
        self._reported = False  # the running step was logged as stuck
        self._watcher: threading.Thread | None = None

    def begin(self) -> None:
        """A step starts on the calling thread."""
        with self._lock:
            self._started, self._thread_id, self._reported = time.monotonic(), threading.get_ident(), False
            if self._watcher is None:
                self._watcher = threading.Thread(
                    target=self._watch, name=f"stallwatch-{self.what}", daemon=True
                )
                self._watcher.start()

    def end(self) -> None:
        """The step started by ``begin`` ended."""
        with self._lock:
            started, reported, self._started = self._started, self._reported, None
        if reported and started is not None:
            self.log.warning("%s: the stuck step ended after %.1f s", self.what, time.monotonic() - started)

    def check(self) -> bool:
        """Log the running step if it is stuck and was not logged yet; whether it was logged now."""
        with self._lock:
            started, thread_id = self._started, self._thread_id
            if started is None or self._reported or time.monotonic() - started <= self.after_s:
                return False
            self._reported = True
            self.stalls += 1
        frame = sys._current_frames().get(thread_id) if thread_id is not None else None
        where = "".join(traceback.format_stack(frame)) if frame is not None else "(thread gone)\n"
        self.log.warning(
            "%s: one step has been running for %.1f s (more than %.1f s); the loop's thread is at:\n%s",
            self.what,
            time.monotonic() - started,
            self.after_s,
            where.rstrip(),
        )
        return True

    def _watch(self) -> None:
        while not self.stop.wait(self.after_s / 2.0):
            self.check()
