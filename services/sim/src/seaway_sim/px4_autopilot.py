"""A simulated PX4 autopilot (differential rover/boat) as vehicle_io sees it: the pure core.

Decoded MAVLink messages and the time in, MAVLink messages to send and thrusts out; no socket, no
clock. Time ``now_ns`` is nanoseconds since the simulated autopilot booted (the sim epoch), which is
also what ``time_boot_ms`` reports. What it mimics, and where it differs from PX4, is tabled in
services/sim/README.md; the sources are docs/autopilots.md, sections A.1-A.5.

State machine (held against the real PX4 1.18 SITL, SIH rover 10046, by
tests/system/sim/test_px4_imitation.py, which prints the two side by side):

* modes (user intent): MANUAL (PX4 custom main mode 1) and HOLD (AUTO.LOITER, main 4 sub 3). Other
  PX4 modes are refused with TEMPORARILY_REJECTED (**differs**: PX4's rover accepts POSCTL, ACRO,
  STABILIZED, OFFBOARD, MISSION and RTL; the imitation cannot fly them); an unknown main mode is
  TEMPORARILY_REJECTED as in PX4. It boots disarmed in HOLD, as PX4 does.
* SET_MESSAGE_INTERVAL thins the telemetry streams (``StreamIntervals``).
* manual control is *lost* when no accepted MANUAL_CONTROL arrived within COM_RC_LOSS_T (PX4 default
  0.5 s), or none ever did. While it is lost, arming in MANUAL is refused (TEMPORARILY_REJECTED) and
  so is a switch to MANUAL while armed; disarmed, the switch is taken, and arming in HOLD is
  accepted, as in PX4.
* failsafe: armed, manual control lost, and not armed-while-lost (PX4's
  ``_manual_control_lost_at_arming``) -> Hold (zero thrust) for COM_FAIL_ACT_T, then NAV_RCL_ACT:
  1 Hold, 2 Return, 3 Land (all zero thrust: the sim does not navigate), 5 Terminate (outputs off
  until restart), 6 Disarm. A Return that begins within NAV_ACC_RAD of home (the fix at arming)
  has arrived: "Landing detected", and COM_DISARM_LAND later "Disarmed by landing", after which the
  user's mode shows again (PX4's sequence, measured); one farther away stays in Return, armed.
  Each step is announced in a STATUSTEXT worded as PX4's. Regaining manual control ends a
  Hold/Return/Land failsafe (the user takes over again).
* thrust: disarmed, terminated, in failsafe or not in MANUAL -> (0, 0); else the last accepted
  MANUAL_CONTROL through ``px4_mixer`` (held until the loss timeout, as PX4's rover module does).

Measured against the SITL (same request sequence, loopback UDP): every COMMAND_ACK result equal
except the modes above; parameters equal except those the SITL's start-up scripts tune
(COM_RC_IN_MODE, RO_*); the failsafe Hold 0.50 s after the last MANUAL_CONTROL here, 0.69 s in PX4;
Return 5 s and the disarm 2 s later on both.
"""

from __future__ import annotations

import logging
import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink
from seaway.contract.messages import Attitude, GnssFix
from seaway.contract.units import NS_PER_S
from seaway.runtime.ratelog import RateLimitedLog
from seaway.simkit.sensors import instants_in, period_ns
from seaway.vessel.frames import GeoOrigin

from seaway_sim import px4_mixer
from seaway_sim.battery import PackReading, report_due
from seaway_sim.px4_geofence import Px4Geofence
from seaway_sim.px4_params import (
    BY_NAME,
    INDEX,
    MAV_PARAM_TYPE_REAL32,
    PARAMS,
    ParamSpec,
    ParamStore,
    decode_value,
    encode_value,
    param_id_text,
)

log = logging.getLogger("seaway_sim.px4")

NS_PER_MS = 1_000_000

