"""Clocks and a drift-free rate loop.

Service logic never reads a clock: its thin loop asks a ``Clock`` for the time and passes it in. Two
clocks exist:

* ``WallClock``: stamps from the system's real-time clock (ns since the Unix epoch), waiting on the
  monotonic clock so that NTP steps cannot stretch or squeeze a period;
* ``SimClock``: time the simulator publishes on ``sim/clock``; ``set`` moves it forward and wakes
  whoever waits. In lockstep it advances only when the sim steps, so a service on a SimClock runs
  exactly as many periods as the simulation, however fast the machine.

``WallStepWatch`` notices the wall clock stepped against the monotonic one (NTP or GPS time setting a
computer without a real-time clock).

``RateLoop`` ticks at ``t0 + k * period`` (never ``last + period``, which drifts). When it falls behind
by more than a period it skips the missed ticks (counted in ``skipped``), runs once at once (late),
and continues on the original grid: never a burst of catch-up ticks, never a drift.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol


class Clock(Protocol):
    def now_ns(self) -> int:
        """Stamp time [ns]: Unix epoch (wall) or simulation epoch (sim)."""
        ...

    def monotonic_ns(self) -> int:
        """A never-decreasing time base for waiting [ns]."""
        ...

    def sleep_until(self, monotonic_ns: int, stop: threading.Event) -> bool:
        """Wait until ``monotonic_ns``; False if ``stop`` was set first."""
        ...


class WallClock:
    """The real clock."""

    def now_ns(self) -> int:
        return time.time_ns()

    def monotonic_ns(self) -> int:
        return time.monotonic_ns()

    def sleep_until(self, monotonic_ns: int, stop: threading.Event) -> bool:
        delay = (monotonic_ns - time.monotonic_ns()) / 1e9
        if delay > 0:
            return not stop.wait(delay)
        return not stop.is_set()


class SimClock:
    """Simulated time, moved by whoever owns the simulation (the sim, or a ``sim/clock`` subscriber)."""

    def __init__(self, start_ns: int = 0) -> None:
        self._t_ns = start_ns
        self._cond = threading.Condition()

    def now_ns(self) -> int:
        return self._t_ns

    monotonic_ns = now_ns

    def set(self, t_ns: int) -> None:
        """Move time to ``t_ns``; going backwards is refused (a replay must reset explicitly)."""
        with self._cond:
            if t_ns < self._t_ns:
                raise ValueError(f"simulated time cannot go back ({t_ns} < {self._t_ns} ns)")
            self._t_ns = t_ns
            self._cond.notify_all()

    def advance(self, dt_ns: int) -> int:
        self.set(self._t_ns + dt_ns)
        return self._t_ns

    def reset(self, t_ns: int = 0) -> None:
        with self._cond:
            self._t_ns = t_ns
            self._cond.notify_all()

    def sleep_until(self, monotonic_ns: int, stop: threading.Event) -> bool:
        with self._cond:
            while self._t_ns < monotonic_ns:
                if stop.is_set():
                    return False
                # Wake periodically to notice ``stop`` (set from a signal handler, no notify).
                self._cond.wait(0.05)
        return not stop.is_set()


class RateLoop:
    """Ticks every ``period_s`` on ``clock`` without drift; counts skipped (overrun) ticks."""

    def __init__(self, period_s: float, clock: Clock, stop: threading.Event) -> None:
        if not period_s > 0:
            raise ValueError(f"period_s must be > 0, got {period_s}")
        self.period_ns = round(period_s * 1e9)
        self.clock = clock
        self.stop = stop
        self.tick = 0
        self.skipped = 0
        self._t0: int | None = None

    def wait(self) -> bool:
        """Block until the next tick; False when the loop should end."""
        now = self.clock.monotonic_ns()
        if self._t0 is None:
            self._t0 = now
            return not self.stop.is_set()
        self.tick += 1
        due = self._t0 + self.tick * self.period_ns
        if now > due + self.period_ns:
            # Behind by more than one period: drop the ticks that are wholly past, run the latest one
            # now, and stay on the grid.
            behind = (now - due) // self.period_ns
            self.skipped += behind
            self.tick += behind
            due = self._t0 + self.tick * self.period_ns
        return self.clock.sleep_until(due, self.stop)


WALL_STEP_MIN_NS = 1_000_000_000
"""A change of the wall clock against the monotonic one this large or larger between two looks is a
step [ns] (1 s). NTP slews the clock by at most 0.5 ms a second, far below it between looks."""


class WallStepWatch:
    """Whether the wall clock stepped since the last look: its offset from the monotonic clock
    changed by ``WALL_STEP_MIN_NS`` or more. Pure: both clocks' readings come in [ns]."""

    def __init__(self) -> None:
        self._offset_ns: int | None = None

    def look(self, wall_ns: int, mono_ns: int) -> int | None:
        """The step since the last look [ns] (+ forward, - back), else None."""
        offset = wall_ns - mono_ns
        before, self._offset_ns = self._offset_ns, offset
        if before is None or abs(offset - before) < WALL_STEP_MIN_NS:
            return None
        return offset - before
