"""The core's thrust path: ThrustCommands in (N per thruster), MANUAL_CONTROL axes out.

A command is refused before it reaches the autopilot when its thrust is absurd or its stamp is out
of bounds (wall clock); the latest admitted one is sent at once and then at
``manual_control_rate_hz`` until the watchdog finds it stale (monotonic time), when neutral goes
out instead. Thrust is normalised against the vessel's ``ThrusterLimits`` and mapped to the
autopilot's axes by its profile (or by the mapping made from its parameters, ``core_params``).
``thrust_withheld`` says why commanded thrust would not reach the thrusters now.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from seaway.contract import keys
from seaway.contract.messages import ThrustCommand, ThrustWithheld
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import STAMP_LOG_EVERY_S, StampBounds, StampGate
from seaway.vessel.thrusters import absurd_thrust

from seaway_vehicle_io.core_outputs import Now, Output, SendManualControl
from seaway_vehicle_io.profile import ManualControlAxes
from seaway_vehicle_io.thrust import ThrusterLimits, normalise_pair
from seaway_vehicle_io.watchdog import ThrustWatchdog

if TYPE_CHECKING:
    from seaway_vehicle_io.autopilot_health import Health
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.core_params import ParamCheck

log = logging.getLogger("seaway.vehicle_io")


class ThrustPath:
    """The thrust part of ``VehicleIoCore``: owns the watchdog, the stamp gate, the refusal counts
    and the MANUAL_CONTROL stream's schedule and record."""

    # read from the other parts
    cfg: VehicleIoConfig
    link: LinkState
    params: ParamCheck
    mapper: Any
    health: Health

    def _init_thrust(self, config: VehicleIoConfig, limits: ThrusterLimits, start: Now) -> None:
        self.limits = limits
        self.watchdog = ThrustWatchdog(config.thrust_timeout_s)
        # The stamp bounds every service applies, held here too: the last step before the thrusters.
        self.thrust_stamps = StampGate("vehicle_io", log, StampBounds.live(config.thrust_max_age_s))
        self.thrust_absurd = 0  # ThrustCommands refused for an absurd thrust
        self._thrust_log = RateLimitedLog(log, STAMP_LOG_EVERY_S)  # as refused stamps are logged
        self.last_axes: ManualControlAxes | None = None
        self.manual_control_sent = 0
        self._period_mc_ns = round(1e9 / config.manual_control_rate_hz)
        self._next_mc_ns = start.mono_ns

    def on_thrust(self, cmd: ThrustCommand, now: Now) -> list[Output]:
        """A ThrustCommand arrived from the bus: becomes the latest, and goes out at once; unless it
        is refused (``thrust_refused``): then it changes nothing and never reaches the autopilot."""
        if self.thrust_refused(cmd, now):
            return []
        out: list[Output] = []
        event = self.watchdog.command(cmd, now.mono_ns)
        if event is not None:
            log.info("thrust commands fresh again (source %r): forwarding", cmd.source)
            out.extend(self._say_status(now))
        out.extend(self._manual_control(now))
        return out

    def thrust_refused(self, cmd: ThrustCommand, now: Now) -> bool:
        """Whether ``cmd`` is refused (counted and logged, at most one line per reason a minute):

        * an absurd thrust (``thrusters.absurd_thrust``: beyond twice the vessel's bounds), which
          saturation would otherwise turn into full power without a word;
        * a stamp over ``MAX_AHEAD_LIVE_S`` ahead of our wall clock or older than
          ``thrust_max_age_s`` (``seaway.runtime.stamps``). A command that stops both thrusters is
          exempt: stopping is always safe (the watchdog does it anyway), and the controller stamps
          its stale-state and shutdown stops with the last state's time, however old."""
        why = absurd_thrust(cmd.thrust_port_n, cmd.thrust_starboard_n, self.limits)
        if why is not None:
            self.thrust_absurd += 1
            self._thrust_log.warning("absurd", "refused a ThrustCommand (source %r): %s. Refused "
                                     "so far: %d (logged at most once a minute)", cmd.source, why,
                                     self.thrust_absurd, now_ns=now.mono_ns)
            return True
        if cmd.thrust_port_n == 0.0 and cmd.thrust_starboard_n == 0.0:
            return False
        return not self.thrust_stamps.admit(keys.THRUST.suffix, cmd.stamp_ns, now.wall_ns,
                                            now_ns=now.mono_ns)

    def refused_thrust(self) -> dict[str, int]:
        """ThrustCommands refused so far, by reason: 'absurd', 'stamp_ahead', 'stamp_behind'."""
        out = {f"stamp_{direction}": n for (_, direction), n in self.thrust_stamps.dropped.items()}
        if self.thrust_absurd:
            out["absurd"] = self.thrust_absurd
        return out

    def thrust_withheld(self) -> ThrustWithheld | None:
        """Why the commanded thrust does not reach the thrusters now, whatever is commanded (None:
        it does): no autopilot link, a configuration under which vehicle_io sends neutral only,
        disarmed, or a mode in which manual control does not drive the thrusters
        (``Profile.thrust_modes``). The watchdog's staleness is not one of these: that is the
        commands stopping, which their sender knows."""
        link = self.link
        if not link.ok or link.profile is None:
            return "no_link"
        a = self.params.assessment
        if a is not None and a.blocking:
            return "autopilot_config"
        if not link.armed:
            return "disarmed"
        if link.mode not in link.profile.thrust_modes:
            return "mode"
        if self.health.problem() is not None:
            return "autopilot_unhealthy"
        return None

    def axes_now(self, now: Now) -> tuple[ManualControlAxes, bool] | None:
        """The MANUAL_CONTROL axes to send now and whether they are neutral; None if no target."""
        link = self.link
        if not link.ok or link.profile is None or link.target_system is None:
            return None
        profile = link.profile
        cmd = self.watchdog.active(now.mono_ns)
        blocked = self.params.assessment is not None and bool(self.params.assessment.blocking)
        # A mapping that depends on parameters (ArduPilot's RC calibration) waits for them.
        unmapped = self.mapper is None and profile.mapping_needs_params
        if (cmd is None or blocked or unmapped
                or (self.cfg.forward_thrust_only_when_armed and not link.armed)):
            return profile.neutral(), True
        left, right = normalise_pair(cmd.thrust_port_n, cmd.thrust_starboard_n, self.limits,
                                     profile.quantisation_guard)
        axes = (self.mapper or profile.manual_control)(left, right)
        return axes, axes == profile.neutral()

    def neutral_command(self) -> SendManualControl | None:
        """Neutral MANUAL_CONTROL for the current target (None without one); used on shutdown."""
        link = self.link
        if not link.ok or link.profile is None or link.target_system is None:
            return None
        return SendManualControl(link.target_system, link.profile.neutral(), True)

    def _manual_control(self, now: Now) -> list[Output]:
        result = self.axes_now(now)
        if result is None:
            return []
        axes, neutral = result
        assert self.link.target_system is not None
        self.last_axes = axes
        self.manual_control_sent += 1
        return [SendManualControl(self.link.target_system, axes, neutral)]
