"""Fly the identification manoeuvre on a running vessel, through vehicle_io: ``seaway identify fly``.

The flyer takes the controller's part in a run (the launcher's ``identify-ardupilot`` profile runs it
in the controller's place, with the controller's identity and so its right to publish ctrl/thrust):
it publishes the manoeuvre's commands on ``ctrl/thrust`` every control period, in real time, while
the recorder records the run. ``seaway identify fit`` then fits a model to that recording.

``FlyCore`` is the pure part (time and vehicle status in, a command and a verdict out):

* **waiting**: it sends neutral (0 N) until vehicle_io reports the link up, the vessel armed and the
  thrust reaching the thrusters (``VehicleStatus.thrust_withheld`` None), at most ``wait_s``;
* **flying**: the manoeuvre's thrust at ``t - t_start``. If the autopilot stops taking thrust
  mid-run (disarmed, a failsafe's mode, the link lost) the flight is aborted: neutral, and the
  reason; what was recorded so far is kept (a fit may still use it);
* **done**: after the manoeuvre, neutral for ``TAIL_S`` so the last coast is recorded.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from dataclasses import dataclass, field
from typing import Literal

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand, VehicleStatus
from seaway.contract.units import NS_PER_S
from seaway.runtime import service
from seaway.runtime.argtypes import positive_float
from seaway.vessel.model import load_vessel

from seaway_lab.identify.manoeuvre import Manoeuvre

log = logging.getLogger("seaway.identify.fly")
SOURCE = "identify"
"""``ThrustCommand.source`` of the manoeuvre's commands (the recording shows who moved the boat)."""
TAIL_S = 3.0
"""Neutral after the manoeuvre before the flyer ends: the final coast is recorded, then the stop."""
STATUS_STALE_S = 2.0
"""A vehicle status older than this counts as no status (vehicle_io publishes it at 2 Hz or more)."""
PROGRESS_EVERY_S = 15.0

Phase = Literal["waiting", "flying", "done", "aborted"]


@dataclass
class FlyCore:
    """The flight's decisions; ``step`` is called every control period with the time [s, monotonic]."""

    manoeuvre: Manoeuvre
    wait_s: float = 300.0
    phase: Phase = "waiting"
    reason: str = ""
    t_created_s: float | None = None
    t_start_s: float | None = None
    seq: int = 0
    _last_status: tuple[float, VehicleStatus] | None = field(default=None, repr=False)

    def on_status(self, t_s: float, status: VehicleStatus) -> None:
        self._last_status = (t_s, status)

    def withheld(self, t_s: float) -> str | None:
        """Why thrust does not reach the thrusters now (None: it does)."""
        if self._last_status is None:
            return "no vehicle status from vehicle_io yet"
        t_seen, st = self._last_status
        if t_s - t_seen > STATUS_STALE_S:
            return f"no vehicle status for {t_s - t_seen:.1f} s"
        if not st.link_ok:
            return "no autopilot link"
        if not st.armed:
            return "not armed"
        if st.thrust_withheld is not None:
            return f"thrust withheld ({st.thrust_withheld}; mode {st.mode})"
        return None

    def step(self, t_s: float, wall_ns: int) -> ThrustCommand:
        """The command for now (``wall_ns`` stamps it); moves the phase on."""
        if self.t_created_s is None:
            self.t_created_s = t_s
        port = starboard = 0.0
        why = self.withheld(t_s)
        if self.phase == "waiting":
            if why is None:
                self.phase, self.t_start_s = "flying", t_s
                log.info("the vessel takes thrust: flying the manoeuvre (%.0f s)",
                         self.manoeuvre.duration_s)
            elif t_s - self.t_created_s > self.wait_s:
                self.phase, self.reason = "aborted", f"not flown: after {self.wait_s:g} s still {why}"
        if self.phase == "flying":
            assert self.t_start_s is not None
            elapsed = t_s - self.t_start_s
            if why is not None:
                self.phase = "aborted"
                self.reason = (f"aborted {elapsed:.1f} s into the manoeuvre: {why}; the recording so "
                               "far is kept")
            elif elapsed >= self.manoeuvre.duration_s + TAIL_S:
                self.phase = "done"
            else:
                port, starboard = self.manoeuvre.thrust_n(elapsed)
        self.seq += 1
        return ThrustCommand.make(stamp_ns=wall_ns, thrust_port_n=port, thrust_starboard_n=starboard,
                                  source=SOURCE, seq=self.seq)

    def elapsed_s(self, t_s: float) -> float:
        return 0.0 if self.t_start_s is None else t_s - self.t_start_s

    @property
    def finished(self) -> bool:
        return self.phase in ("done", "aborted")


