"""Autopilot boot time -> Seaway stamp: a windowed-minimum offset estimate.

Telemetry carries ``time_boot_ms``, the autopilot's time since boot when the data was valid. PX4
and ArduPilot stamp ATTITUDE, GLOBAL_POSITION_INT and LOCAL_POSITION_NED with the time their
estimator produced the value, i.e. about when it is sent (measured on both SITLs, docs/autopilots.md;
only GPS_RAW_INT carries the receiver's fix time, and it is not used for stamps). For each message
we observe::

    offset_sample = wall time at receipt [ns] - time_boot_ms * 1e6  =  true offset + link latency

Latency is never negative, so the smallest sample seen is the closest to the true offset: latency
spikes (a busy radio, a scheduling hiccup, one packet seconds late) only make samples larger and so
never move the estimate; such a message simply gets its true, older, stamp. Taking the minimum over
a sliding window (default 10 s) rather than forever lets the estimate follow the slow drift between
the two oscillators and an NTP adjustment of the wall clock, within one window.

Then ``stamp_ns = time_boot_ms * 1e6 + offset``; since the offset is at most any sample's, a stamp is
never later than the moment its message arrived.

What one sample can and cannot do:

* a sample whose boot time lies more than ``jump_ms`` *ahead* of the estimate (its stamp would be
  in the future of its receipt) is refused (``stamp`` returns None): a corrupt ``time_boot_ms``
  must not drag the estimate. If every sample says so for ``confirm_s`` (and at least
  ``confirm_samples`` of them, agreeing with each other), the estimate is what is wrong (a wrong
  guess, e.g. a reset on a late packet): it is rebuilt from those samples (``rebases``);
* a sample whose boot time lies more than ``jump_ms`` *behind* the estimate is a late packet and
  gets its (old) stamp. Only when every sample says so for ``confirm_s`` has the autopilot
  rebooted without the link dropping: the estimate restarts from those samples (``resets``);
* a reboot is otherwise the link's business: ``system_time`` (SYSTEM_TIME's boot time going back by
  more than ``jump_ms``) and a link loss (no HEARTBEAT: ``reset()``) restart the estimate at once.
  Neither feeds the estimate a sample, so even a wrong restart (a SYSTEM_TIME reordered on the
  link) costs only a fresh start from the next message.
"""

from __future__ import annotations

import collections

from seaway.contract.units import NS_PER_MS