# PX4 custom modes (px4_custom_mode.h): main mode in bits 16-23, sub mode in bits 24-31.
MAIN_MANUAL = 1
MAIN_AUTO = 4
SUB_AUTO_LOITER = 3
SUB_AUTO_RTL = 5
SUB_AUTO_LAND = 6
MANUAL = (MAIN_MANUAL, 0)
HOLD = (MAIN_AUTO, SUB_AUTO_LOITER)
RTL = (MAIN_AUTO, SUB_AUTO_RTL)
LAND = (MAIN_AUTO, SUB_AUTO_LAND)
MODE_NAMES = {MANUAL: "MANUAL", HOLD: "HOLD", RTL: "RTL", LAND: "LAND"}
# PX4 boots in Hold (AUTO.LOITER; measured on the 1.18 SITL, tests/system/sim/test_px4_imitation.py),
# so an operator (the launcher's profiles: mode_on_start) asks for MANUAL before arming.
BOOT_MODE = HOLD

# GF_ACTION values (geofence_result_s).
GF_NONE, GF_WARN, GF_HOLD, GF_RETURN, GF_TERMINATE, GF_LAND = 0, 1, 2, 3, 4, 5
# NAV_RCL_ACT values (PX4 v1.14+).
RCL_HOLD, RCL_RETURN, RCL_LAND, RCL_TERMINATE, RCL_DISARM = 1, 2, 3, 5, 6
# COM_RC_IN_MODE values under which a MAVLink MANUAL_CONTROL stream is not an input.
RC_IN_MODE_RC_ONLY, RC_IN_MODE_DISABLED = 0, 4
COM_RCL_EXCEPT_HOLD_BIT = 1 << 1
FORCE_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2 that forces (disarm only, from MAVLink)

# Telemetry rates [Hz] (docs/autopilots.md A.5); sensor-driven streams follow the scenario's rates.
HEARTBEAT_HZ = 1.0
SYS_STATUS_HZ = 1.0
SYSTEM_TIME_HZ = 1.0

# PX4 v1.16.0 release, FIRMWARE_VERSION_TYPE_OFFICIAL (0xFF) in the low byte.
FLIGHT_SW_VERSION = (1 << 24) | (16 << 16) | (0 << 8) | 0xFF
CAPABILITIES = (mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mavlink.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE)

COMPID = mavlink.MAV_COMP_ID_AUTOPILOT1
SEVERITY_CRITICAL = mavlink.MAV_SEVERITY_CRITICAL
SEVERITY_INFO = mavlink.MAV_SEVERITY_INFO
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


@dataclass(frozen=True)
class Px4Config:
    """What the simulated autopilot is told at start."""

    thrust_max_n: float  # scale of normalised thrust [N] (vessel file)
    sysid: int = 1
    compid: int = COMPID
    param_overrides: tuple[tuple[str, float | int], ...] = ()


def custom_mode(mode: tuple[int, int]) -> int:
    """HEARTBEAT.custom_mode of a PX4 (main, sub) mode."""
    return (mode[0] << 16) | (mode[1] << 24)


def lround(value: float) -> int:
    """C's lroundf, as PX4 rounds command params: halves away from zero (Python rounds to even)."""
    return int(math.copysign(math.floor(abs(value) + 0.5), value))


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


MAV_CMD_SET_MESSAGE_INTERVAL = 511
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