def add_arguments(ap: argparse.ArgumentParser) -> None:
    """``seaway identify fly``'s own options (besides a service's: vessel, run, credentials)."""
    ap.add_argument("--level-n", type=positive_float, default=None,
                    help="the manoeuvre's full thrust per thruster [N] (default: a fifth of the "
                         "model vessel's thrust_max_n; the fit is valid over the range flown, so pick "
                         "the range the missions will use)")
    ap.add_argument("--wait", type=positive_float, default=300.0, metavar="S",
                    help="how long to wait for the vessel to take thrust (armed, in a manual mode) "
                         "[s] (default 300)")


def fly(args: argparse.Namespace) -> int:
    """The thin loop: the bus, the period, the signals. 0 flown, 1 aborted or not flown, 2 bad args."""
    run = service.resolve_run(args, "controller")
    vessel = load_vessel(run.model_vessel_file)
    if vessel.dead_zone_n > 0:
        # vehicle_io sends a demand inside the model's dead zone at its edge (or 0): the slow ramp
        # would jump over the boat's dead zone, and the fit, which reads the demands, would find
        # none and misplace every low-thrust step.
        print(f"seaway identify fly: the run's vessel file {run.model_vessel_file} has dead_zone_n "
              f"= {vessel.dead_zone_n:g} N, and vehicle_io compensates it (a demand inside it goes "
              "out at its edge or as 0), so the manoeuvre could not show the boat's dead zone. Fly "
              "with a vessel file whose dead_zone_n is 0: the base the fit starts from (the "
              "profile's vessel_file, or --vessel-file)", file=sys.stderr)
        return 2
    level = args.level_n if args.level_n is not None else vessel.thrust_max_n / 5.0
    if not 0 < level <= vessel.thrust_max_n:
        print(f"seaway identify fly: --level-n must be in (0, {vessel.thrust_max_n:g}] N (the "
              f"vessel's thrust_max_n), got {level:g}", file=sys.stderr)
        return 2
    core = FlyCore(Manoeuvre(level_n=level, reverse_level_n=min(level, vessel.reverse_max_n)),
                   wait_s=args.wait)
    period_ns = run.control_period_ns
    # The controller's part in the run: its identity (the right to publish ctrl/thrust), its health
    # token, its agreement on the run.
    with service.run_service("controller", args, run=run) as ctx:
        pub = ctx.bus.publisher(keys.THRUST)
        ctx.bus.subscribe(keys.VEHICLE_STATUS, inline=True,
                          callback=lambda _key, st: core.on_status(time.monotonic(), st))
        ctx.ready()
        log.info("identify fly: level %.3g N per thruster, %.0f s, period %.3g s; waiting for the "
                 "vessel to take thrust", level, core.manoeuvre.duration_s, period_ns / NS_PER_S)
        next_ns = time.monotonic_ns()
        last_progress = -PROGRESS_EVERY_S
        while not ctx.stop.is_set() and not core.finished:
            now = time.monotonic()
            pub.put(core.step(now, ctx.clock.now_ns()))
            if core.phase == "flying" and core.elapsed_s(now) - last_progress >= PROGRESS_EVERY_S:
                last_progress = core.elapsed_s(now)
                log.info("manoeuvre %3.0f %% (%.0f of %.0f s)",
                         100 * min(1.0, last_progress / core.manoeuvre.duration_s), last_progress,
                         core.manoeuvre.duration_s)
            next_ns += period_ns
            ctx.clock.sleep_until(next_ns, ctx.stop)
        # Neutral, a few times: the autopilot's watchdog would get there too, but later.
        for _ in range(3):
            pub.put(ThrustCommand.make(stamp_ns=ctx.clock.now_ns(), thrust_port_n=0.0,
                                       thrust_starboard_n=0.0, source=SOURCE, seq=core.seq + 1))
            core.seq += 1
            time.sleep(period_ns / NS_PER_S)
    if core.phase == "done":
        log.info("manoeuvre flown (%.0f s)", core.manoeuvre.duration_s)
        return 0
    log.error("identify fly: %s", core.reason or "stopped before the manoeuvre was flown")
    return 1
