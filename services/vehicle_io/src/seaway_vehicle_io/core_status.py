"""The core's VehicleStatus: link, armed state, mode, failsafe, battery, rates, refusals, and why the
autopilot took the vessel or would not drive the thrusters.

Stamped with the wall clock; ages (the last HEARTBEAT's) in seconds of monotonic time. It owns
the autopilot's condition as heard: the hold reason (``failsafe_cause``) and its health
(``autopilot_health``), both reset by a loss or a reboot.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING

from seaway.contract.messages import HoldReason, ThrustWithheld, VehicleStatus

from seaway_vehicle_io.autopilot_health import Health, latched_failsafe
from seaway_vehicle_io.conversions import worse_level
from seaway_vehicle_io.core_outputs import Now, Output, Publish
from seaway_vehicle_io.failsafe_cause import FailsafeCause
from seaway_vehicle_io.status_pacing import StatusPacer
from seaway_vehicle_io.watchdog import FAILSAFE_THRUST_STALE

if TYPE_CHECKING:
    from seaway.contract.messages import BatteryLevel

    from seaway_vehicle_io.authority import Refusals
    from seaway_vehicle_io.conversions import BatteryReading
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.core_params import ParamCheck
    from seaway_vehicle_io.fence_sync import FenceSync
    from seaway_vehicle_io.rates import RateWatch
    from seaway_vehicle_io.watchdog import ThrustWatchdog

log = logging.getLogger("seaway.vehicle_io")

FAILSAFE_AUTOPILOT_CONFIG = "autopilot_config"


class StatusReport:
    """The status part of ``VehicleIoCore``: owns the hold reason, the health, the health problem
    last logged, the thrust-withheld reason last published and the pacing of the statuses said at
    once (``status_pacing``)."""

    # read from the other parts
    link: LinkState
    params: ParamCheck
    watchdog: ThrustWatchdog
    battery: BatteryReading
    battery_said: tuple[BatteryLevel, str] | None
    rates_hz: dict[str, float]
    dropped: int
    refusals: Refusals
    rate_watch: RateWatch | None
    fence: FenceSync | None

    def _init_status(self) -> None:
        """Last: the thrust-withheld reason is the other parts' state as it starts."""
        self.hold = FailsafeCause()  # why the autopilot took the vessel (failsafe_cause.py)
        self.health = Health()  # is it fit to start a mission (autopilot_health.py)
        self._health_said: str | None = None  # the health problem last logged
        self._health_quiet = False  # that one was said at INFO, the autopilot starting
        self._withheld: ThrustWithheld | None = self.thrust_withheld()  # as last published
        # A change said at once, at most once per gap; ``tick`` says a held one at the gap's end.
        self.status_pacer = StatusPacer()

    def _say_status(self, now: Now) -> list[Output]:
        """A change to say at once: its status, or nothing if one was said less than
        ``MIN_STATUS_GAP_NS`` ago; then ``tick`` says it at the gap's end, as the state is then."""
        if not self.status_pacer.may_say(now.mono_ns):
            return []
        return [Publish(self.status(now))]

    def failsafe(self, now: Now) -> str | None:
        """The failsafe to report, most serious first."""
        a = self.params.assessment
        if a is not None and a.blocking:
            return FAILSAFE_AUTOPILOT_CONFIG
        if self.watchdog.active(now.mono_ns) is None:
            return FAILSAFE_THRUST_STALE
        return None

    def failsafe_latched(self) -> tuple[HoldReason, str] | None:
        """The failsafe the autopilot still stands in, and what says so (``autopilot_health``)."""
        said = self.battery_said
        level = worse_level(self.battery.level, None if said is None else said[0])
        return latched_failsafe(self.health.failsafe_bits, level, "" if said is None else said[1])

    def _say_health(self, now: Now) -> None:
        """Log what the autopilot lacks when that changes: at INFO while it is starting
        (``Health.starting``: the expected state of a start, which the status shows), as a WARNING
        after. A lack said at INFO that outlasts the start is said again, once, as a WARNING."""
        health = self.health
        problem = health.problem()
        starting = health.starting(now.mono_ns)
        overdue = self._health_quiet and problem is not None and not starting
        if problem == self._health_said and not overdue:
            return
        up_s = (now.mono_ns - health.since_mono_ns) / 1e9
        if problem is None:
            if self._health_said is not None:
                self._log_change(now, "health", logging.INFO, "the autopilot is healthy again "
                                 "(estimator, status, sensors)" if not self._health_quiet else
                                 f"the autopilot is healthy (estimator, status, sensors), {up_s:.0f} s "
                                 "after it came up")
        elif starting:
            self._log_change(now, "health", logging.INFO, f"{problem} (starting: {up_s:.0f} s since "
                             "it came up)")
        else:
            self._log_change(now, "health", logging.WARNING, f"{problem} ({up_s:.0f} s since it came "
                             "up, not healthy yet)" if overdue and not health.ready else problem)
        self._health_said = problem
        self._health_quiet = starting and problem is not None

    def autopilot_starting(self, now: Now) -> bool:
        """Whether the autopilot is still starting (``Health.starting``): what it refuses and lacks
        meanwhile is the expected state of a start."""
        return self.link.ok and self.health.starting(now.mono_ns)

    def status(self, now: Now) -> VehicleStatus:
        link = self.link
        self._withheld = self.thrust_withheld()
        latched = self.failsafe_latched()
        self._say_health(now)
        hb_age = (None if link.last_heartbeat_mono_ns is None
                  else max(0.0, (now.mono_ns - link.last_heartbeat_mono_ns) / 1e9))
        return VehicleStatus.make(
            stamp_ns=now.wall_ns,
            autopilot=link.profile.name if link.profile else "unknown",
            link_ok=link.ok,
            armed=link.armed,
            mode=link.mode,
            failsafe=self.failsafe(now),
            battery_voltage_v=self.battery.voltage_v,
            battery_remaining_frac=self.battery.remaining_frac,
            heartbeat_age_s=hb_age,
            rates_hz=dict(self.rates_hz),
            dropped_messages=self.dropped,
            refused_messages=dict(self.refusals.by_reason),
            # A standing hazard, not an event: reported beside the failsafe, not as one.
            autopilot_loss_failsafe=None if self.params.assessment is None
            else self.params.assessment.verdict,
            autopilot_loss_failsafe_summary="" if self.params.assessment is None
            else self.params.assessment.summary,
            hold_reason=self.hold.cause,
            hold_reason_detail=self.hold.detail,
            telemetry_rates_short=None if self.rate_watch is None or self.rate_watch.short is None
            else dict(self.rate_watch.short),
            thrust_withheld=self._withheld,
            refused_thrust=self.refused_thrust(),
            autopilot_fence=self.fence.report() if self.fence is not None else None,
            autopilot_unhealthy_detail=self.health.problem() or "",
            failsafe_latched=None if latched is None else latched[0],
            failsafe_latched_detail="" if latched is None else latched[1],
        )

    def _hold_changed(self, changed: bool, now: Now) -> None:
        if changed:
            self._log_change(now, "hold", logging.WARNING,
                             f"autopilot took the vessel: {self.hold.cause} ({self.hold.detail})")
