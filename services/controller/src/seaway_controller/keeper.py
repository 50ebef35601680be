"""Real time: keep ``ctrl/thrust`` going while a control step overruns.

The loop publishes one command per step, so a step that runs long leaves the thrusters without one:
past vehicle_io's thrust watchdog (``thrust_timeout_s``, 0.3 s) it sends neutral and reports
``thrust_stale``, and past the launcher's liveness (5 s silent on ``ctrl/thrust``) the process is
restarted. ``ThrustKeeper`` runs a thread of its own: the loop calls ``begin`` with the step's
fallback before each step and ``end`` once the step has its command; a step still running
``KEEP_AFTER_PERIODS`` control periods after it began gets the fallback published in its place,
then once a period, on time, until it ends. The fallback (``overrun_command``) is the fallback
chain's line-of-sight guidance on the active leg, from the newest state heard (it does not wait for
the core, whose lock the stuck step holds), or zero thrust when no mission is flown.

A step stuck for ``KEEP_MAX_S`` is not one that runs late but one that hangs: the keeper then
commands zero thrust once, says so, and stops, so that the silence that follows lets the
launcher's liveness restart the process (line-of-sight guidance flown for ever on a leg the stuck
core no longer switches would run past its waypoint).

Commands sent in a step's place carry the sequence number of the last command the core made, and
their energy is not in the core's count (it counts the commands it made, over the time they held).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

from seaway.contract.messages import StateEstimate, ThrustCommand
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel.guidance import LosGains, los_thrust
from seaway.vessel.model import VesselParams

KEEP_AFTER_PERIODS = 1.5
"""A step still running this many control periods after it began gets a command published in its
place: the last command went out at the end of the step before, so the thrusters then go at most
about 2.5 periods (0.25 s at 10 Hz) without one, inside vehicle_io's 0.3 s watchdog."""
KEEP_MAX_S = 2.0
"""A step still running this long hangs [s]: zero thrust once, then silence (module docstring)."""
SOURCE_LOS = "overrun-los"
"""``ThrustCommand.source`` of line-of-sight guidance sent in the place of an overrunning step."""
SOURCE_STOP = "overrun-stop"
"""``ThrustCommand.source`` of zero thrust sent in the place of an overrunning step (no mission
flown, no fresh state, or the step hangs)."""


def overrun_command(state: StateEstimate | None, leg: tuple[tuple[float, float], tuple[float, float]] | None,
                    vessel: VesselParams, gains: LosGains, speed_hint_mps: float | None, seq: int,
                    stop: bool = False) -> ThrustCommand | None:
    """The command sent in the place of an overrunning step: line-of-sight guidance along ``leg``
    (P_{i-1}, P_i) [m, local NED] from ``state`` (stamped with its stamp), zero thrust without a
    leg or with ``stop``; None without a state (nothing to stamp it with)."""
    if state is None:
        return None
    if leg is None or stop:
        thrust, source = (0.0, 0.0), SOURCE_STOP
    else:
        x0 = (state.u_mps, state.v_mps, state.r_radps, state.x_m, state.y_m, state.psi_rad)
        thrust, source = los_thrust(x0, leg[0], leg[1], vessel, gains, speed_hint_mps), SOURCE_LOS
    return ThrustCommand.make(stamp_ns=state.stamp_ns, thrust_port_n=thrust[0],
                              thrust_starboard_n=thrust[1], source=source, seq=seq)


Fallback = Callable[[bool], ThrustCommand | None]
"""Makes the command sent in a step's place now; its argument is ``stop`` (zero thrust)."""


class ThrustKeeper:
    """Publishes a step's fallback while the step overruns (module docstring)."""

    def __init__(self, publish: Callable[[ThrustCommand], None], period_s: float,
                 log: logging.Logger, stop: threading.Event) -> None:
        if not period_s > 0:
            raise ValueError(f"period_s must be > 0 s, got {period_s}")
        self.publish, self.period_s, self.log, self.stop = publish, period_s, log, stop
        self._ratelog = RateLimitedLog(log)  # steps overrunning one after another: now and then
        self.sent = 0  # commands sent in a step's place so far
        self.overruns = 0  # steps that had one sent in their place
        self._cond = threading.Condition()
        self._step = 0  # the running step's number (0: none yet)
        self._fallback: Fallback | None = None  # the running step's, None once it ended
        self._started = 0.0  # monotonic [s]
        self._thread: threading.Thread | None = None

    def begin(self, fallback: Fallback) -> None:
        """A step starts; ``fallback`` makes the command sent in its place."""
        with self._cond:
            self._step += 1
            self._fallback, self._started = fallback, time.monotonic()
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, name="thrust-keeper", daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def end(self) -> None:
        """The step has its command (to be published by the loop): none is sent in its place
        from now on. Idempotent."""
        with self._cond:
            self._fallback = None
            self._cond.notify_all()

    def _run(self) -> None:
        while not self.stop.is_set():
            with self._cond:
                while self._fallback is None and not self.stop.is_set():
                    self._cond.wait(0.5)
                step, started = self._step, self._started
            self._keep(step, started)

    def _keep(self, step: int, started: float) -> None:
        """Publish in step ``step``'s place, from ``KEEP_AFTER_PERIODS`` after ``started`` and
        once a period, until it ends; zero thrust and silence past ``KEEP_MAX_S``."""
        due = started + KEEP_AFTER_PERIODS * self.period_s
        first = True
        while not self.stop.is_set():
            with self._cond:
                while (self._step == step and self._fallback is not None and not self.stop.is_set()
                       and (left := due - time.monotonic()) > 0):
                    self._cond.wait(left)
                if self._step != step or self._fallback is None or self.stop.is_set():
                    return
                hung = time.monotonic() - started >= KEEP_MAX_S
                # Under the condition: ``end`` cannot return while a command for its step goes out,
                # so none follows the step's own.
                cmd = self._fallback(hung)
                if cmd is not None:
                    self.publish(cmd)
                    self.sent += 1
                    self.overruns += first
                if first or hung:
                    self._say(first, hung, cmd, time.monotonic() - started)
                first = False
                if hung:
                    self._fallback = None  # silence from now on: the liveness sees a hang
                    return
            due += self.period_s

    def _say(self, first: bool, hung: bool, cmd: ThrustCommand | None, running_s: float) -> None:
        what = "nothing (no state heard)" if cmd is None else f"{cmd.source} thrust"
        if hung:
            self.log.error("a control step has not ended in %.1f s: commanded %s and stopped "
                           "commanding in its place (a process silent on the thrust is restarted)",
                           running_s, what)
        elif first:
            self._ratelog.warning("overrun", "a control step overran: %.2f s so far "
                                  "(control period %.3f s); commanding %s in its place, once a "
                                  "period, until it ends", running_s, self.period_s, what)
