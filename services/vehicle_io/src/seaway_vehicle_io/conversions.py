"""MAVLink telemetry -> Seaway messages: unit conversions and range checks, as pure functions.

MAVLink's scaled integers stop here (design.md): degrees*1e7 become radians, millimetres metres,
centimetres per second metres per second, millivolts volts, centiamperes amperes, hectojoules
joules, percent a fraction. Each function takes a decoded pymavlink message (only its attributes
are read, so tests may pass any object with those attributes) and the stamp the caller computed,
and either returns a validated Seaway message or raises:

* ``FieldError`` when a field is non-finite or outside the physically possible range; the caller
  counts the message as dropped and logs ``err.field``. Nothing partial is ever published.
* ``NoDataError`` when the message is well-formed but says "nothing known yet" (ArduPilot sends
  GLOBAL_POSITION_INT with lat = lon = 0 before it has a position); not an error, not published.

Limits are deliberately generous: they reject garbage (a corrupted or mis-scaled field), not
unusual but real values.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from seaway.contract.messages import (
    GNSS_ALT_MAX_M,
    GNSS_ALT_MIN_M,
    Attitude,
    BatteryLevel,
    BatteryState,
    GnssFix,
    LocalPosition,
)
from seaway.vessel.battery import BatteryParams

UINT16_MAX = 65535
DEG_E7_TO_RAD = math.pi / 180.0 / 1e7
MM_TO_M = 1e-3
CM_TO_M = 1e-2
MV_TO_V = 1e-3

# Physical plausibility bounds for a surface vessel (anything outside is corruption, not motion).
SPEED_MAX_MPS = 100.0
ANGLE_TOL_RAD = 1e-3  # float32 rounding puts +-pi a hair outside [-pi, pi]
RATE_MAX_RADPS = 40.0  # beyond a 2000 deg/s gyro's full scale
LOCAL_POS_MAX_M = 1.0e6
VOLTAGE_MAX_V = 1_000.0


class FieldError(ValueError):
    """One field of a MAVLink message is non-finite or out of range; ``field`` names it."""

    def __init__(self, message_type: str, field: str, value: Any, why: str) -> None:
        super().__init__(f"{message_type}.{field}={value!r}: {why}")
        self.message_type = message_type
        self.field = field
        self.value = value


class NoDataError(ValueError):
    """A well-formed message that carries no usable value yet."""


def _finite(mtype: str, field: str, value: Any) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise FieldError(mtype, field, value, "not a number") from None
    if not math.isfinite(v):
        raise FieldError(mtype, field, value, "not finite")
    return v


def _within(mtype: str, field: str, value: Any, lo: float, hi: float) -> float:
    v = _finite(mtype, field, value)
    if not lo <= v <= hi:
        raise FieldError(mtype, field, value, f"outside [{lo:g}, {hi:g}]")
    return v


def wrap_pi(angle_rad: float) -> float:
    """Angle into [-pi, pi] [rad]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return max(-math.pi, min(math.pi, wrapped))


# ---------------------------------------------------------------------------------------------
# Position and velocity
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class GpsQuality:
    """What GPS_RAW_INT adds to a fix: fix type, 1-sigma horizontal accuracy, satellites."""

    fix_type: int
    horizontal_std_m: float | None
    satellites: int | None


def gps_quality_from_gps_raw_int(msg: Any) -> GpsQuality:
    """GPS_RAW_INT (#24) -> fix type (GPS_FIX_TYPE, 0..8), h_acc [mm -> m], satellites.

    ``h_acc`` is a MAVLink 2 extension; 0 means "not provided". ``satellites_visible`` 255 means
    unknown.
    """
    t = "GPS_RAW_INT"
    fix_type = int(_within(t, "fix_type", msg.fix_type, 0, 8))
    h_acc_mm = int(getattr(msg, "h_acc", 0) or 0)
    sats = int(_within(t, "satellites_visible", msg.satellites_visible, 0, 255))
    return GpsQuality(
        fix_type=fix_type,
        horizontal_std_m=h_acc_mm * MM_TO_M if h_acc_mm > 0 else None,
        satellites=None if sats == 255 else sats,
    )


