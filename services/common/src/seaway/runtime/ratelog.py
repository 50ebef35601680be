"""Rate-limited logging: a repeated line is written once, then at most once per interval.

A flood of bad input (10,000 malformed samples a second) must not become a flood of log lines, on
the terminal or on disk. Each *kind* of line has a key the caller chooses (the bus key and what was
wrong with it; the message type and field): the first line of a key is written at once, later ones
at most once per ``every_s``, each saying how many like it were held back since the last one. The
counts stay exact; only the lines are thinned.

Memory is bounded too: at most ``max_keys`` keys are tracked, and a key beyond them shares one
budget with every other such key, so a flood of ever-new keys (a wildcard subscriber hearing
junk on new key expressions) cannot grow the table or the log.

Time is monotonic nanoseconds: a pure core passes its own (``now_ns``); a service loop may leave it
out and the monotonic clock is read. Thread-safe: bus callbacks log from the transport's threads.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Hashable

LOG_EVERY_S = 5.0
"""Default interval between two lines of one key [s]."""
MAX_KEYS = 256
"""Default number of keys tracked one by one; further keys share one budget."""
_OVERFLOW_KEY = ("seaway.ratelog", "other keys")


class RateLimitedLog:
    """Writes to ``logger`` at most one line per key per ``every_s``; see the module docstring."""

    def __init__(self, logger: logging.Logger, every_s: float = LOG_EVERY_S,
                 max_keys: int = MAX_KEYS) -> None:
        if not every_s > 0 or max_keys < 1:
            raise ValueError("every_s must be > 0 and max_keys >= 1")
        self.logger = logger
        self.every_ns = round(every_s * 1e9)
        self.max_keys = max_keys
        self.suppressed_total = 0
        self._last_ns: dict[Hashable, int] = {}
        self._held: dict[Hashable, int] = {}
        self._lock = threading.Lock()

    def log(self, key: Hashable, level: int, msg: str, *args: object, now_ns: int | None = None,
            exc_info: bool = False) -> bool:
        """Write ``msg % args`` at ``level`` unless a line of ``key`` was written less than
        ``every_s`` ago (then it is only counted). True if written."""
        now = time.monotonic_ns() if now_ns is None else now_ns
        with self._lock:
            if key not in self._last_ns and len(self._last_ns) >= self.max_keys:
                key = _OVERFLOW_KEY
            last = self._last_ns.get(key)
            if last is not None and now - last < self.every_ns:
                self._held[key] = self._held.get(key, 0) + 1
                self.suppressed_total += 1
                return False
            held = self._held.pop(key, 0)
            self._last_ns[key] = now
        if not self.logger.isEnabledFor(level):
            return True
        text = msg % args if args else msg
        if held:
            text += f" ({held} more like it since the last report)"
        if key == _OVERFLOW_KEY:
            text += f" (one report for every key beyond the first {self.max_keys})"
        self.logger.log(level, "%s", text, exc_info=exc_info)
        return True

    def warning(self, key: Hashable, msg: str, *args: object, now_ns: int | None = None) -> bool:
        return self.log(key, logging.WARNING, msg, *args, now_ns=now_ns)

    def info(self, key: Hashable, msg: str, *args: object, now_ns: int | None = None) -> bool:
        return self.log(key, logging.INFO, msg, *args, now_ns=now_ns)

    def exception(self, key: Hashable, msg: str, *args: object, now_ns: int | None = None) -> bool:
        """An ERROR line with the traceback of the exception being handled (rate-limited)."""
        return self.log(key, logging.ERROR, msg, *args, now_ns=now_ns, exc_info=True)

    def held(self, key: Hashable) -> int:
        """Lines of ``key`` held back since its last written line."""
        with self._lock:
            return self._held.get(key, 0)
