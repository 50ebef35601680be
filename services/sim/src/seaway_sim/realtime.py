"""Real time: the sim's node on the wall clock, driven through its PX4-like MAVLink endpoint.

Two threads share the core under ``SimNode.lock``:

* the link thread waits on the UDP socket and hands every decoded message to the autopilot core at
  once (so a COMMAND_ACK does not wait for a tick), sending its answers back;
* the runtime's rate loop (``seaway.runtime.node.LiveDriver``) ticks every ``--step`` (10 ms): the
  node asks the autopilot for the thrust, advances the plant to the tick (after missed ticks, by all
  of them: simulated time never falls behind the wall clock), sends the sensor and periodic MAVLink
  telemetry that fell due, and every ``--period`` publishes SIM_TRUTH, SIM_DISTURBANCE and SIM_CLOCK
  on the bus; it keeps the plant's state for a restarted sim (``seaway_sim.plant_kept``).

Time: the autopilot's "time since boot" and the core's sim time are both nanoseconds since the sim
started (monotonic); bus stamps are the wall clock at start plus that (``SimCore.epoch_ns``).
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING

from seaway.simkit.scenario import Scenario
from seaway.simkit.sensors import instants_in
from seaway.vessel.model import VesselParams

from seaway_sim.mavlink_link import MavlinkLink
from seaway_sim.plant_kept import PlantKeeper
from seaway_sim.px4_autopilot import Px4Autopilot

if TYPE_CHECKING:
    from seaway_sim.node import SimNode

log = logging.getLogger("seaway_sim.realtime")

_RECEIVE_POLL_S = 0.1  # the link thread's longest wait, bounding how late it notices a stop


class Realtime:
    """The sim node's real-time half: plant on the wall clock, MAVLink in and out."""

    def __init__(self, app: SimNode, autopilot: Px4Autopilot, link: MavlinkLink, step_s: float,
                 period_s: float, boot_monotonic_ns: int, keeper: PlantKeeper | None = None) -> None:
        self.app = app
        self.autopilot = autopilot
        self.link = link
        self.step_ns = round(step_s * 1e9)
        self.publish_period_ns = round(period_s * 1e9)
        self.stop = threading.Event()
        self.boot_ns = boot_monotonic_ns
        self._done = 0  # the whole steps since boot the world is advanced to
        self._started = False  # the first tick's catch-up over the set-up is no overrun
        self._receiver: threading.Thread | None = None
        self.overrun_ticks = 0
        self.keeper = keeper
        """Keeps the plant's state for a restarted sim (``seaway_sim.plant_kept``); None: not kept."""
        app.on_load.append(self._on_load)

    def _on_load(self, scenario: Scenario, vessel: VesselParams) -> None:
        self.autopilot.thrust_max_n = vessel.thrust_max_n
        self.autopilot.last_fix = None  # never report the old world's position after a swap

    def since_boot_ns(self) -> int:
        return time.monotonic_ns() - self.boot_ns

    def _link_thread(self) -> None:
        while not self.stop.is_set():
            msgs = self.link.receive(_RECEIVE_POLL_S)
            if not msgs:
                continue
            with self.app.lock:
                now = self.since_boot_ns()
                for msg in msgs:
                    self.link.send(self.autopilot.handle(msg, now))

    def start(self, stop: threading.Event) -> None:
        """Start the link thread; it ends with ``stop`` (the service's) or ``close``."""
        self.stop = stop
        log.info("real time: MAVLink on udpin:%s:%d, step %.3f s, truth every %.3f s",
                 *self.link.address, self.step_ns / 1e9, self.publish_period_ns / 1e9)
        self._receiver = threading.Thread(target=self._link_thread, name="mavlink-rx", daemon=True)
        self._receiver.start()

    def tick(self, index: int) -> None:
        """At a tick of the rate loop: advance the world to the whole steps since boot (more than
        one after missed ticks) and send what fell due (lock held by the caller).

        Counted from boot, not from the loop's ``index``: the loop starts after the set-up that
        follows boot (a second under load), and counting its ticks left the world, its telemetry's
        time_boot_ms and its bus stamps that far behind the autopilot's own clock (commands, the
        loss failsafe), so a failsafe acting on time was stamped 0.17 s early. The first tick
        catches the world up over that set-up (not an overrun)."""
        due = self.since_boot_ns() // self.step_ns
        ticks = due - self._done
        if ticks <= 0:
            return
        if ticks > 1 and self._started:
            self.overrun_ticks += ticks - 1
        self._started = True
        self._done = due
        self.advance(ticks)

    def advance(self, ticks: int) -> None:
        """Advance the world by ``ticks`` steps and send what fell due (lock held by the caller)."""
        core, ap = self.app.core, self.autopilot
        before = core.t_ns
        thrust = ap.thrust_n(self.since_boot_ns())
        core.advance(thrust, ticks * self.step_ns)
        samples = core.take_samples()
        gnss_ok = core.gnss_ok()
        self.link.send(ap.sensor_telemetry(samples.gnss, samples.attitude, core.epoch_ns,
                                           core.origin))
        self.link.send(ap.periodic_telemetry(before, core.t_ns, core.epoch_ns, core.pack_reading(),
                                             gnss_ok, self.link.garbage))
        if instants_in(self.publish_period_ns, before, core.t_ns):
            self.app.publish_truth(1.0)
        if self.keeper is not None:
            self.keeper.tick(core)

    def close(self) -> None:
        """The service stops: the link thread joined, the plant kept one last time."""
        self.stop.set()
        if self._receiver is not None:
            self._receiver.join(2 * _RECEIVE_POLL_S)
        if self.keeper is not None:
            with self.app.lock:
                self.keeper.close(self.app.core)
        log.info("real time ended at t = %.3f s (%d overrun ticks caught up); link %s; "
                 "autopilot %s", self.app.core.t_ns / 1e9, self.overrun_ticks,
                 dict(self.link.counters), dict(self.autopilot.counters))
