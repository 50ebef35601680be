"""Autopilot boot time -> Seaway stamp: a windowed-minimum offset estimate.

Telemetry carries ``time_boot_ms``, the autopilot's time since boot when the data was valid. For each
message we observe::

    offset_sample = wall time at receipt [ns] - time_boot_ms * 1e6  =  true offset + link latency

Latency is never negative, so the smallest sample seen is the closest to the true offset: latency
spikes (a busy radio, a scheduling hiccup) only make samples larger and so never move the estimate.
Taking the minimum over a sliding window (default 10 s) rather than forever lets the estimate follow
the slow drift between the two oscillators and an NTP adjustment of the wall clock, within one window.

Then ``stamp_ns = time_boot_ms * 1e6 + offset``; since the offset is at most any sample's, a stamp is
never later than the moment its message arrived.

A boot time that goes backwards by more than ``reboot_jump_ms`` means the autopilot rebooted: the
window is cleared and estimation starts again. ``reset()`` is also called on link loss.
"""

from __future__ import annotations

import collections


class BootTimeOffset:
    """Sliding-window minimum of (receipt wall time - boot time), in nanoseconds."""

    def __init__(self, window_s: float = 10.0, reboot_jump_ms: int = 1000) -> None:
        if not window_s > 0:
            raise ValueError("window_s must be > 0")
        self.window_ns = round(window_s * 1e9)
        self.reboot_jump_ms = reboot_jump_ms
        # Monotonic deque of (receipt_ns, offset_ns): offsets increase from left to right, so the
        # left end is the window's minimum (amortised O(1) per sample).
        self._q: collections.deque[tuple[int, int]] = collections.deque()
        self._last_boot_ms: int | None = None
        self.resets = 0

    def reset(self) -> None:
        self._q.clear()
        self._last_boot_ms = None

    def _rebooted(self, time_boot_ms: int) -> bool:
        return self._last_boot_ms is not None and time_boot_ms + self.reboot_jump_ms < self._last_boot_ms

    def peek(self, time_boot_ms: int, receipt_wall_ns: int) -> int:
        """The stamp ``update`` would return, without recording the observation.

        Used to validate a message before it is allowed to influence the estimate: a corrupted
        ``time_boot_ms`` must not drag the offset for a whole window.
        """
        sample = receipt_wall_ns - time_boot_ms * 1_000_000
        if not self._rebooted(time_boot_ms):
            horizon = receipt_wall_ns - self.window_ns
            for t, off in self._q:
                if t >= horizon:
                    sample = min(sample, off)
                    break
        return time_boot_ms * 1_000_000 + sample

    def update(self, time_boot_ms: int, receipt_wall_ns: int) -> int:
        """Add one observation; return the stamp [ns since epoch] for this message."""
        if self._rebooted(time_boot_ms):
            self.resets += 1
            self.reset()
        self._last_boot_ms = time_boot_ms if self._last_boot_ms is None else max(
            self._last_boot_ms, time_boot_ms)
        sample = receipt_wall_ns - time_boot_ms * 1_000_000
        q = self._q
        while q and q[-1][1] >= sample:
            q.pop()
        q.append((receipt_wall_ns, sample))
        horizon = receipt_wall_ns - self.window_ns
        while q[0][0] < horizon:
            q.popleft()
        return time_boot_ms * 1_000_000 + q[0][1]

    @property
    def offset_ns(self) -> int | None:
        """Current estimate, or None before the first observation."""
        return self._q[0][1] if self._q else None

    def lead_ns(self, time_boot_ms: int, receipt_wall_ns: int) -> int:
        """How far in the future of its receipt this boot time would put a stamp, with the current
        estimate (0 before the first observation). A large lead means ``time_boot_ms`` jumped
        forward, which no real clock does: the message is corrupt."""
        off = self.offset_ns
        if off is None or self._rebooted(time_boot_ms):
            return 0
        return time_boot_ms * 1_000_000 + off - receipt_wall_ns
