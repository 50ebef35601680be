"""How often a VehicleStatus may go out "at once", between the periodic ones (``status_rate_hz``).

A change worth saying now (the autopilot armed or disarmed, another mode, the link lost or made,
thrust commands stale or fresh again, telemetry rates short) publishes a status at once. The
autopilot decides how often some of those happen: a locked, signed autopilot (an insider, or a
firmware bug) flapping its HEARTBEAT between armed and disarmed 10,000 times a second made
vehicle_io publish 10,000 statuses a second, flooding the recorder, the ground station and the
controller. The state itself still follows every HEARTBEAT; only how often it is said is bounded.

``StatusPacer`` lets a status out at once if none went out "at once" in the last
``MIN_STATUS_GAP_NS``; otherwise the change is held, not lost: a status is due at the end of that
gap, and ``tick`` publishes it then, with the state as it is then (the latest: the trailing edge).
Hence:

* at most one such status per gap (20 a second at 50 ms), on top of the periodic ones;
* a change, a link loss or a disarm included, reaches the bus at most ``MIN_STATUS_GAP_NS`` after
  it happened (plus the loop's own wake-up latency), at once if the status was quiet before;
* the last state said is always the latest one: nothing is dropped but intermediate states that
  lasted less than a gap.

Pure: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

MIN_STATUS_GAP_NS = 50_000_000
"""The least time between two statuses said at once [ns] (50 ms): at most 20 a second on top of the
periodic ones, well within what the bus and the recorder take, and short beside what the status
reports (a HEARTBEAT a second, a link timeout of seconds, the 300 ms thrust watchdog) and beside an
operator's or the controller's reaction, so a real change is not noticeably late."""


class StatusPacer:
    """When a status said at once may go out (see the module docstring). Times in monotonic ns."""

    def __init__(self, gap_ns: int = MIN_STATUS_GAP_NS) -> None:
        if gap_ns <= 0:
            raise ValueError("gap_ns must be > 0")
        self.gap_ns = gap_ns
        self.last_ns: int | None = None
        """When the last status said at once went out (None: none yet)."""
        self.held_ns: int | None = None
        """When the status held back is due (None: nothing held)."""
        self.held = 0
        """Changes held back so far (said later, with the latest state)."""

    def may_say(self, now_ns: int) -> bool:
        """A change to say at once: True if its status may go out now (it then counts as said now);
        False if one went out less than a gap ago: held, due at the gap's end (``due``)."""
        if self.last_ns is None or now_ns - self.last_ns >= self.gap_ns:
            self.last_ns = now_ns
            self.held_ns = None
            return True
        self.held_ns = self.last_ns + self.gap_ns
        self.held += 1
        return False

    def due(self, now_ns: int) -> bool:
        """Whether a held-back status is due now (``may_say`` then lets it out)."""
        return self.held_ns is not None and now_ns >= self.held_ns

    def said(self) -> None:
        """A status went out (a periodic one too): it carries the latest state, so whatever was
        held back has been said."""
        self.held_ns = None

    def next_due_ns(self) -> int | None:
        """When the held-back status is due (None: nothing held), for the loop's wake-up."""
        return self.held_ns


FLAPPING_HELD = 10
"""Changes held back within ``FLAPPING_WINDOW_NS`` that make a flapping link or autopilot worth a
warning. A normal run holds one now and then (the link made, armed and the mode set within 50 ms of
each other): no news, and a warning for it was noise in every run's log."""
FLAPPING_WINDOW_NS = 60_000_000_000
"""The window ``FLAPPING_HELD`` is counted in [ns] (a minute, monotonic)."""


class FlapWatch:
    """Whether the pacing's count of changes held back (``StatusPacer.held``) grew by
    ``FLAPPING_HELD`` or more within one window of ``FLAPPING_WINDOW_NS``. Pure: the count and the
    monotonic time come in."""

    def __init__(self) -> None:
        self._start_ns: int | None = None
        self._held_then = 0
        self._told = 0

    def look(self, held: int, mono_ns: int) -> int | None:
        """The changes held back in the current window when that is news worth a warning (the count
        reached ``FLAPPING_HELD`` and grew since it was last said), else None."""
        if self._start_ns is None or mono_ns - self._start_ns >= FLAPPING_WINDOW_NS:
            self._start_ns, self._held_then = mono_ns, held
            return None
        count = held - self._held_then
        if count < FLAPPING_HELD or held == self._told:
            return None
        self._told = held
        return count
