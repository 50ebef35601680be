"""Bounds on what a message's stamp can make a service do.

A ``stamp_ns`` is data from another process. A valid but absurd one (10 s ahead of every clock,
10^4000 ns, the epoch) must not make a service integrate for ever, drop its state, or keep a message
for a time that never comes. So each service judges every stamp it acts on against its own time,
the *reference*: its wall clock in real time, the current period t_k in lockstep. A stamp outside
the bounds is dropped before it reaches the service's core: counted per key and direction, and
logged once (then at most once a minute per key and direction, with the count): never fatal, and
never a flood of lines.

The bounds:

* **real time** (``StampBounds.live``): at most ``MAX_AHEAD_LIVE_S`` ahead of the receiver's clock.
  Every stamp a service acts on was taken from a clock of the same machine, or of one kept to it by
  NTP (milliseconds apart), at or before the moment it was sent; one stamped a second ahead of the
  clock reading it is wrong, not early. How far *behind* is the service's own rule (how old an
  input it can still use), passed by the service.
* **lockstep** (``StampBounds.lockstep``): at most ``LOCKSTEP_AHEAD_PERIODS`` periods ahead of t_k.
  A member can hear the samples of t_{k+1} before the sim's answer that announces that period (Zenoh
  does not order keys), never anything later. Behind is not bounded: a new episode starts again at
  t = 0, and the protocol itself drops what is left of an earlier one (``seaway.runtime.lockstep``).
"""

from __future__ import annotations

import functools
import logging
import threading
from dataclasses import dataclass
from typing import Literal

from seaway.contract.units import NS_PER_S
from seaway.runtime.ratelog import RateLimitedLog

MAX_AHEAD_LIVE_S = 1.0
"""Real time: how far a stamp may lie ahead of the receiving process's wall clock [s]."""
LOCKSTEP_AHEAD_PERIODS = 2
"""Lockstep: how many periods a stamp may lie ahead of the member's current period."""
STAMP_LOG_EVERY_S = 60.0
"""A key and direction already logged is logged again at most this often, with the count."""
MAX_COUNTED_KEYS = 64
"""Keys counted one by one; drops on further keys are counted together under ``"other"``."""

Direction = Literal["ahead", "behind"]


def describe_ns(delta_ns: int) -> str:
    """A duration for a person: '12.345 s', or its order of magnitude when it is absurdly long
    (a float cannot hold 10^4000)."""
    if abs(delta_ns) < 10**15:
        return f"{delta_ns / NS_PER_S:.3f} s"
    return f"about 10^{len(str(abs(delta_ns))) - 10} s"


@dataclass(frozen=True)
class StampBounds:
    """How far a stamp may lie from the receiver's reference time [ns]; None: not bounded."""

    ahead_ns: int
    behind_ns: int | None = None

    def __post_init__(self) -> None:
        if self.ahead_ns < 0 or (self.behind_ns is not None and self.behind_ns < 0):
            raise ValueError(f"stamp bounds must be >= 0, got ahead {self.ahead_ns} ns, "
                             f"behind {self.behind_ns} ns")

    @classmethod
    def live(cls, behind_s: float | None = None) -> StampBounds:
        """Real time: ``MAX_AHEAD_LIVE_S`` ahead; ``behind_s`` behind (None: any age)."""
        return cls(round(MAX_AHEAD_LIVE_S * NS_PER_S),
                   None if behind_s is None else round(behind_s * NS_PER_S))

    @classmethod
    def lockstep(cls, period_ns: int) -> StampBounds:
        """Lockstep with periods of ``period_ns``: ``LOCKSTEP_AHEAD_PERIODS`` ahead, any age.
        One instance per period length (asked for every message a lockstep member takes)."""
        return _lockstep_bounds(cls, int(period_ns))

    def judge(self, stamp_ns: int, ref_ns: int) -> Direction | None:
        """None if ``stamp_ns`` is within the bounds around ``ref_ns``, else which side it is on."""
        if stamp_ns - ref_ns > self.ahead_ns:
            return "ahead"
        if self.behind_ns is not None and ref_ns - stamp_ns > self.behind_ns:
            return "behind"
        return None

    def describe(self) -> str:
        behind = "any age" if self.behind_ns is None else f"{describe_ns(self.behind_ns)} behind"
        return f"up to {describe_ns(self.ahead_ns)} ahead, {behind}"


class StampGate:
    """Applies ``StampBounds`` to the stamps one service acts on: admits a stamp, or counts, drops
    and logs it (see the module docstring). Thread-safe."""

    def __init__(self, who: str, logger: logging.Logger, bounds: StampBounds | None = None,
                 log_every_s: float = STAMP_LOG_EVERY_S) -> None:
        self.who = who
        self.bounds = bounds
        self.dropped: dict[tuple[str, Direction], int] = {}
        self._log = RateLimitedLog(logger, log_every_s, max_keys=2 * MAX_COUNTED_KEYS)
        self._lock = threading.Lock()

    def admit(self, key: str, stamp_ns: int, ref_ns: int | None,
              bounds: StampBounds | None = None, now_ns: int | None = None) -> bool:
        """Whether a message on ``key`` stamped ``stamp_ns`` may be acted on at ``ref_ns`` (the
        service's reference time; None: not known yet, so anything is). ``bounds`` replaces the
        gate's own for this call; ``now_ns`` (monotonic) times the log's rate limit."""
        b = bounds or self.bounds
        if ref_ns is None or b is None:
            return True
        direction = b.judge(stamp_ns, ref_ns)
        if direction is None:
            return True
        with self._lock:
            counted = (key, direction)
            if counted not in self.dropped and len(self.dropped) >= MAX_COUNTED_KEYS:
                counted = ("other", direction)
            n = self.dropped[counted] = self.dropped.get(counted, 0) + 1
        self._log.warning(counted, "%s: dropped a message on %s stamped %s %s its time (stamp %s, "
                          "time %d ns); allowed: %s. Dropped so far on this key: %d (logged at "
                          "most once a minute)", self.who, key, describe_ns(abs(stamp_ns - ref_ns)),
                          direction, _short(stamp_ns), ref_ns, b.describe(), n, now_ns=now_ns)
        return False

    @property
    def total(self) -> int:
        with self._lock:
            return sum(self.dropped.values())

    def summary(self) -> str:
        """'ctrl/thrust ahead 3, sensors/gnss behind 1' (empty when nothing was dropped)."""
        with self._lock:
            return ", ".join(f"{k} {d} {n}" for (k, d), n in sorted(self.dropped.items()))


def _short(stamp_ns: int) -> str:
    text = str(stamp_ns)
    return text if len(text) <= 24 else f"{text[:8]}...({len(text)} digits)"


@functools.lru_cache(maxsize=8)
def _lockstep_bounds(cls: type[StampBounds], period_ns: int) -> StampBounds:
    return cls(LOCKSTEP_AHEAD_PERIODS * max(period_ns, 0))
