"""The PX4 parameters the simulated autopilot exposes, with PX4's defaults, and their wire encoding.

Only the parameters vehicle_io reads at start-up to check the failsafe chain (docs/autopilots.md,
"PARAM_REQUEST_READ at start-up") exist. Those the sim acts on are marked ``used``; the others are
reported so that a start-up check sees PX4's values, and changing them changes nothing in the sim.

Encoding: PX4 uses the MAVLink parameter protocol's *bytewise* encoding (it advertises
MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE in AUTOPILOT_VERSION): an INT32 parameter's four bytes
are carried unchanged in PARAM_VALUE.param_value (a float field), not converted to a float.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

MAV_PARAM_TYPE_INT32 = 6
MAV_PARAM_TYPE_REAL32 = 9
PARAM_ID_LEN = 16


@dataclass(frozen=True)
class ParamSpec:
    name: str
    param_type: int  # MAV_PARAM_TYPE_INT32 or MAV_PARAM_TYPE_REAL32
    default: float | int
    minimum: float
    maximum: float
    used: bool
    doc: str


# PX4 defaults as docs/autopilots.md A.3/A.4 and "simulator should mimic", item 6, give them.
PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec("COM_RC_IN_MODE", MAV_PARAM_TYPE_INT32, 3, 0, 6, True,
              "manual control source; 0 RC only and 4 disabled make the sim ignore MANUAL_CONTROL"),
    ParamSpec("COM_RC_LOSS_T", MAV_PARAM_TYPE_REAL32, 0.5, 0.0, 35.0, True,
              "manual control loss timeout [s]"),
    ParamSpec("NAV_RCL_ACT", MAV_PARAM_TYPE_INT32, 2, 1, 6, True,
              "manual control loss action: 1 Hold, 2 Return, 3 Land, 5 Terminate, 6 Disarm"),
    ParamSpec("COM_RCL_EXCEPT", MAV_PARAM_TYPE_INT32, 0, 0, 31, False,
              "RC loss exceptions (cannot exempt Manual)"),
    ParamSpec("COM_FAIL_ACT_T", MAV_PARAM_TYPE_REAL32, 5.0, 0.0, 25.0, True,
              "delay in Hold before the failsafe action [s]"),
    ParamSpec("NAV_DLL_ACT", MAV_PARAM_TYPE_INT32, 0, 0, 6, False, "data link loss action"),
    # INT32 in PX4 (commander_params.c), as the 1.18 SITL reports it.
    ParamSpec("COM_DL_LOSS_T", MAV_PARAM_TYPE_INT32, 10, 5, 300, False,
              "data link loss timeout [s]"),
    ParamSpec("COM_DISARM_LAND", MAV_PARAM_TYPE_REAL32, 2.0, -1.0, 20.0, True,
              "disarm this long after landing is detected (a Return that ends at home) [s]; "
              "<= 0: never"),
    ParamSpec("NAV_ACC_RAD", MAV_PARAM_TYPE_REAL32, 0.5, 0.05, 200.0, True,
              "acceptance radius [m]: a Return that begins this close to home has arrived "
              "(PX4's rover default, rc.rover_differential_defaults)"),
    ParamSpec("COM_OF_LOSS_T", MAV_PARAM_TYPE_REAL32, 1.0, 0.0, 60.0, False,
              "offboard loss timeout [s]"),
    ParamSpec("COM_OBL_RC_ACT", MAV_PARAM_TYPE_INT32, 0, 0, 7, False, "offboard loss action"),
    ParamSpec("MAV_TYPE", MAV_PARAM_TYPE_INT32, 10, 0, 40, True,
              "HEARTBEAT type: 10 GROUND_ROVER (PX4 rover defaults) or 11 SURFACE_BOAT"),
    ParamSpec("MAV_SYS_ID", MAV_PARAM_TYPE_INT32, 1, 1, 250, False, "MAVLink system id"),
    ParamSpec("CA_AIRFRAME", MAV_PARAM_TYPE_INT32, 6, 0, 15, False, "6 = Rover (Differential)"),
    ParamSpec("CA_R_REV", MAV_PARAM_TYPE_INT32, 3, 0, 255, False, "reversible motors bitmask"),
    # The rover throttle slew limits: the sim does not model them, so it reports them off (-1:
    # disabled), which is what a companion streaming MANUAL_CONTROL for direct thrust wants.
    ParamSpec("RO_ACCEL_LIM", MAV_PARAM_TYPE_REAL32, -1.0, -1.0, 100.0, False,
              "throttle acceleration limit [m/s^2]; -1 disabled (not simulated)"),
    ParamSpec("RO_DECEL_LIM", MAV_PARAM_TYPE_REAL32, -1.0, -1.0, 100.0, False,
              "throttle deceleration limit [m/s^2]; -1 disabled (not simulated)"),
    ParamSpec("RD_YAW_STK_GAIN", MAV_PARAM_TYPE_REAL32, 1.0, 0.0, 1.0, True,
              "Manual mode: speed difference = roll stick x this (rover_differential)"),
    ParamSpec("RO_MAX_THR_SPEED", MAV_PARAM_TYPE_REAL32, -1.0, -1.0, 100.0, False,
              "speed at full throttle [m/s]; -1 disabled (not simulated)"),
    ParamSpec("GF_ACTION", MAV_PARAM_TYPE_INT32, 2, 0, 5, True,
              "geofence breach action: 0 none, 1 warning, 2 Hold, 3 Return, 4 Terminate, 5 Land "
              "(PX4's default 2)"),
    ParamSpec("GF_SOURCE", MAV_PARAM_TYPE_INT32, 0, 0, 1, False,
              "geofence position source: 0 global position, 1 GPS (the sim's fix either way)"),
)
BY_NAME: dict[str, ParamSpec] = {p.name: p for p in PARAMS}
INDEX: dict[str, int] = {p.name: i for i, p in enumerate(PARAMS)}


def encode_value(spec: ParamSpec, value: float | int) -> float:
    """The float that goes into PARAM_VALUE.param_value (bytewise for INT32)."""
    if spec.param_type == MAV_PARAM_TYPE_INT32:
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]
    return float(value)


def decode_value(param_type: int, wire: float) -> float | int:
    """The value a PARAM_SET/PARAM_VALUE float carries, for ``param_type`` (bytewise for INT32)."""
    if param_type == MAV_PARAM_TYPE_INT32:
        return struct.unpack("<i", struct.pack("<f", wire))[0]
    return wire


def param_id_text(raw: str | bytes) -> str:
    """A param_id field as text: NUL-terminated unless all 16 characters are used."""
    text = raw.decode("ascii", "replace") if isinstance(raw, bytes) else raw
    return text.split("\0", 1)[0][:PARAM_ID_LEN]


class ParamStore:
    """Current values, starting at PX4's defaults; ``set`` validates type and range."""

    def __init__(self, overrides: dict[str, float | int] | None = None) -> None:
        self.values: dict[str, float | int] = {p.name: p.default for p in PARAMS}
        for name, value in (overrides or {}).items():
            error = self.set(name, BY_NAME[name].param_type if name in BY_NAME else -1, value)
            if error:
                raise ValueError(error)

    def get(self, name: str) -> float | int:
        return self.values[name]

    def set(self, name: str, param_type: int, value: float | int) -> str | None:
        """Set a value; returns None, or why it was refused (the value is then unchanged)."""
        spec = BY_NAME.get(name)
        if spec is None:
            return f"unknown parameter {name!r}"
        if param_type != spec.param_type:
            return f"{name}: type {param_type} given, the parameter is type {spec.param_type}"
        if isinstance(value, float) and not math.isfinite(value):
            return f"{name}: value {value} is not finite"
        if not spec.minimum <= value <= spec.maximum:
            return f"{name}: {value} outside [{spec.minimum:g}, {spec.maximum:g}]"
        self.values[name] = int(value) if spec.param_type == MAV_PARAM_TYPE_INT32 else float(value)
        return None