def gnss_from_global_position_int(msg: Any, stamp_ns: int, quality: GpsQuality | None,
                                  fix_type_without_quality: int = 0) -> GnssFix:
    """GLOBAL_POSITION_INT (#33) -> GnssFix.

    lat, lon [degE7 -> rad]; alt (MSL) [mm -> m]; vx north, vy east [cm/s -> m/s]. This is the
    autopilot's fused global position; ``quality`` (from the latest GPS_RAW_INT, if recent) supplies
    the fix type and accuracy, else ``fix_type_without_quality``.
    """
    t = "GLOBAL_POSITION_INT"
    lat = _within(t, "lat", msg.lat, -90e7, 90e7)
    lon = _within(t, "lon", msg.lon, -180e7, 180e7)
    if lat == 0 and lon == 0:
        raise NoDataError(f"{t}: lat = lon = 0, the autopilot has no global position yet")
    alt_m = _within(t, "alt", msg.alt, GNSS_ALT_MIN_M / MM_TO_M, GNSS_ALT_MAX_M / MM_TO_M) * MM_TO_M
    vx = _within(t, "vx", msg.vx, -SPEED_MAX_MPS / CM_TO_M, SPEED_MAX_MPS / CM_TO_M) * CM_TO_M
    vy = _within(t, "vy", msg.vy, -SPEED_MAX_MPS / CM_TO_M, SPEED_MAX_MPS / CM_TO_M) * CM_TO_M
    return GnssFix.make(
        stamp_ns=stamp_ns,
        lat_rad=lat * DEG_E7_TO_RAD,
        lon_rad=lon * DEG_E7_TO_RAD,
        alt_m=alt_m,
        fix_type=quality.fix_type if quality else fix_type_without_quality,
        vel_n_mps=vx,
        vel_e_mps=vy,
        horizontal_std_m=quality.horizontal_std_m if quality else None,
        satellites=quality.satellites if quality else None,
    )


def local_position_from_local_position_ned(msg: Any, stamp_ns: int) -> LocalPosition:
    """LOCAL_POSITION_NED (#32) -> LocalPosition: already SI (m, m/s), NED at the autopilot's origin."""
    t = "LOCAL_POSITION_NED"
    pos = {f: _within(t, f, getattr(msg, f), -LOCAL_POS_MAX_M, LOCAL_POS_MAX_M) for f in "xyz"}
    vel = {f: _within(t, f, getattr(msg, f), -SPEED_MAX_MPS, SPEED_MAX_MPS)
           for f in ("vx", "vy", "vz")}
    return LocalPosition.make(
        stamp_ns=stamp_ns, x_m=pos["x"], y_m=pos["y"], z_m=pos["z"],
        vx_mps=vel["vx"], vy_mps=vel["vy"], vz_mps=vel["vz"],
    )


# ---------------------------------------------------------------------------------------------
# Attitude
# ---------------------------------------------------------------------------------------------


def attitude_from_attitude(msg: Any, stamp_ns: int) -> Attitude:
    """ATTITUDE (#30) -> Attitude: roll, pitch, yaw [rad] (NED/FRD), rates [rad/s].

    Yaw is the heading from north, clockwise; it is wrapped into [-pi, pi] after the range check
    (float32 rounding can put +-pi just outside).
    """
    t = "ATTITUDE"
    lim = math.pi + ANGLE_TOL_RAD
    roll = _within(t, "roll", msg.roll, -lim, lim)
    pitch = _within(t, "pitch", msg.pitch, -lim, lim)
    yaw = _within(t, "yaw", msg.yaw, -lim, lim)
    rates = {f: _within(t, f, getattr(msg, f), -RATE_MAX_RADPS, RATE_MAX_RADPS)
             for f in ("rollspeed", "pitchspeed", "yawspeed")}
    return Attitude.make(
        stamp_ns=stamp_ns,
        roll_rad=wrap_pi(roll),
        pitch_rad=wrap_pi(pitch),
        yaw_rad=wrap_pi(yaw),
        roll_rate_radps=rates["rollspeed"],
        pitch_rate_radps=rates["pitchspeed"],
        yaw_rate_radps=rates["yawspeed"],
    )