class BootTimeOffset:
    """Sliding-window minimum of (receipt wall time - boot time), in nanoseconds."""

    def __init__(self, window_s: float = 10.0, jump_ms: int = 1000, confirm_s: float = 1.0,
                 confirm_samples: int = 3) -> None:
        if not window_s > 0:
            raise ValueError("window_s must be > 0")
        if not (confirm_s > 0 and confirm_samples >= 1 and jump_ms > 0):
            raise ValueError("confirm_s, confirm_samples and jump_ms must be > 0")
        self.window_ns = round(window_s * 1e9)
        self.jump_ns = jump_ms * NS_PER_MS
        self.confirm_ns = round(confirm_s * 1e9)
        self.confirm_samples = confirm_samples
        # Monotonic deque of (receipt_ns, offset_ns): offsets increase from left to right, so the
        # left end is the window's minimum (amortised O(1) per sample).
        self._q: collections.deque[tuple[int, int]] = collections.deque()
        # Consecutive samples far from the estimate, on one side: (receipt_ns, offset sample).
        self._streak: list[tuple[int, int]] = []
        self._streak_side = 0  # +1: boot times ahead of the estimate, -1: behind, 0: none
        self._system_time_ms: int | None = None
        self.resets = 0  # reboots seen (SYSTEM_TIME going back, or every sample behind)
        self.rebases = 0  # estimates found wrong and rebuilt (every sample ahead of it)

    def reset(self) -> None:
        """Forget everything (link loss, reboot): the next sample starts a new estimate."""
        self._q.clear()
        self._streak.clear()
        self._streak_side = 0
        self._system_time_ms = None

    @property
    def offset_ns(self) -> int | None:
        """Current estimate, or None before the first observation."""
        return self._q[0][1] if self._q else None

    def _current(self, receipt_wall_ns: int) -> int | None:
        """The window's minimum as of ``receipt_wall_ns`` (expired samples left out; with all of
        them expired, the newest: a silence is no reason to believe the next sample blindly)."""
        horizon = receipt_wall_ns - self.window_ns
        for t, off in self._q:
            if t >= horizon:
                return off
        return self._q[-1][1] if self._q else None

    def stamp(self, time_boot_ms: int, receipt_wall_ns: int) -> int | None:
        """The stamp [ns since epoch] for a message with ``time_boot_ms`` received at
        ``receipt_wall_ns``, or None if its boot time jumps more than ``jump_ms`` ahead of the
        estimate (refuse the message). Does not add the sample to the estimate: ``commit`` does,
        once the rest of the message has been found valid."""
        sample = receipt_wall_ns - time_boot_ms * NS_PER_MS
        off = self._current(receipt_wall_ns)
        if off is None:
            return time_boot_ms * NS_PER_MS + sample
        side = 1 if off - sample > self.jump_ns else -1 if sample - off > self.jump_ns else 0
        if side == 0:
            self._streak.clear()
            self._streak_side = 0
        elif self._confirmed(side, receipt_wall_ns, sample):
            # Every sample for confirm_s says the same: the autopilot's clock restarted (behind)
            # or the estimate was wrong (ahead). Start again from what they agree on.
            if side > 0:
                self.rebases += 1
            else:
                self.resets += 1
            streak = list(self._streak)
            self.reset()
            for t, s in streak:
                self._add(t, s)
            off = self._q[0][1]
        elif side > 0:
            return None
        return time_boot_ms * NS_PER_MS + min(off, sample)

    def _confirmed(self, side: int, receipt_wall_ns: int, sample: int) -> bool:
        """Record a sample far from the estimate; True once the streak proves it right."""
        if side != self._streak_side:
            self._streak.clear()
            self._streak_side = side
        if self._streak and abs(sample - self._streak[0][1]) > self.jump_ns:
            self._streak.clear()  # they do not agree with each other: garbage, not a clock
        self._streak.append((receipt_wall_ns, sample))
        span = receipt_wall_ns - self._streak[0][0]
        return len(self._streak) >= self.confirm_samples and span >= self.confirm_ns

    def commit(self, time_boot_ms: int, receipt_wall_ns: int) -> None:
        """Add a sample ``stamp`` accepted (and whose message was valid) to the estimate."""
        self._add(receipt_wall_ns, receipt_wall_ns - time_boot_ms * NS_PER_MS)

    def _add(self, receipt_wall_ns: int, sample: int) -> None:
        q = self._q
        while q and q[-1][1] >= sample:
            q.pop()
        q.append((receipt_wall_ns, sample))
        horizon = receipt_wall_ns - self.window_ns
        while q[0][0] < horizon:
            q.popleft()

    def update(self, time_boot_ms: int, receipt_wall_ns: int) -> int | None:
        """``stamp`` then ``commit``: the stamp for this message (None: refused, not recorded)."""
        stamp = self.stamp(time_boot_ms, receipt_wall_ns)
        if stamp is not None:
            self.commit(time_boot_ms, receipt_wall_ns)
        return stamp

    def system_time(self, time_boot_ms: int) -> bool:
        """SYSTEM_TIME's boot time (the autopilot's clock now). Going back by more than
        ``jump_ms`` means the autopilot rebooted: the estimate restarts (returns True)."""
        last = self._system_time_ms
        if last is not None and time_boot_ms * NS_PER_MS + self.jump_ns < last * NS_PER_MS:
            self.resets += 1
            self.reset()
            self._system_time_ms = time_boot_ms
            return True
        self._system_time_ms = time_boot_ms if last is None else max(last, time_boot_ms)
        return False
