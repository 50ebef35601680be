"""What the simulated PX4 autopilot sends: HEARTBEAT, SYS_STATUS, BATTERY_STATUS, SYSTEM_TIME,
AUTOPILOT_VERSION, STATUSTEXT and the sensor streams (GPS_RAW_INT, GLOBAL_POSITION_INT,
LOCAL_POSITION_NED, ATTITUDE), filled as PX4's mavlink streams fill them, and thinned by
SET_MESSAGE_INTERVAL (``StreamIntervals``). ``Px4Telemetry`` is the ``Px4Autopilot``'s outgoing
half: it reads the state machine's state (``px4_autopilot``). Pure: times since boot [ns] in,
pymavlink messages out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink
from seaway.contract.messages import Attitude, GnssFix
from seaway.simkit.sensors import instants_in, period_ns
from seaway.vessel.frames import GeoOrigin

from seaway_sim.battery import PackReading, report_due
from seaway_sim.px4_params import ParamStore
from seaway_sim.px4_wire import MANUAL, boot_ms, custom_mode, lround

# Telemetry rates [Hz] (docs/autopilots.md A.5); sensor-driven streams follow the scenario's rates.
HEARTBEAT_HZ = 1.0
SYS_STATUS_HZ = 1.0
SYSTEM_TIME_HZ = 1.0

# PX4 v1.16.0 release, FIRMWARE_VERSION_TYPE_OFFICIAL (0xFF) in the low byte.
FLIGHT_SW_VERSION = (1 << 24) | (16 << 16) | (0 << 8) | 0xFF
CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE)

SENSORS_PRESENT = (mavlink.MAV_SYS_STATUS_SENSOR_GPS | mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
                   | mavlink.MAV_SYS_STATUS_AHRS | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
                   | mavlink.MAV_SYS_STATUS_PREARM_CHECK)

UINT16_UNKNOWN = 65535  # MAVLink's "not set" for unsigned 16-bit fields
INT16_MAX = 32767
GPS_EPH_CDOP = 100  # GPS_RAW_INT.eph: HDOP x 100; a simulated open-sky receiver reports 1.0


@dataclass(frozen=True)
class BatteryFields:
    """The pack in MAVLink's units, filled as PX4's mavlink streams fill SYS_STATUS and
    BATTERY_STATUS (src/modules/mavlink/streams/SYS_STATUS.hpp, BATTERY_STATUS.hpp): the float
    figures converted to integers by C's truncation, the remaining percentage rounded up (ceilf)."""

    voltage_mv: int  # SYS_STATUS.voltage_battery, BATTERY_STATUS.voltages[0]
    current_ca: int  # current_battery [cA]
    consumed_mah: int  # BATTERY_STATUS.current_consumed [mA h]
    consumed_hj: int  # BATTERY_STATUS.energy_consumed [hJ]; PX4 sends -1 (see battery_fields)
    remaining_pct: int  # battery_remaining [%]


def battery_fields(pack: PackReading) -> BatteryFields:
    """``pack`` as PX4 puts it on the wire.

    **Differs** from PX4 in one field: PX4 sends ``energy_consumed`` = -1 (its battery_status has no
    energy count); the sim fills it with the energy drawn, so that vehicle_io's energy path (as
    ArduPilot fills it) is exercised too. Each is at most one unit below the true value (the
    truncation): 1 mV, 10 mA, 1 mA h, 100 J; the percentage at most 1 above.
    """
    return BatteryFields(
        voltage_mv=min(UINT16_UNKNOWN - 1, int(pack.voltage_v * 1000.0)),
        current_ca=max(-INT16_MAX, min(INT16_MAX, int(pack.current_a * 100.0))),
        consumed_mah=int(pack.consumed_mah),
        consumed_hj=int(pack.consumed_j / 100.0),
        remaining_pct=math.ceil(pack.remaining_frac * 100.0))


STREAM_SLACK = 0.1  # a sample up to 10 % of the interval early still goes (no beating)