# ---------------------------------------------------------------------------------------------
# Battery
# ---------------------------------------------------------------------------------------------
#
# What PX4 and ArduPilot put in the two battery messages (docs/autopilots.md C.9):
#   voltage      SYS_STATUS.voltage_battery [mV], BATTERY_STATUS.voltages[] [mV]; UINT16_MAX unknown
#   current      current_battery [cA], -1 unknown (other negative values: charging)
#   remaining    battery_remaining [%], -1 unknown; PX4 rounds up (ceilf), ArduPilot from its mA h count
#   charge drawn BATTERY_STATUS.current_consumed [mA h], -1 unknown (both fill it)
#   energy drawn BATTERY_STATUS.energy_consumed [hJ], -1 unknown (ArduPilot fills it; PX4 sends -1)


@dataclass(frozen=True)
class BatteryReading:
    """What SYS_STATUS and BATTERY_STATUS say about the pack; None where the autopilot says unknown.

    voltage [V], remaining charge [0..1], current [A] (positive discharging), charge drawn [mA h],
    energy drawn [J], the autopilot's own level (BATTERY_STATUS charge_state)."""

    voltage_v: float | None = None
    remaining_frac: float | None = None
    current_a: float | None = None
    consumed_mah: float | None = None
    consumed_j: float | None = None
    level: BatteryLevel | None = None  # the autopilot's charge_state

    def merged(self, newer: BatteryReading) -> BatteryReading:
        """``newer``'s figures, this one's where ``newer`` says unknown: both messages describe the
        same pack, and a field one of them leaves unknown must not flicker to None."""
        return BatteryReading(*(new if new is not None else old for new, old in zip(
            dataclasses.astuple(newer), dataclasses.astuple(self), strict=True)))


HJ_TO_J = 100.0
CA_TO_A = 1e-2
INT16_MAX = 32767
INT32_MAX = 2_147_483_647


def _remaining(t: str, value: Any) -> float | None:
    pct = _within(t, "battery_remaining", value, -1, 100)
    return None if pct == -1 else pct / 100.0


def _current(t: str, value: Any) -> float | None:
    """current_battery [cA -> A]: -1 unknown; other negative values are charging, allowed."""
    ca = _within(t, "current_battery", value, -INT16_MAX, INT16_MAX)
    return None if ca == -1 else ca * CA_TO_A


def _count(t: str, field: str, value: Any) -> float | None:
    """A consumed count (mA h, hJ): -1 unknown, else >= 0 (the pack cannot have given less than
    nothing since the count started)."""
    v = _within(t, field, value, -1, INT32_MAX)
    if -1 < v < 0:
        raise FieldError(t, field, value, "negative (only -1, unknown, is allowed below 0)")
    return None if v == -1 else v


def battery_from_sys_status(msg: Any) -> BatteryReading:
    """SYS_STATUS (#1): voltage_battery [mV -> V] (UINT16_MAX unknown), current_battery [cA -> A]
    (-1 unknown), battery_remaining [% -> 0..1] (-1 unknown)."""
    t = "SYS_STATUS"
    mv = int(_within(t, "voltage_battery", msg.voltage_battery, 0, UINT16_MAX))
    return BatteryReading(
        voltage_v=None if mv == UINT16_MAX else mv * MV_TO_V,
        remaining_frac=_remaining(t, msg.battery_remaining),
        current_a=_current(t, msg.current_battery),
    )


def battery_from_battery_status(msg: Any) -> BatteryReading:
    """BATTERY_STATUS (#147): pack voltage = sum of the cell entries that are not UINT16_MAX [mV -> V];
    current_battery [cA -> A], current_consumed [mA h], energy_consumed [hJ -> J] (each -1 unknown);
    battery_remaining [% -> 0..1] (-1 unknown).

    The MAVLink definition fills unused cells with UINT16_MAX, puts the whole pack in cell 0 when cells
    are not measured, and splits a pack above 65534 mV over cells 0 and 1; summing the valid entries
    is right in all three cases. ``voltages_ext`` (cells 11-14, MAVLink 2) is 0 (ArduPilot) or
    UINT16_MAX (PX4) for unused.
    """
    t = "BATTERY_STATUS"
    cells = [int(_within(t, f"voltages[{i}]", v, 0, UINT16_MAX)) for i, v in enumerate(msg.voltages)]
    ext = [int(_within(t, f"voltages_ext[{i}]", v, 0, UINT16_MAX))
           for i, v in enumerate(getattr(msg, "voltages_ext", None) or [])]
    valid = [c for c in cells if c != UINT16_MAX] + [c for c in ext if c not in (0, UINT16_MAX)]
    voltage_v = sum(valid) * MV_TO_V if valid else None
    if voltage_v is not None and voltage_v > VOLTAGE_MAX_V:
        raise FieldError(t, "voltages", list(msg.voltages), f"pack voltage {voltage_v:g} V implausible")
    hj = _count(t, "energy_consumed", msg.energy_consumed)
    return BatteryReading(
        voltage_v=voltage_v,
        remaining_frac=_remaining(t, msg.battery_remaining),
        current_a=_current(t, msg.current_battery),
        consumed_mah=_count(t, "current_consumed", msg.current_consumed),
        consumed_j=None if hj is None else hj * HJ_TO_J,
        level=CHARGE_STATES.get(int(getattr(msg, "charge_state", 0) or 0)),
    )


