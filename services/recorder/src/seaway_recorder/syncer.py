"""The recording made durable as it goes: every ``sync_interval_s`` the file being written is
``fdatasync``-ed, on a thread of its own, so that a power loss (a boat's battery cut, its kill
switch) loses about that much of the recording. Without it the OS alone decides, and it may hold
writes for 30 s (``vm.dirty_expire_centisecs``): the last half minute before the power went, the
part of a recording most wanted, would be gone.

Never on the writer's loop: an fdatasync waits for whatever else the disk is writing (hundreds of
milliseconds on an SD card), and a lockstep sim waits on that loop. A sync asked while the one
before is still under way is skipped and counted (the next covers it); one that fails is counted
and logged at a limited rate, and recording goes on. Each sync works on a duplicate of the file's
descriptor, so the file may be rotated or closed meanwhile.
"""

from __future__ import annotations

import logging
import os
import threading
import time

from seaway.runtime.ratelog import RateLimitedLog

log = logging.getLogger("seaway.recorder")

DEFAULT_SYNC_INTERVAL_S = 1.0
"""Between two syncs of the recording [s]: what a power loss loses at most, about."""


class Syncer:
    """fdatasync of the file being written, every ``interval_s`` [s] (0: never), off the loop."""

    def __init__(self, interval_s: float) -> None:
        self.interval_ns = round(interval_s * 1e9)
        self.syncs = 0
        self.skipped = 0
        """Syncs not asked because the one before was still under way."""
        self.failed = 0
        self.slowest_s = 0.0
        """The longest sync [s]."""
        self._next_ns = 0
        self._pending: int | None = None
        self._busy = False
        self._closed = False
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        self._ratelog = RateLimitedLog(log)

    def maybe(self, fd: int | None, now_ns: int) -> None:
        """Sync ``fd`` (the file being written; None: none) if ``interval_s`` has passed since the
        last was asked; ``now_ns`` monotonic."""
        if self.interval_ns <= 0 or fd is None or now_ns < self._next_ns:
            return
        self._next_ns = now_ns + self.interval_ns
        with self._cond:
            if self._closed:
                return
            if self._busy or self._pending is not None:
                self.skipped += 1
                return
            self._pending = os.dup(fd)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="recorder-sync", daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._pending is None:
                    return
                fd, self._pending, self._busy = self._pending, None, True
            t0 = time.monotonic()
            try:
                os.fdatasync(fd)
                ok = True
            except OSError as err:
                ok = False
                self._ratelog.warning("sync", "could not sync the recording to the disk: %s", err)
            finally:
                os.close(fd)
            took_s = time.monotonic() - t0
            with self._cond:
                self._busy = False
                if ok:
                    self.syncs += 1
                    self.slowest_s = max(self.slowest_s, took_s)
                else:
                    self.failed += 1
                self._cond.notify_all()

    def close(self, timeout_s: float = 5.0) -> None:
        """Stop the thread once a sync under way is done (bounded by ``timeout_s``)."""
        with self._cond:
            self._closed = True
            pending, self._pending = self._pending, None
            self._cond.notify_all()
        if pending is not None:
            os.close(pending)
        if self._thread is not None:
            self._thread.join(timeout_s)

    def figures(self) -> dict[str, float | int]:
        """For the recorder's summary."""
        return {"syncs": self.syncs, "syncs_skipped": self.skipped, "syncs_failed": self.failed,
                "sync_slowest_s": round(self.slowest_s, 6)}
