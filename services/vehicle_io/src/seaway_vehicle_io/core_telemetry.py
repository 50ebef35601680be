"""The core's telemetry in: the autopilot's sensor and battery messages to the bus's SI messages.

Messages carrying ``time_boot_ms`` are stamped on the wall clock through the boot-time offset
(``timesync.BootTimeOffset``), validated before they may move it; its restart, or SYSTEM_TIME going
back, is a reboot, which ends what the autopilot said before it. The conversions themselves
(units, frames: WGS84, NED, radians, volts) are in ``conversions``. Battery messages are stamped at
receipt and completed from the vessel file's battery.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from seaway.contract.messages import BatteryLevel
from seaway.vessel.battery import BatteryParams

from seaway_vehicle_io.autopilot_health import Health
from seaway_vehicle_io.conversions import (
    BatteryReading,
    FieldError,
    GpsQuality,
    attitude_from_attitude,
    battery_from_battery_status,
    battery_from_sys_status,
    battery_state,
    gnss_from_global_position_int,
    gps_quality_from_gps_raw_int,
    local_position_from_local_position_ned,
)
from seaway_vehicle_io.core_outputs import Now, Output, Publish
from seaway_vehicle_io.failsafe_cause import FailsafeCause
from seaway_vehicle_io.timesync import BootTimeOffset

if TYPE_CHECKING:
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.events_channel import EventsChannel

log = logging.getLogger("seaway.vehicle_io")


class TelemetryIn:
    """The telemetry part of ``VehicleIoCore``: owns the time offset, the GNSS quality last heard
    and the battery (its reading, and the battery failsafe the autopilot said, latched)."""

    # read (and, on a reboot, reset) from the other parts
    cfg: VehicleIoConfig
    health: Health
    hold: FailsafeCause
    events: EventsChannel

    def _init_telemetry(self, config: VehicleIoConfig, battery: BatteryParams | None) -> None:
        # The vessel file's [battery] completes the autopilot's battery figures (None: it has none,
        # and only the measured figures are published).
        self.battery_params = battery
        self.offset = BootTimeOffset(config.time_offset_window_s,
                                     confirm_s=config.time_confirm_s)
        self.gps_quality: GpsQuality | None = None
        self.gps_quality_mono_ns = 0
        self.battery = BatteryReading()
        self.battery_said: tuple[BatteryLevel, str] | None = None  # its battery text, latched
        self.last_boot_ms: dict[str, int] = {}
        """The ``time_boot_ms`` of the last message of each type published: the same again is a
        duplicated packet (a router loop, two radio paths), not a second measurement."""
        self.duplicates = 0

    def _stamp(self, msg: Any, now: Now) -> int:
        """Stamp for a message with time_boot_ms, validated before it may move the estimate
        (``timesync.BootTimeOffset``: a boot time far ahead is refused, a late one gets its older
        stamp, and only a streak of samples, never one, restarts the estimate)."""
        boot_ms = msg.time_boot_ms
        offset = self.offset
        resets, rebases, steps = offset.resets, offset.rebases, offset.steps
        stamp = offset.stamp(boot_ms, now.wall_ns, now.mono_ns)
        if offset.resets != resets:
            log.warning("autopilot clock restarted (every time_boot_ms over %.1f s behind the "
                        "estimate): time offset estimated anew", self.cfg.time_confirm_s)
            self._rebooted(now)
        elif offset.steps != steps:
            log.warning("the wall clock stepped (every time_boot_ms behind the estimate for %.1f s "
                        "on the wall clock, not on the monotonic one): time offset estimated anew; "
                        "the autopilot did not reboot", self.cfg.time_confirm_s)
        elif offset.rebases != rebases:
            log.warning("time offset was wrong (every time_boot_ms over %.1f s away from it): "
                        "estimated anew from those messages", self.cfg.time_confirm_s)
        if stamp is None:
            raise FieldError(msg.get_type(), "time_boot_ms", boot_ms,
                             f"lies over {offset.window_ns / 1e9:g} s behind the autopilot's clock "
                             "(too late to stamp)" if offset.refused == "late"
                             else "jumps ahead of the autopilot's clock")
        if stamp < 0:
            raise FieldError(msg.get_type(), "time_boot_ms", boot_ms, "gives a negative stamp")
        return stamp

    def _publish_stamped(self, msg: Any, now: Now, convert: Any) -> list[Output]:
        mtype = msg.get_type()
        if self.last_boot_ms.get(mtype) == msg.time_boot_ms:
            self.duplicates += 1  # fused twice, one fix would weigh double in the estimate
            return []
        stamp = self._stamp(msg, now)
        message = convert(stamp)  # raises FieldError before the estimate is touched
        self.offset.commit(msg.time_boot_ms, now.wall_ns, now.mono_ns)
        self.last_boot_ms[mtype] = msg.time_boot_ms
        self.health.booted_ms(msg.time_boot_ms)
        return [Publish(message)]

    def _on_system_time(self, msg: Any, now: Now) -> list[Output]:
        """SYSTEM_TIME: the autopilot's clock now; going back, and running on from there, means it
        rebooted (``BootTimeOffset.system_time``)."""
        if self.offset.system_time(msg.time_boot_ms, now.mono_ns):
            log.warning("autopilot rebooted (SYSTEM_TIME time_boot_ms went back to %d ms): time "
                        "offset estimated anew", msg.time_boot_ms)
            self._rebooted(now)
        return []

    def _rebooted(self, now: Now) -> None:
        """The autopilot rebooted without the link dropping (its clock went back): forget what it
        said before, as a link loss does. A reboot ends what it latched till reboot (ArduPilot's
        battery failsafe), and a failsafe or a mode change before it is no cause of a hold after."""
        self.battery_said = None
        self.last_boot_ms.clear()
        self.health = Health(px4=self.health.px4, since_mono_ns=now.mono_ns)
        self.events.restart_count()
        if self.hold.cause is not None:
            log.info("the autopilot's hold reason (%s) ends with its reboot", self.hold.cause)
        self.hold = FailsafeCause()

    def _on_global_position_int(self, msg: Any, now: Now) -> list[Output]:
        fresh = (self.gps_quality is not None and now.mono_ns - self.gps_quality_mono_ns
                 <= round(self.cfg.gps_raw_max_age_s * 1e9))
        quality = self.gps_quality if fresh else None
        return self._publish_stamped(msg, now, lambda stamp: gnss_from_global_position_int(
            msg, stamp, quality, self.cfg.fix_type_without_gps_raw))

    def _on_attitude(self, msg: Any, now: Now) -> list[Output]:
        return self._publish_stamped(msg, now, lambda stamp: attitude_from_attitude(msg, stamp))

    def _on_local_position_ned(self, msg: Any, now: Now) -> list[Output]:
        return self._publish_stamped(
            msg, now, lambda stamp: local_position_from_local_position_ned(msg, stamp))

    def _on_gps_raw_int(self, msg: Any, now: Now) -> list[Output]:
        self.gps_quality = gps_quality_from_gps_raw_int(msg)
        self.gps_quality_mono_ns = now.mono_ns
        return []

    def _on_sys_status(self, msg: Any, now: Now) -> list[Output]:
        reading = battery_from_sys_status(msg)  # refuses an absurd message before it is used
        self._hold_changed(self.hold.health(msg.onboard_control_sensors_present,
                                            msg.onboard_control_sensors_enabled,
                                            msg.onboard_control_sensors_health, now.mono_ns),
                           now)
        self.health.sys_status(msg.onboard_control_sensors_present,
                               msg.onboard_control_sensors_enabled,
                               msg.onboard_control_sensors_health)
        return self._on_battery(reading, now)

    def _on_estimator_report(self, msg: Any, now: Now) -> list[Output]:
        """EKF_STATUS_REPORT (ArduPilot) or ESTIMATOR_STATUS (PX4): is it using GNSS."""
        self.health.estimator_flags(msg.get_type(), int(msg.flags))
        return []

    def _on_battery_status(self, msg: Any, now: Now) -> list[Output]:
        if msg.id != 0:
            return []  # the first battery is the one SYS_STATUS also describes
        return self._on_battery(battery_from_battery_status(msg), now)

    def _on_battery(self, reading: BatteryReading, now: Now) -> list[Output]:
        """A battery message converted (refused before this if a field is absurd): the pack's
        state, completed from the vessel file, on ``vehicle/battery`` at once. Stamped at receipt
        (wall clock), as VehicleStatus: neither message carries the autopilot's time."""
        self.battery = self.battery.merged(reading)
        return [Publish(battery_state(self.battery, self.battery_params, now.wall_ns,
                                      self.battery_said))]