class StreamIntervals:
    """MAV_CMD_SET_MESSAGE_INTERVAL (511) as PX4 takes it, for the messages the sim streams:
    param1 = message id, param2 = interval [us] (-1: stop it, 0: back to the default). A stream is
    thinned to the interval, never sent faster than the sim produces it (its sensor rates). PX4
    answered ACCEPTED for each telemetry message and FAILED for HEARTBEAT (1.18 SITL); a message
    the sim does not stream is FAILED here too. Pure: times are since boot [ns]."""

    STREAMED = frozenset({
        mavlink.MAVLINK_MSG_ID_ATTITUDE, mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
        mavlink.MAVLINK_MSG_ID_SYS_STATUS, mavlink.MAVLINK_MSG_ID_BATTERY_STATUS})

    def __init__(self) -> None:
        self.interval_ns: dict[int, int] = {}  # message id -> interval (-1: off)
        self._last_ns: dict[int, int] = {}

    def set(self, param1: float, param2: float) -> int:
        msg_id = lround(param1)
        if msg_id not in self.STREAMED or not (param2 == -1 or param2 >= 0):
            return mavlink.MAV_RESULT_FAILED
        if param2 == 0:
            self.interval_ns.pop(msg_id, None)
        else:
            self.interval_ns[msg_id] = -1 if param2 == -1 else round(param2 * 1000)
        self._last_ns.pop(msg_id, None)
        return mavlink.MAV_RESULT_ACCEPTED

    def keep(self, msg_id: int, t_ns: int) -> bool:
        """Whether a sample of ``msg_id`` at ``t_ns`` goes out (and, if so, it is counted sent)."""
        interval = self.interval_ns.get(msg_id)
        if interval is None:
            return True
        if interval < 0:
            return False
        last = self._last_ns.get(msg_id)
        if last is not None and t_ns - last < interval * (1.0 - STREAM_SLACK):
            return False
        self._last_ns[msg_id] = t_ns
        return True


