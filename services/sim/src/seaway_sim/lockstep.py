"""Lockstep: the sim owns time and advances one control period per thrust command (no MAVLink).

THE LOCKSTEP PROTOCOL (services/sim/README.md says the same):

Sim time starts at t_0 = 0 ns (the sim epoch) and t_{k+1} = t_k + period (``--period``, 0.1 s). For
each k, from one Zenoh session and in this order:

  (a) publish the sensor samples due in (t_{k-1}, t_k] (at k = 0: those at t = 0) on GNSS and
      ATTITUDE, each stamped with its own sample instant (GnssFix carries vel_n/vel_e as SOG; a fix
      due inside a dropout is not published); then SIM_TRUTH and SIM_DISTURBANCE stamped t_k; and
      LAST ``ClockTick(stamp_ns=t_k, lockstep=True)``;
  (b) wait for a ThrustCommand on THRUST with ``stamp_ns >= t_k`` (the controller stamps a command
      with the stamp of the nav/state it was computed from; the estimator stamps nav/state with the
      sim time it has processed up to, t_k). Commands stamped before t_k are stale: ignored and
      counted.
      If none arrives within ``--lockstep-timeout`` (5 s wall) the sim logs, republishes the whole
      period of (a) unchanged -- the same sensor samples with the same stamps, truth and the tick --
      so that a process that joined late (or missed the first samples of a new connection) can
      start, and keeps waiting: it never steps on its own. Receivers treat a sample whose stamp
      equals the last one on its key as a repeat;
  (c) apply that command (T1 port, T2 starboard, N; the plant saturates) for one period, so the
      state goes to t_{k+1}; back to (a).

A scenario loaded through ``sim/scenario`` while (b) waits restarts the vessel at the same t_k: the
sim goes back to (a) and publishes the new scenario's first outputs, still stamped t_k.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand

from seaway_sim.app import SimApp

log = logging.getLogger("seaway_sim.lockstep")

_POLL_S = 0.05  # how often a wait looks at the stop flag and the scenario generation


@dataclass
class LockstepStats:
    periods: int = 0
    stale_commands: int = 0
    timeouts: int = 0


class Lockstep:
    """The lockstep loop over one ``SimApp``."""

    def __init__(self, app: SimApp, period_s: float, timeout_s: float,
                 stop: threading.Event) -> None:
        if not period_s > 0 or not timeout_s > 0:
            raise ValueError("period and timeout must be > 0")
        self.app = app
        self.period_ns = round(period_s * 1e9)
        self.timeout_s = timeout_s
        self.stop = stop
        self.stats = LockstepStats()
        self.pub_gnss = app.bus.publisher(keys.GNSS)
        self.pub_attitude = app.bus.publisher(keys.ATTITUDE)
        self.commands = app.bus.subscribe(keys.THRUST, mode="fifo")
        self._last_samples: tuple[list, list] = ([], [])

    def publish_period(self) -> tuple[int, int]:
        """Step (a); returns (t_k, scenario generation) it published for."""
        app = self.app
        with app.lock:
            samples = app.core.take_samples()
            self._last_samples = ([f for f in samples.gnss if f is not None], list(samples.attitude))
            self._publish_samples()
            app.publish_truth(None)
            return app.core.stamp_ns, app.generation

    def _publish_samples(self) -> None:
        gnss, attitude = self._last_samples
        for fix in gnss:
            self.pub_gnss.put(fix)
        for att in attitude:
            self.pub_attitude.put(att)

    def republish_period(self, generation: int) -> None:
        """Step (a) again, unchanged, for late joiners (the hold of step (b))."""
        with self.app.lock:
            if self.app.generation == generation:
                self._publish_samples()
                self.app.publish_truth(None)

    def wait_command(self, t_k: int, generation: int) -> ThrustCommand | None:
        """Step (b): the first command stamped >= t_k; None if stopped or the scenario changed."""
        deadline = time.monotonic() + self.timeout_s
        while not self.stop.is_set():
            if self.app.generation != generation:
                return None
            cmd = self.commands.get(_POLL_S)
            if cmd is not None:
                if cmd.stamp_ns >= t_k:
                    return cmd
                self.stats.stale_commands += 1
                log.debug("ignored stale thrust command stamped %d < t_k %d", cmd.stamp_ns, t_k)
                continue
            if time.monotonic() >= deadline:
                self.stats.timeouts += 1
                log.warning("lockstep: no thrust command stamped >= %d ns (t = %.3f s) for %.1f s; "
                            "holding and republishing the period", t_k, t_k / 1e9, self.timeout_s)
                self.republish_period(generation)
                deadline = time.monotonic() + self.timeout_s
        return None

    def step(self, cmd: ThrustCommand, generation: int) -> bool:
        """Step (c); False (nothing done) if the scenario changed since step (a)."""
        with self.app.lock:
            if self.app.generation != generation:
                return False
            self.app.core.advance((cmd.thrust_port_n, cmd.thrust_starboard_n), self.period_ns)
        self.stats.periods += 1
        return True

    def run(self, max_periods: int | None = None) -> LockstepStats:
        """Run until stopped (or ``max_periods`` commands applied)."""
        log.info("lockstep: period %.3f s, timeout %.1f s; waiting for commands on %s",
                 self.period_ns / 1e9, self.timeout_s, self.app.bus.key(keys.THRUST))
        while not self.stop.is_set() and (max_periods is None or self.stats.periods < max_periods):
            t_k, generation = self.publish_period()
            cmd = self.wait_command(t_k, generation)
            if cmd is not None:
                self.step(cmd, generation)
        log.info("lockstep ended at t = %.3f s: %d periods, %d stale commands ignored, %d timeouts",
                 self.app.core.t_ns / 1e9, self.stats.periods, self.stats.stale_commands,
                 self.stats.timeouts)
        return self.stats
