"""The thrust watchdog: no fresh ThrustCommand within the timeout -> neutral thrust.

Freshness is measured on *receipt* (vehicle_io's monotonic clock), not on the command's stamp:
a stamp is the time of the state the command was computed from, and comparing it with our clock
would mix two clocks (and, in simulation, two time bases). What the watchdog guards against is a
controller that stopped sending, and that shows on receipt.

Time is passed in [ns, monotonic]; nothing here reads a clock.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.contract.messages import ThrustCommand

FAILSAFE_THRUST_STALE = "thrust_stale"


@dataclass(frozen=True)
class WatchdogEvent:
    """A change of the watchdog's state; ``stale`` is the new state."""

    stale: bool
    at_ns: int
    silent_for_ns: int | None  # how long no command had arrived (None: none ever)


class ThrustWatchdog:
    """Holds the latest command and says whether it is still fresh."""

    def __init__(self, timeout_s: float) -> None:
        if not timeout_s > 0:
            raise ValueError("timeout_s must be > 0")
        self.timeout_ns = round(timeout_s * 1e9)
        self.latest: ThrustCommand | None = None
        self.received_ns: int | None = None
        self.stale = True  # nothing received yet counts as stale: neutral until a command arrives
        self.trips = 0

    def command(self, cmd: ThrustCommand, now_ns: int) -> WatchdogEvent | None:
        """Record a command received at ``now_ns``; returns an event if it clears staleness."""
        self.latest = cmd
        self.received_ns = now_ns
        if self.stale:
            self.stale = False
            return WatchdogEvent(stale=False, at_ns=now_ns, silent_for_ns=None)
        return None

    def deadline_ns(self) -> int | None:
        """When the latest command goes stale (None if already stale)."""
        if self.stale or self.received_ns is None:
            return None
        return self.received_ns + self.timeout_ns

    def check(self, now_ns: int) -> WatchdogEvent | None:
        """Returns an event when the latest command has just gone stale."""
        deadline = self.deadline_ns()
        if deadline is None or now_ns < deadline:
            return None
        self.stale = True
        self.trips += 1
        assert self.received_ns is not None
        return WatchdogEvent(stale=True, at_ns=now_ns, silent_for_ns=now_ns - self.received_ns)

    def active(self, now_ns: int) -> ThrustCommand | None:
        """The command to apply at ``now_ns``, or None for neutral (does not change state)."""
        deadline = self.deadline_ns()
        if deadline is None or now_ns >= deadline:
            return None
        return self.latest
