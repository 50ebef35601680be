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
* SET_MESSAGE_INTERVAL thins the telemetry streams (``px4_telemetry.StreamIntervals``).
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
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink
from seaway.contract.messages import GnssFix
from seaway.contract.units import NS_PER_S
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel.frames import GeoOrigin

from seaway_sim import px4_mixer
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
from seaway_sim.px4_telemetry import Px4Telemetry, StreamIntervals
from seaway_sim.px4_wire import (
    BOOT_MODE,
    HOLD,
    LAND,
    MAIN_MANUAL,
    MANUAL,
    MODE_NAMES,
    RTL,
    lround,
)

log = logging.getLogger("seaway_sim.px4")

# GF_ACTION values (geofence_result_s).
GF_NONE, GF_WARN, GF_HOLD, GF_RETURN, GF_TERMINATE, GF_LAND = 0, 1, 2, 3, 4, 5
# NAV_RCL_ACT values (PX4 v1.14+).
RCL_HOLD, RCL_RETURN, RCL_LAND, RCL_TERMINATE, RCL_DISARM = 1, 2, 3, 5, 6
# COM_RC_IN_MODE values under which a MAVLink MANUAL_CONTROL stream is not an input.
RC_IN_MODE_RC_ONLY, RC_IN_MODE_DISABLED = 0, 4
COM_RCL_EXCEPT_HOLD_BIT = 1 << 1
FORCE_MAGIC = 21196  # MAV_CMD_COMPONENT_ARM_DISARM param2 that forces (disarm only, from MAVLink)

COMPID = mavlink.MAV_COMP_ID_AUTOPILOT1
SEVERITY_CRITICAL = mavlink.MAV_SEVERITY_CRITICAL
SEVERITY_INFO = mavlink.MAV_SEVERITY_INFO


@dataclass(frozen=True)
class Px4Config:
    """What the simulated autopilot is told at start."""

    thrust_max_n: float  # scale of normalised thrust [N] (vessel file)
    sysid: int = 1
    compid: int = COMPID
    param_overrides: tuple[tuple[str, float | int], ...] = ()


def _finite(*values: float) -> bool:
    return all(math.isfinite(v) for v in values)


MAV_CMD_SET_MESSAGE_INTERVAL = 511


class Px4Autopilot(Px4Telemetry):
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
