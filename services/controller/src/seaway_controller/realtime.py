"""The controller on the wall clock: what keeps the thrusters commanded around each step.

Each tick of the control period uses the newest state if a new one arrived; a state older than
``max_state_age_s`` gives zero thrust (once said in the log); a step that overruns gets a command
sent in its place, once a period (``keeper.ThrustKeeper``); a step stuck for long is logged with
where it is (``seaway.runtime.stallwatch``); a step longer than the period says so.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import NamedTuple

from seaway.contract import keys
from seaway.contract.messages import StateEstimate, ThrustCommand
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stallwatch import StallWatch
from seaway.vessel.guidance import LosGains
from seaway.vessel.model import VesselParams

from seaway_controller.core import ControllerCore
from seaway_controller.keeper import Fallback, ThrustKeeper, overrun_command

STEP_STALL_S = 1.0
"""Real time: a control step still running after this long is logged with the loop's stack
(``seaway.runtime.stallwatch``) [s]: past vehicle_io's thrust watchdog, well before the launcher's
liveness restarts a controller silent on ``ctrl/thrust``, so the log says where it hung."""


class Flying(NamedTuple):
    """What the keeper's fallback flies: the active mission's leg and speed hint (None: none
    active), and the last command's sequence number."""

    leg: tuple[tuple[float, float], tuple[float, float]] | None
    speed_hint_mps: float | None
    seq: int


def flying_of(core: ControllerCore) -> Flying:
    """The core's ``Flying`` now (under the core's lock, which a stuck step holds: so it is kept
    as of the last step or request, not read while a step runs)."""
    mm = core.missions
    if mm.state == "active" and mm.mission is not None:
        return Flying(mm.leg(), mm.mission.speed_hint_mps, core.seq)
    return Flying(None, None, core.seq)


class RealTime:
    """The real-time loop's state: the last state stepped on, whether its staleness was said, the
    keeper and the stall watch. ``publish`` sends a thrust command."""

    def __init__(self, publish: Callable[[ThrustCommand], None], period_s: float,
                 max_state_age_s: float, stop: threading.Event, log: logging.Logger) -> None:
        self.period_s, self.max_state_age_s = period_s, max_state_age_s
        self.log = log
        # A step stuck for long is logged with where it is, before a restart ends it.
        self.watch = StallWatch(log, "control loop", STEP_STALL_S, stop)
        # A step that overruns gets a command sent in its place (keeper.py), on time.
        self.keeper = ThrustKeeper(publish, period_s, log, stop)
        self.last_stamp: int | None = None  # the last state's stamp (stepped on or not)
        self.stale_reported = False

    def due(self, state: StateEstimate | None, now_ns: int) -> StateEstimate | None:
        """``state`` (the newest heard, its stamp already bounded) if it is new since the last
        tick and fresh: the state to step on now; else None."""
        if state is None or state.stamp_ns == self.last_stamp:
            return None
        self.last_stamp = state.stamp_ns
        if (now_ns - state.stamp_ns) / 1e9 > self.max_state_age_s:
            return None
        self.stale_reported = False
        return state

    def stale(self, now_ns: int) -> int | None:
        """The last state's stamp if it is older than ``max_state_age_s`` at ``now_ns`` (no fresh
        state: hold still rather than act on old information; said once), else None."""
        if self.last_stamp is None or (now_ns - self.last_stamp) / 1e9 <= self.max_state_age_s:
            return None
        if not self.stale_reported:
            self.log.warning("%s older than %.2f s: commanding zero thrust",
                             keys.NAV_STATE.suffix, self.max_state_age_s)
            self.stale_reported = True
        return self.last_stamp

    def run_step(self, step: Callable[[], None], fallback: Fallback, ratelog: RateLimitedLog
                 ) -> None:
        """Run one control step, watched, with ``fallback`` sent in its place while it overruns
        (the step ends the keeper's turn itself before it publishes its own command)."""
        t0 = time.perf_counter()
        self.watch.begin()
        self.keeper.begin(fallback)
        try:
            step()
        finally:
            self.keeper.end()
            self.watch.end()
        warn_slow_step(ratelog, time.perf_counter() - t0, self.period_s)

    def fallback(self, state: StateEstimate, newest: StateEstimate | None, now_ns: int,
                 flying: Flying | None, vessel: VesselParams, los: LosGains,
                 stop: bool) -> ThrustCommand | None:
        """The command ``ThrustKeeper`` sends in the place of the step for ``state``
        (``keeper.overrun_command``): line-of-sight guidance on the leg flown at the last step,
        from the ``newest`` state heard (not ahead of ``now_ns``, not older than
        ``max_state_age_s``: else zero thrust); ``stop``: zero thrust."""
        leg, hint, seq = flying or (None, None, 0)
        if newest is not None and state.stamp_ns <= newest.stamp_ns <= now_ns:
            state = newest
        stale = (now_ns - state.stamp_ns) / 1e9 > self.max_state_age_s
        return overrun_command(state, leg, vessel, los, hint, seq, stop=stop or stale)


def warn_slow_step(ratelog: RateLimitedLog, took_s: float, period_s: float) -> bool:
    """Real time: a WARNING (rate-limited) when one control step took ``took_s`` [s], longer than
    the control period ``period_s`` [s], so that a late or missing command names its cause in the
    log. True if the step was slow."""
    if took_s <= period_s:
        return False
    ratelog.warning("slow-step", "a control step took %.3f s, longer than the control period "
                    "(%.3f s): the thrust command came late; the solve records (%s) say "
                    "which solver ran", took_s, period_s, keys.SOLVE.suffix)
    return True