class Px4Autopilot:
    """The simulated autopilot's state machine (see the module docstring)."""

    def __init__(self, config: Px4Config) -> None:
        self.config = config
        self.params = ParamStore(dict(config.param_overrides))
        self.thrust_max_n = config.thrust_max_n
        self.armed = False
        self.terminated = False
        self.user_mode = BOOT_MODE
        self.failsafe_since_ns: int | None = None
        self.failsafe_action: int | None = None  # NAV_RCL_ACT once the Hold delay is over
        self.landed_since_ns: int | None = None  # a Return that ended at home: when it "landed"
        self.home: tuple[float, float] | None = None  # (lat, lon) [rad] of the fix at arming
        self._texts: list[tuple[int, str]] = []  # STATUSTEXT (severity, text) not yet sent
        self.manual_lost_at_arming = False
        self.last_manual_ns: int | None = None
        self.last_manual_axes = (0, px4_mixer.Z_STOP)  # (y, z)
        self.counters: Counter[str] = Counter()
        self.last_fix: GnssFix | None = None  # for LOCAL_POSITION_NED
        self._last_heading: float | None = None  # for GLOBAL_POSITION_INT.hdg
        self._warnings = RateLimitedLog(log, every_s=1.0)  # streams repeat: once a second per kind
        self.streams = StreamIntervals()
        self.geofence = Px4Geofence(config.sysid, COMPID)
        self.fence_action: int | None = None  # GF_ACTION taken on a breach, until a mode change
        self._fence_loaded = 0  # the geofence's load count last built into zones
        self._was_inside = True
        self._handlers = {
            "MANUAL_CONTROL": self._on_manual_control,
            "COMMAND_LONG": self._on_command_long,
            "PARAM_REQUEST_READ": self._on_param_request_read,
            "PARAM_REQUEST_LIST": self._on_param_request_list,
            "PARAM_SET": self._on_param_set,
            **dict.fromkeys(("MISSION_COUNT", "MISSION_ITEM_INT", "MISSION_REQUEST_LIST",
                             "MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"),
                            self._on_mission),
        }

    # -- derived state -----------------------------------------------------------------------

    @property
    def rc_loss_timeout_ns(self) -> int:
        return round(float(self.params.get("COM_RC_LOSS_T")) * NS_PER_S)

    def manual_control_lost(self, now_ns: int) -> bool:
        return self.last_manual_ns is None or now_ns - self.last_manual_ns > self.rc_loss_timeout_ns

    def in_failsafe(self) -> bool:
        return self.failsafe_since_ns is not None

    def nav_mode(self) -> tuple[int, int]:
        """The mode PX4 would report: the failsafe's while one is active, else the user's."""
        if self.fence_action is not None:
            return {GF_RETURN: RTL, GF_LAND: LAND}.get(self.fence_action, HOLD)
        if self.failsafe_since_ns is None:
            return self.user_mode
        return {RCL_RETURN: RTL, RCL_LAND: LAND}.get(self.failsafe_action or RCL_HOLD, HOLD)

    def mode_name(self) -> str:
        return MODE_NAMES.get(self.nav_mode(), "UNKNOWN")

    # -- time ---------------------------------------------------------------------------------

    def update(self, now_ns: int) -> None:
        """Advance the failsafe state machine to ``now_ns`` (call before reading thrust)."""
        self._check_geofence()
        lost = self.manual_control_lost(now_ns)
        if not lost:
            self.manual_lost_at_arming = False
        if self.failsafe_since_ns is not None:
            if not lost and self.failsafe_action not in (RCL_TERMINATE, RCL_DISARM):
                log.info("manual control regained: failsafe cleared, back in %s",
                         MODE_NAMES[self.user_mode])
                self._clear_failsafe()
                return
            self._run_failsafe_action(now_ns)
            return
        exempt = (int(self.params.get("COM_RC_IN_MODE")) == RC_IN_MODE_DISABLED
                  or (self.user_mode == HOLD
                      and int(self.params.get("COM_RCL_EXCEPT")) & COM_RCL_EXCEPT_HOLD_BIT))
        if self.armed and lost and not self.manual_lost_at_arming and not exempt:
            # The failsafe began when the timeout ran out, however late this call notices it.
            self.failsafe_since_ns = (now_ns if self.last_manual_ns is None
                                      else min(now_ns, self.last_manual_ns + self.rc_loss_timeout_ns))
            self.counters["failsafe_manual_control_lost"] += 1
            self._text(SEVERITY_CRITICAL, "Failsafe activated: entering Hold for "
                       f"{float(self.params.get('COM_FAIL_ACT_T')):g} seconds")
            log.warning("manual control lost (no MANUAL_CONTROL for %.2f s): failsafe Hold, "
                        "NAV_RCL_ACT %d after %.1f s", self.rc_loss_timeout_ns / NS_PER_S,
                        int(self.params.get("NAV_RCL_ACT")),
                        float(self.params.get("COM_FAIL_ACT_T")))

    def _run_failsafe_action(self, now_ns: int) -> None:
        assert self.failsafe_since_ns is not None
        if self.failsafe_action is None:
            delay_ns = round(float(self.params.get("COM_FAIL_ACT_T")) * NS_PER_S)
            if now_ns - self.failsafe_since_ns < delay_ns:
                return
            action = int(self.params.get("NAV_RCL_ACT"))
            self.failsafe_action = action
            self._text(SEVERITY_CRITICAL, "Failsafe activated")
            log.warning("failsafe action NAV_RCL_ACT=%d", action)
            if action == RCL_DISARM:
                self.armed = False
                self._clear_failsafe()
            elif action == RCL_TERMINATE:
                self.terminated = True
                self.armed = False
            elif action == RCL_RETURN and self._at_home():
                # PX4's rover Return from home "lands" at once; the land detector then disarms
                # after COM_DISARM_LAND (measured on the 1.18 SITL: ~2 s after Return).
                self.landed_since_ns = now_ns
                self._text(SEVERITY_INFO, "Landing detected")
        disarm_land_s = float(self.params.get("COM_DISARM_LAND"))
        if (self.landed_since_ns is not None and disarm_land_s > 0
                and now_ns - self.landed_since_ns >= round(disarm_land_s * NS_PER_S)):
            self.armed = False
            self._text(SEVERITY_INFO, "Disarmed by landing")
            log.warning("Return ended at home: disarmed by landing")
            self._clear_failsafe()

    def _check_geofence(self) -> None:
        """The geofence (``px4_geofence``): a new fence is loaded into zones; armed, a position
        newly outside it takes ``GF_ACTION`` (PX4's failsafe framework: the action stands until a
        mode change or disarming), with PX4's text."""
        fix = self.last_fix
        position = None if fix is None else (fix.lat_rad, fix.lon_rad)
        action = int(self.params.get("GF_ACTION"))
        if self.geofence.loaded != self._fence_loaded:
            self._fence_loaded = self.geofence.loaded
            self.geofence.load(self.home, position if self.armed and action != GF_NONE else None)
            self._texts += self.geofence.texts
            self.geofence.texts.clear()
        inside = position is None or self.geofence.inside(*position)
        newly_out, self._was_inside = self._was_inside and not inside, inside
        if not (newly_out and self.armed and action != GF_NONE) or self.fence_action is not None:
            return
        self._text(SEVERITY_CRITICAL, "Geofence violation: approaching or outside geofence")
        self.counters["geofence_breach"] += 1
        log.warning("geofence breached: GF_ACTION %d", action)
        if action == GF_TERMINATE:
            self.terminated, self.armed = True, False
        elif action != GF_WARN:
            self.fence_action = action

    def _at_home(self) -> bool:
        """Whether the last fix is within NAV_ACC_RAD of home (the fix at arming). The sim does
        not navigate, so a Return that begins farther away never arrives."""
        if self.home is None or self.last_fix is None:
            return False
        north, east, _ = GeoOrigin(*self.home).to_ned(self.last_fix.lat_rad, self.last_fix.lon_rad)
        return math.hypot(north, east) <= float(self.params.get("NAV_ACC_RAD"))

    def _clear_failsafe(self) -> None:
        self.fence_action = None
        self.failsafe_since_ns = None
        self.failsafe_action = None
        self.landed_since_ns = None

    def _text(self, severity: int, text: str) -> None:
        """Queue a STATUSTEXT, worded as PX4 words it; sent with the next telemetry."""
        self._texts.append((severity, text))

    def thrust_n(self, now_ns: int) -> tuple[float, float]:
        """(T1 port, T2 starboard) [N] the autopilot outputs at ``now_ns``."""
        self.update(now_ns)
        if (not self.armed or self.terminated or self.failsafe_since_ns is not None
                or self.fence_action is not None or self.user_mode != MANUAL
                or self.manual_control_lost(now_ns)):
            return 0.0, 0.0
        y, z = self.last_manual_axes
        return px4_mixer.manual_control_to_thrust_n(y, z, self.thrust_max_n,
                                                    float(self.params.get("RD_YAW_STK_GAIN")))

    # -- incoming -----------------------------------------------------------------------------

    def handle(self, msg: Any, now_ns: int) -> list[Any]:
        """Process one decoded message; returns the messages to send back."""
        kind = msg.get_type()
        self.counters[f"rx_{kind}"] += 1
        handler = self._handlers.get(kind)
        if handler is None:
            return []  # HEARTBEAT and anything else: nothing to do (the link layer noted the peer)
        return handler(msg, now_ns)

    def _for_me(self, target_system: int) -> bool:
        return target_system in (0, self.config.sysid)

    def _reject(self, kind: str, now_ns: int, text: str) -> list[Any]:
        """Count a dropped message, log it (rate-limited) and answer nothing."""
        self._count_and_warn(kind, now_ns, f"dropped: {text}")
        return []

    def _count_and_warn(self, kind: str, now_ns: int, text: str) -> None:
        """Count an event of ``kind``; log it at most once a second per kind (streams repeat)."""
        self.counters[kind] += 1
        self._warnings.warning(kind, "%s (%s so far: %d)", text, kind, self.counters[kind],
                               now_ns=now_ns)

    def _on_manual_control(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target):
            self.counters["ignored_other_target"] += 1
            return []
        axes = {"x": msg.x, "y": msg.y, "z": msg.z, "r": msg.r}
        bad = {k: v for k, v in axes.items() if not -px4_mixer.AXIS_MAX <= v <= px4_mixer.AXIS_MAX}
        if bad:
            # PX4 would zero the axis silently; a sender doing this is a bug we want to see.
            return self._reject("manual_control_out_of_range", now_ns,
                                f"MANUAL_CONTROL with axes outside [-1000, 1000]: {bad}")
        if int(self.params.get("COM_RC_IN_MODE")) in (RC_IN_MODE_RC_ONLY, RC_IN_MODE_DISABLED):
            self.counters["manual_control_ignored_rc_in_mode"] += 1
            return []
        if msg.z < px4_mixer.Z_MIN:
            self._count_and_warn("manual_control_z_negative", now_ns,
                                 f"MANUAL_CONTROL z={msg.z} < 0: PX4 reads throttle 0 (stop), "
                                 "not reverse")
        self.last_manual_ns = now_ns
        self.last_manual_axes = (msg.y, msg.z)
        return []

    def _on_command_long(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target_system):
            self.counters["ignored_other_target"] += 1
            return []
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6,
                  msg.param7)
        if not _finite(*params):
            return self._reject("command_garbage_fields", now_ns,
                                f"COMMAND_LONG {msg.command} with non-finite params {params}")
        if msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            result = self._arm_disarm(msg.param1, msg.param2, now_ns)
        elif msg.command == mavlink.MAV_CMD_DO_SET_MODE:
            result = self._set_mode(msg.param1, msg.param2, msg.param3, now_ns)
        elif msg.command == MAV_CMD_SET_MESSAGE_INTERVAL:
            result = self.streams.set(msg.param1, msg.param2)
        elif self._asks_version(msg):
            return [self._ack(msg, mavlink.MAV_RESULT_ACCEPTED), self.autopilot_version()]
        else:
            self.counters["command_unsupported"] += 1
            log.info("COMMAND_LONG %d not simulated: UNSUPPORTED", msg.command)
            result = mavlink.MAV_RESULT_UNSUPPORTED
        return [self._ack(msg, result)]

    @staticmethod
    def _asks_version(msg: Any) -> bool:
        if msg.command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            return True
        return (msg.command == mavlink.MAV_CMD_REQUEST_MESSAGE
                and lround(msg.param1) == mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _ack(self, msg: Any, result: int) -> Any:
        return mavlink.MAVLink_command_ack_message(msg.command, result, 0, 0, msg.get_srcSystem(),
                                                  msg.get_srcComponent())

    def _arm_disarm(self, param1: float, param2: float, now_ns: int) -> int:
        request = lround(param1)
        if request == 0:
            if self.armed:
                log.info("disarmed%s", " (forced)" if lround(param2) == FORCE_MAGIC else "")
            self.armed = False
            self._clear_failsafe()
            return mavlink.MAV_RESULT_ACCEPTED
        if request != 1:
            log.warning("Unsupported ARM_DISARM param %g", param1)
            return mavlink.MAV_RESULT_DENIED
        if self.armed:
            return mavlink.MAV_RESULT_ACCEPTED
        lost = self.manual_control_lost(now_ns)
        # PX4 runs the preflight checks for every arm request from MAVLink, forced or not.
        if self.terminated:
            log.warning("arming refused: flight termination active (reboot the sim)")
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        if self.user_mode == MANUAL and lost:
            log.warning("arming refused: No manual control input (mode MANUAL)")
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        self.armed = True
        self.manual_lost_at_arming = lost
        fix = self.last_fix
        self.home = None if fix is None else (fix.lat_rad, fix.lon_rad)  # PX4 sets home at arming
        log.info("armed in %s", MODE_NAMES[self.user_mode])
        return mavlink.MAV_RESULT_ACCEPTED

    def _set_mode(self, param1: float, param2: float, param3: float, now_ns: int) -> int:
        if not lround(param1) & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            log.warning("DO_SET_MODE without CUSTOM_MODE_ENABLED is not simulated")
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        # PX4 casts the mode params to uint8_t (truncation, not rounding).
        mode = (int(param2), int(param3))
        if mode[0] == MAIN_MANUAL:
            mode = MANUAL  # PX4 ignores the sub mode of MANUAL
        if mode not in (MANUAL, HOLD):
            log.warning("mode %s (main %d, sub %d) is not simulated: refused", mode, *mode)
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        if (mode == MANUAL and self.user_mode != MANUAL and self.armed
                and self.manual_control_lost(now_ns)):
            # Disarmed, PX4 takes the mode and refuses the arming instead (measured).
            log.warning("switch to MANUAL refused while armed: No manual control input")
            return mavlink.MAV_RESULT_TEMPORARILY_REJECTED
        if mode != self.user_mode:
            log.info("mode %s -> %s", MODE_NAMES[self.user_mode], MODE_NAMES[mode])
        self.user_mode = mode
        self.fence_action = None  # a mode change takes the vessel back from the geofence action
        return mavlink.MAV_RESULT_ACCEPTED

    def _param_value(self, spec: ParamSpec) -> Any:
        return mavlink.MAVLink_param_value_message(
            spec.name.encode("ascii"), encode_value(spec, self.params.get(spec.name)),
            spec.param_type, len(PARAMS), INDEX[spec.name])

    def _on_param_request_read(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target_system):
            return []
        if msg.param_index >= 0:
            if msg.param_index >= len(PARAMS):
                return self._reject("param_unknown", now_ns, f"param index {msg.param_index}")
            return [self._param_value(PARAMS[msg.param_index])]
        name = param_id_text(msg.param_id)
        spec = BY_NAME.get(name)
        if spec is None:
            return self._reject("param_unknown", now_ns, f"unknown parameter {name!r}")
        return [self._param_value(spec)]

    def _on_param_request_list(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target_system):
            return []
        return [self._param_value(spec) for spec in PARAMS]

    def _on_param_set(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target_system):
            return []
        name = param_id_text(msg.param_id)
        if msg.param_type == MAV_PARAM_TYPE_REAL32 and not math.isfinite(msg.param_value):
            return self._reject("param_garbage_fields", now_ns,
                                f"PARAM_SET {name!r} with non-finite value {msg.param_value}")
        value = decode_value(msg.param_type, msg.param_value)
        error = self.params.set(name, msg.param_type, value)
        if error:
            return self._reject("param_set_refused", now_ns, f"PARAM_SET refused: {error}")
        log.info("parameter %s = %s", name, value)
        return [self._param_value(BY_NAME[name])]

    def _on_mission(self, msg: Any, now_ns: int) -> list[Any]:
        if not self._for_me(msg.target_system):
            self.counters["ignored_other_target"] += 1
            return []
        out = self.geofence.handle(msg)
        self._texts += self.geofence.texts
        self.geofence.texts.clear()
        return out

    # -- outgoing -----------------------------------------------------------------------------

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
                    _boot_ms(att.stamp_ns - epoch_ns), att.roll_rad, att.pitch_rad, att.yaw_rad,
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
                    _boot_ms(t_ns), round(math.degrees(fix.lat_rad) * 1e7),
                    round(math.degrees(fix.lon_rad) * 1e7), round(fix.alt_m * 1000), 0,
                    round((fix.vel_n_mps or 0.0) * 100), round((fix.vel_e_mps or 0.0) * 100), 0,
                    hdg))
            if origin is not None and keep(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, t_ns):
                # PX4's local origin is the sim's origin; its estimate here is the fix.
                north, east, _ = origin.to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m)
                out.append(mavlink.MAVLink_local_position_ned_message(
                    _boot_ms(t_ns), north, east, 0.0,  # z: on the surface
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
                                                          _boot_ms(upto_ns)))
        return out


def _boot_ms(since_boot_ns: int) -> int:
    """MAVLink time_boot_ms (uint32, wraps after 49.7 days) from time since boot [ns]."""
    return (since_boot_ns // NS_PER_MS) & 0xFFFFFFFF
