"""Build real MAVLink messages (packed to bytes and parsed back) for the core's tests."""

from __future__ import annotations

from typing import Any

from seaway_vehicle_io.mav import mavlink


def wire(msg: Any, sysid: int = 1, compid: int = 1) -> Any:
    """``msg`` as vehicle_io would receive it from (sysid, compid): packed, then decoded."""
    tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    rx = mavlink.MAVLink(None)
    return rx.decode(bytearray(msg.pack(tx)))


def heartbeat(autopilot: int = 12, armed: bool = False, custom_mode: int = 1 << 16,
              mav_type: int = 10, sysid: int = 1, compid: int = 1) -> Any:
    base = 1 | (128 if armed else 0)
    return wire(mavlink.MAVLink_heartbeat_message(mav_type, autopilot, base, custom_mode, 4, 3),
                sysid, compid)


def global_position_int(time_boot_ms: int = 1000, lat: int = 473977420, lon: int = 85455940,
                        alt: int = 488_000, vx: int = 150, vy: int = -50, sysid: int = 1) -> Any:
    return wire(mavlink.MAVLink_global_position_int_message(
        time_boot_ms, lat, lon, alt, 0, vx, vy, 0, 0), sysid)


def attitude(time_boot_ms: int = 1000, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.5,
             rollspeed: float = 0.0, pitchspeed: float = 0.0, yawspeed: float = 0.1,
             sysid: int = 1) -> Any:
    return wire(mavlink.MAVLink_attitude_message(time_boot_ms, roll, pitch, yaw, rollspeed,
                                                 pitchspeed, yawspeed), sysid)
