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
  gets its (old) stamp, unless it lies more than a window behind: no link holds a packet that long,
  and the estimate it would be stamped against is younger than the packet, so it is refused
  (``refused == "late"``). When every sample says "behind" for ``confirm_s``, the estimate restarts
  from those samples, and what moved decides what happened, because the estimate is kept on the
  wall clock and, alongside, on the monotonic clock:

  - the offset on the monotonic clock moved too: the autopilot's clock went back, it **rebooted**
    without the link dropping (``resets``; its latched failsafes end with it);
  - only the wall clock's offset moved: the **wall clock stepped** (NTP or chrony setting the
    time of a board without a real-time clock), the autopilot did not reboot (``steps``);
  - the estimate never had ``confirm_samples`` agreeing samples over ``confirm_s`` (a corrupt
    first ``time_boot_ms`` after link-up): it was **wrong**, not the autopilot (``rebases``);

* SYSTEM_TIME's boot time going back by more than ``jump_ms`` (``system_time``) is a reboot only
  once SYSTEM_TIMEs over ``confirm_s`` agree with each other and with the monotonic clock: one
  reordered, duplicated or replayed packet is not one. A link loss (``reset()``) restarts the
  estimate at once.
"""

from __future__ import annotations

import collections

from seaway.contract.units import NS_PER_MS


def _window_add(q: collections.deque[tuple[int, int]], t_ns: int, value: int, window_ns: int) -> None:
    """Add ``value`` seen at ``t_ns`` to a monotonic deque whose left end is the minimum of the
    values seen over the last ``window_ns`` (amortised O(1))."""
    while q and q[-1][1] >= value:
        q.pop()
    q.append((t_ns, value))
    horizon = t_ns - window_ns
    while q[0][0] < horizon:
        q.popleft()


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
        # The same on the monotonic clock (receipt monotonic ns, monotonic - boot time): it moves
        # when the autopilot's clock restarts, not when the wall clock is set.
        self._mono_q: collections.deque[tuple[int, int]] = collections.deque()
        # Samples in the current estimate, and when its first and its latest were received [wall ns].
        self._count, self._first_ns, self._last_ns = 0, 0, 0
        # Consecutive samples far from the estimate, on one side:
        # (receipt wall ns, offset sample, receipt monotonic ns, monotonic offset sample).
        self._streak: list[tuple[int, int, int, int]] = []
        self._streak_side = 0  # +1: boot times ahead of the estimate, -1: behind, 0: none
        self._system_time_ms: int | None = None
        # The first SYSTEM_TIME of a run going back: (its boot time [ms], received [monotonic ns]).
        self._system_back: tuple[int, int] | None = None
        self.resets = 0  # reboots seen (SYSTEM_TIME going back, or every sample behind)
        self.rebases = 0  # estimates found wrong and rebuilt (every sample ahead of it, or unconfirmed)
        self.steps = 0  # wall clock steps seen (every sample behind on the wall clock only)
        self.refused: str | None = None  # why ``stamp`` last returned None: "ahead" or "late"

    def reset(self) -> None:
        """Forget everything (link loss, reboot): the next sample starts a new estimate."""
        self._q.clear()
        self._mono_q.clear()
        self._count = 0
        self._streak.clear()
        self._streak_side = 0
        self._system_time_ms = None
        self._system_back = None

    @property
    def offset_ns(self) -> int | None:
        """Current estimate, or None before the first observation."""
        return self._q[0][1] if self._q else None

    def _current(self, receipt_wall_ns: int) -> int | None:
        """The window's minimum as of ``receipt_wall_ns`` (expired samples left out; with all of
        them expired, the newest: a silence is no reason to believe the next sample blindly)."""
        return self._min(self._q, receipt_wall_ns)

    def _min(self, q: collections.deque[tuple[int, int]], t_ns: int) -> int | None:
        horizon = t_ns - self.window_ns
        for t, off in q:
            if t >= horizon:
                return off
        return q[-1][1] if q else None

    def _established(self) -> bool:
        """Whether the estimate rests on ``confirm_samples`` samples over ``confirm_s``."""
        return self._count >= self.confirm_samples and \
            self._last_ns - self._first_ns >= self.confirm_ns

    def stamp(self, time_boot_ms: int, receipt_wall_ns: int,
              receipt_mono_ns: int | None = None) -> int | None:
        """The stamp [ns since epoch] for a message with ``time_boot_ms`` received at
        ``receipt_wall_ns`` (and ``receipt_mono_ns`` on the monotonic clock; None: the wall clock
        is taken not to step), or None if its boot time jumps more than ``jump_ms`` ahead of the
        estimate or lies more than a window behind it (refuse the message; ``refused`` says
        which). Does not add the sample to the estimate: ``commit`` does, once the rest of the
        message has been found valid."""
        self.refused = None
        mono_ns = receipt_wall_ns if receipt_mono_ns is None else receipt_mono_ns
        sample = receipt_wall_ns - time_boot_ms * NS_PER_MS
        mono_sample = mono_ns - time_boot_ms * NS_PER_MS
        off = self._current(receipt_wall_ns)
        if off is None:
            return time_boot_ms * NS_PER_MS + sample
        side = 1 if off - sample > self.jump_ns else -1 if sample - off > self.jump_ns else 0
        if side == 0:
            self._streak.clear()
            self._streak_side = 0
        elif self._confirmed(side, (receipt_wall_ns, sample, mono_ns, mono_sample)):
            # Every sample for confirm_s says the same. Start again from what they agree on.
            self._count_restart(side, mono_ns, mono_sample)
            streak = list(self._streak)
            self.reset()
            for t, s, mt, ms in streak:
                self._add(t, s, mt, ms)
            off = self._q[0][1]
        elif side > 0:
            self.refused = "ahead"
            return None
        elif sample - off > self.window_ns:
            self.refused = "late"
            return None
        return time_boot_ms * NS_PER_MS + min(off, sample)

    def _count_restart(self, side: int, mono_ns: int, mono_sample: int) -> None:
        """Count a confirmed restart of the estimate by its cause (see the module docstring)."""
        mono_off = self._min(self._mono_q, mono_ns)
        if side > 0 or not self._established():
            self.rebases += 1
        elif mono_off is not None and mono_sample - mono_off <= self.jump_ns:
            self.steps += 1
        else:
            self.resets += 1

    def _confirmed(self, side: int, seen: tuple[int, int, int, int]) -> bool:
        """Record a sample far from the estimate; True once the streak proves it right."""
        if side != self._streak_side:
            self._streak.clear()
            self._streak_side = side
        if self._streak and abs(seen[1] - self._streak[0][1]) > self.jump_ns:
            self._streak.clear()  # they do not agree with each other: garbage, not a clock
        self._streak.append(seen)
        span = seen[0] - self._streak[0][0]
        return len(self._streak) >= self.confirm_samples and span >= self.confirm_ns

    def commit(self, time_boot_ms: int, receipt_wall_ns: int,
               receipt_mono_ns: int | None = None) -> None:
        """Add a sample ``stamp`` accepted (and whose message was valid) to the estimate."""
        mono_ns = receipt_wall_ns if receipt_mono_ns is None else receipt_mono_ns
        self._add(receipt_wall_ns, receipt_wall_ns - time_boot_ms * NS_PER_MS,
                  mono_ns, mono_ns - time_boot_ms * NS_PER_MS)

    def _add(self, receipt_wall_ns: int, sample: int, mono_ns: int, mono_sample: int) -> None:
        _window_add(self._q, receipt_wall_ns, sample, self.window_ns)
        _window_add(self._mono_q, mono_ns, mono_sample, self.window_ns)
        if self._count == 0:
            self._first_ns = receipt_wall_ns
        self._count += 1
        self._last_ns = receipt_wall_ns

    def update(self, time_boot_ms: int, receipt_wall_ns: int,
               receipt_mono_ns: int | None = None) -> int | None:
        """``stamp`` then ``commit``: the stamp for this message (None: refused, not recorded)."""
        stamp = self.stamp(time_boot_ms, receipt_wall_ns, receipt_mono_ns)
        if stamp is not None:
            self.commit(time_boot_ms, receipt_wall_ns, receipt_mono_ns)
        return stamp

    def system_time(self, time_boot_ms: int, receipt_mono_ns: int) -> bool:
        """SYSTEM_TIME's boot time (the autopilot's clock now), received at ``receipt_mono_ns``
        [monotonic ns]. Going back by more than ``jump_ms``, in SYSTEM_TIMEs that keep agreeing
        with each other and with the monotonic clock for ``confirm_s``, means the autopilot
        rebooted: the estimate restarts (returns True)."""
        last = self._system_time_ms
        if last is None or time_boot_ms * NS_PER_MS + self.jump_ns >= last * NS_PER_MS:
            self._system_back = None
            self._system_time_ms = time_boot_ms if last is None else max(last, time_boot_ms)
            return False
        first = self._system_back
        if first is None or abs((time_boot_ms - first[0]) * NS_PER_MS
                                - (receipt_mono_ns - first[1])) > self.jump_ns:
            # The first going back, or one that does not run on from it with the monotonic clock
            # (stale packets replayed in a burst): start the count again from this one.
            self._system_back = (time_boot_ms, receipt_mono_ns)
            return False
        if time_boot_ms <= first[0] or receipt_mono_ns - first[1] < self.confirm_ns:
            return False
        self.resets += 1
        self.reset()
        self._system_time_ms = time_boot_ms
        return True