class Px4Telemetry:
    """The outgoing messages of ``Px4Autopilot`` (its base): built from its state, which the
    state machine keeps."""

    # the state machine's, read here
    params: ParamStore
    armed: bool
    terminated: bool
    user_mode: tuple[int, int]
    failsafe_since_ns: int | None
    streams: StreamIntervals
    last_fix: GnssFix | None
    _last_heading: float | None
    _texts: list[tuple[int, str]]

    def nav_mode(self) -> tuple[int, int]:
        """The mode flown now, failsafe included (the state machine's)."""
        raise NotImplementedError

    def manual_control_lost(self, now_ns: int) -> bool:
        """Whether manual control is lost at ``now_ns`` [ns since boot] (the state machine's)."""
        raise NotImplementedError

    def heartbeat(self) -> Any:
        mode = self.nav_mode()
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if self.armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        if mode == MANUAL:
            base |= mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        else:
            base |= (mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
                     | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED)
        if self.terminated:
            status = mavlink.MAV_STATE_FLIGHT_TERMINATION
        elif self.failsafe_since_ns is not None:
            status = mavlink.MAV_STATE_CRITICAL
        elif self.armed:
            status = mavlink.MAV_STATE_ACTIVE
        else:
            status = mavlink.MAV_STATE_STANDBY
        return mavlink.MAVLink_heartbeat_message(int(self.params.get("MAV_TYPE")),
                                                 mavlink.MAV_AUTOPILOT_PX4, base, custom_mode(mode),
                                                 status, 3)

    def sys_status(self, now_ns: int, pack: PackReading, gnss_ok: bool, link_errors: int) -> Any:
        """SYS_STATUS: RC_RECEIVER health is manual control, GPS health the fix, errors_comm the
        count of garbage the link dropped; the battery is ``pack`` (``battery_fields``)."""
        health = SENSORS_PRESENT
        if self.manual_control_lost(now_ns):
            health &= ~mavlink.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
        if not gnss_ok:
            health &= ~mavlink.MAV_SYS_STATUS_SENSOR_GPS
        if self.terminated or (self.user_mode == MANUAL and self.manual_control_lost(now_ns)):
            health &= ~mavlink.MAV_SYS_STATUS_PREARM_CHECK
        b = battery_fields(pack)
        return mavlink.MAVLink_sys_status_message(
            SENSORS_PRESENT, SENSORS_PRESENT, health, 0, b.voltage_mv, b.current_ca,
            b.remaining_pct, 0, min(65535, link_errors), 0, 0, 0, 0)

    def battery_status(self, pack: PackReading) -> Any:
        """BATTERY_STATUS id 0 of ``pack``: the total voltage in voltages[0] and the other cells
        UINT16_MAX, as PX4 without cell voltages; temperature unknown (INT16_MAX)."""
        b = battery_fields(pack)
        voltages = [b.voltage_mv] + [UINT16_UNKNOWN] * 9
        return mavlink.MAVLink_battery_status_message(
            0, mavlink.MAV_BATTERY_FUNCTION_ALL, mavlink.MAV_BATTERY_TYPE_LIPO, INT16_MAX, voltages,
            b.current_ca, b.consumed_mah, b.consumed_hj, b.remaining_pct)

    def autopilot_version(self) -> Any:
        return mavlink.MAVLink_autopilot_version_message(
            CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0, bytes(8), bytes(8), bytes(8), 0, 0, 0)

    def sensor_telemetry(self, fixes: Sequence[GnssFix | None], attitudes: Sequence[Attitude],
                         epoch_ns: int, origin: GeoOrigin | None = None) -> list[Any]:
        """GPS_RAW_INT, GLOBAL_POSITION_INT and (with ``origin``) LOCAL_POSITION_NED per fix,
        ATTITUDE per attitude sample (time order kept per kind). GPS_RAW_INT carries what only the
        receiver knows (fix type, accuracy, satellites): a companion needs it to trust a fix, and
        PX4 streams it by default.

        Stamps of the samples are ``epoch_ns + time since boot``. Each message goes out once, when
        its value is made, stamped with that time, as PX4's streams send an estimator output once
        (``time_boot_ms`` = its publication time, about the time it is sent: measured on the 1.18
        SITL, within the spread of SYSTEM_TIME). An old value is never repeated with its old
        stamp: during a GNSS dropout no position goes out at all.
        """
        out: list[Any] = []
        heading = self._last_heading
        keep = self.streams.keep
        for att in attitudes:
            heading = att.yaw_rad
            if keep(mavlink.MAVLINK_MSG_ID_ATTITUDE, att.stamp_ns - epoch_ns):
                out.append(mavlink.MAVLink_attitude_message(
                    boot_ms(att.stamp_ns - epoch_ns), att.roll_rad, att.pitch_rad, att.yaw_rad,
                    att.roll_rate_radps, att.pitch_rate_radps, att.yaw_rate_radps))
        self._last_heading = heading
        for fix in fixes:
            if fix is None:
                continue
            self.last_fix = fix
            hdg = round(math.degrees(heading) * 100) % 36000 if heading is not None else 65535
            vel_n, vel_e = fix.vel_n_mps or 0.0, fix.vel_e_mps or 0.0
            h_acc_mm = round((fix.horizontal_std_m or 0.0) * 1000)
            t_ns = fix.stamp_ns - epoch_ns
            if keep(mavlink.MAVLINK_MSG_ID_GPS_RAW_INT, t_ns):
                out.append(mavlink.MAVLink_gps_raw_int_message(
                    t_ns // 1000, fix.fix_type, round(math.degrees(fix.lat_rad) * 1e7),
                    round(math.degrees(fix.lon_rad) * 1e7), round(fix.alt_m * 1000), GPS_EPH_CDOP,
                    UINT16_UNKNOWN, round(math.hypot(vel_n, vel_e) * 100),
                    round(math.degrees(math.atan2(vel_e, vel_n)) * 100) % 36000,
                    fix.satellites if fix.satellites is not None else 255,
                    h_acc=h_acc_mm))
            if keep(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, t_ns):
                out.append(mavlink.MAVLink_global_position_int_message(
                    boot_ms(t_ns), round(math.degrees(fix.lat_rad) * 1e7),
                    round(math.degrees(fix.lon_rad) * 1e7), round(fix.alt_m * 1000), 0,
                    round((fix.vel_n_mps or 0.0) * 100), round((fix.vel_e_mps or 0.0) * 100), 0,
                    hdg))
            if origin is not None and keep(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, t_ns):
                # PX4's local origin is the sim's origin; its estimate here is the fix.
                north, east, _ = origin.to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m)
                out.append(mavlink.MAVLink_local_position_ned_message(
                    boot_ms(t_ns), north, east, 0.0,  # z: on the surface
                    fix.vel_n_mps or 0.0, fix.vel_e_mps or 0.0, 0.0))
        return out

    def periodic_telemetry(self, after_ns: int, upto_ns: int, epoch_ns: int,
                           pack: PackReading, gnss_ok: bool, link_errors: int) -> list[Any]:
        """HEARTBEAT, SYSTEM_TIME, SYS_STATUS, BATTERY_STATUS (1 Hz) due in (after, upto]; the
        battery messages describe ``pack`` (the battery at ``upto_ns``).

        Times are since boot. SYSTEM_TIME carries the wall clock (``epoch_ns`` + time since boot)
        and the boot time at ``upto_ns``, as PX4 streams it on its onboard link (1 Hz measured);
        a companion tells a reboot from it (its boot time goes back).
        """
        out: list[Any] = [mavlink.MAVLink_statustext_message(severity, text.encode()[:50])
                          for severity, text in self._texts]
        self._texts.clear()
        if instants_in(period_ns(HEARTBEAT_HZ), after_ns, upto_ns):
            out.append(self.heartbeat())
        keep = self.streams.keep
        if (instants_in(period_ns(SYS_STATUS_HZ), after_ns, upto_ns)
                and keep(mavlink.MAVLINK_MSG_ID_SYS_STATUS, upto_ns)):
            out.append(self.sys_status(upto_ns, pack, gnss_ok, link_errors))
        if report_due(after_ns, upto_ns) and keep(mavlink.MAVLINK_MSG_ID_BATTERY_STATUS, upto_ns):
            out.append(self.battery_status(pack))
        if instants_in(period_ns(SYSTEM_TIME_HZ), after_ns, upto_ns):
            out.append(mavlink.MAVLink_system_time_message((epoch_ns + upto_ns) // 1000,
                                                          boot_ms(upto_ns)))
        return out