# MAV_BATTERY_CHARGE_STATE (common.xml): every value defined; 0 UNDEFINED (and a value a newer
# dialect may add) is "not said".
CHARGE_STATES: dict[int, BatteryLevel] = {1: "ok", 2: "low", 3: "critical", 4: "emergency",
                                          5: "failed", 6: "unhealthy", 7: "charging"}
_LEVEL_RANK: dict[BatteryLevel, int] = {"ok": 0, "charging": 0, "low": 1, "critical": 2,
                                        "emergency": 3, "unhealthy": 3, "failed": 4}


def worse_level(a: BatteryLevel | None, b: BatteryLevel | None) -> BatteryLevel | None:
    """The more serious of two levels (None: not said)."""
    if a is None or b is None:
        return a if b is None else b
    return a if _LEVEL_RANK[a] >= _LEVEL_RANK[b] else b


def battery_level_from_text(text: str) -> BatteryLevel | None:
    """The level a battery STATUSTEXT says (ArduPilot AP_BattMonitor: "Battery 1 is low 11.00V used
    500 mAh", "... is critical ..."; PX4: "Critical battery level ...", "Emergency battery level
    ..."), None if it says none."""
    t = text.lower()
    if "battery" not in t or t.startswith(("prearm", "arm:")):
        return None
    for word, level in (("emergency", "emergency"), ("critical", "critical"), ("low", "low")):
        if word in t:
            return level  # type: ignore[return-value]
    return None


def battery_state(reading: BatteryReading, pack: BatteryParams | None, stamp_ns: int,
                  said: tuple[BatteryLevel, str] | None = None) -> BatteryState:
    """The autopilot's battery in SI units (``BatteryState``, source ``autopilot``), completed from
    the vessel file's ``[battery]`` (``pack``; None: only what the autopilot measured).

    * power = voltage x current where the autopilot measures both [W];
    * energy drawn: the autopilot's energy count [J]; else its charge count at the pack's nominal
      voltage (``BatteryParams.joules_from_mah``);
    * remaining energy: the autopilot's remaining fraction x the usable energy; else usable energy
      minus the energy drawn (never below 0); the fraction, if the autopilot gives none, is that
      over the usable energy;
    * capacity (usable energy) and reserve: the vessel file's;
    * the autopilot's level: its charge_state, or the level its battery text ``said`` (level, text),
      whichever is worse.
    """
    v, i = reading.voltage_v, reading.current_a
    consumed = reading.consumed_j
    frac = reading.remaining_frac
    capacity = reserve = remaining = None
    if pack is not None:
        capacity, reserve = pack.energy_j, pack.reserve_energy_j
        if consumed is None and reading.consumed_mah is not None:
            consumed = pack.joules_from_mah(reading.consumed_mah)
        if frac is not None:
            remaining = frac * capacity
        elif consumed is not None:
            remaining = max(0.0, capacity - consumed)
            frac = remaining / capacity
    return BatteryState.make(
        stamp_ns=stamp_ns, source="autopilot", voltage_v=v, current_a=i,
        power_w=v * i if v is not None and i is not None else None, consumed_j=consumed,
        remaining_j=remaining, remaining_frac=frac, capacity_j=capacity, reserve_j=reserve,
        autopilot_level=worse_level(reading.level, None if said is None else said[0]),
        autopilot_level_detail="" if said is None else said[1])
