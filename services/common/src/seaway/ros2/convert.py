"""Seaway's messages as ROS 2 messages, and the one place Seaway's frames become ROS's.

Seaway (design.md): world frame local NED at the published origin (x north, y east, psi clockwise
from north), body frame forward-right-down. ROS (REP 103, REP 105): world frame ENU (x east, y
north, z up: frame ``map``, at the same origin), body frame forward-left-up (``base_link``). So:

* a position (north, east) is (x = east, y = north, z = 0) in ``map``;
* a heading psi (clockwise from north) is the yaw pi/2 - psi (counter-clockwise from east), as a
  quaternion about z;
* a body velocity (u forward, v right, r clockwise) is (x = u, y = -v) with angular z = -r;
* a body force and moment (X forward, Y right, N clockwise) is (x = X, y = -Y), torque z = -N;
* and back, for what ROS 2 may send (``seaway-ros2 --ros2-writes``): a ``nav_msgs/Path`` in ``map``
  is the NED waypoints (north = y, east = x) of a mission (``path_waypoints_ned``).

Every function here takes a Seaway message and returns ``(ROS type name, message dict)`` for
``seaway.ros2.cdr.encode``; units stay SI, times become ``builtin_interfaces/Time`` from
``stamp_ns`` (the same clock as the message: wall time live, sim time in simulation).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from seaway.contract import messages as m
from seaway.ros2 import types as rt
from seaway.vessel.model import VesselParams, wrench

MAP_FRAME = "map"
"""ROS's world frame: ENU at Seaway's published NED origin."""
BODY_FRAME = "base_link"
"""ROS's body frame: forward-left-up, at the vessel's reference point."""
NAN = float("nan")
"""What a ROS field holds when Seaway does not know it (sensor_msgs' convention for unmeasured)."""

Msg = tuple[str, dict[str, Any]]


# -- frames: the one place NED/FRD becomes ENU/FLU --------------------------------------------


def ned_to_enu(north_m: float, east_m: float) -> tuple[float, float]:
    """(north, east) in NED -> (x east, y north) in ENU [m]."""
    return east_m, north_m


def enu_to_ned(x_east_m: float, y_north_m: float) -> tuple[float, float]:
    """(x east, y north) in ENU -> (north, east) in NED [m]."""
    return y_north_m, x_east_m


def heading_to_yaw(psi_rad: float) -> float:
    """Heading clockwise from north (NED) -> yaw counter-clockwise from east (ENU), in (-pi, pi]."""
    yaw = math.pi / 2.0 - psi_rad
    return math.atan2(math.sin(yaw), math.cos(yaw))


def frd_to_flu(forward: float, right: float, down: float = 0.0) -> tuple[float, float, float]:
    """A body vector forward-right-down -> forward-left-up (a rate about down -> about up too)."""
    return forward, -right, -down


def yaw_quaternion(yaw_rad: float) -> dict[str, float]:
    """The rotation by ``yaw_rad`` about z, as ``geometry_msgs/Quaternion``."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw_rad / 2.0), "w": math.cos(yaw_rad / 2.0)}


# -- pieces -----------------------------------------------------------------------------------


def stamp(stamp_ns: int) -> dict[str, int]:
    """``builtin_interfaces/Time`` of a stamp [ns]."""
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return {"sec": sec, "nanosec": nanosec}


def header(stamp_ns: int, frame_id: str) -> dict[str, Any]:
    return {"stamp": stamp(stamp_ns), "frame_id": frame_id}


def _vec(x: float, y: float, z: float) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def pose_ned(north_m: float, east_m: float, psi_rad: float) -> dict[str, Any]:
    """``geometry_msgs/Pose`` in ``map`` of a NED position and heading."""
    x, y = ned_to_enu(north_m, east_m)
    return {"position": _vec(x, y, 0.0), "orientation": yaw_quaternion(heading_to_yaw(psi_rad))}


# State covariance indices of StateEstimate.covariance (row-major 9x9 of u, v, r, x, y, psi, ...).
_U, _V, _R, _X, _Y, _PSI = range(6)


def _pose_covariance(cov: Sequence[float] | None) -> list[float]:
    """The 6x6 (x, y, z, roll, pitch, yaw) ENU pose covariance from Seaway's 9x9; zero where Seaway
    estimates nothing (z, roll, pitch) and all zero when the estimate has no covariance."""
    out = [0.0] * 36
    if cov is None:
        return out
    # ENU x = NED y, ENU y = NED x, ENU yaw = pi/2 - psi (sign -1).
    src = {0: (_Y, 1.0), 1: (_X, 1.0), 5: (_PSI, -1.0)}
    for i, (a, sa) in src.items():
        for j, (b, sb) in src.items():
            out[6 * i + j] = sa * sb * cov[9 * a + b]
    return out


def _twist_covariance(cov: Sequence[float] | None) -> list[float]:
    """The 6x6 (vx, vy, vz, wx, wy, wz) FLU twist covariance from Seaway's (u, v, r) block."""
    out = [0.0] * 36
    if cov is None:
        return out
    src = {0: (_U, 1.0), 1: (_V, -1.0), 5: (_R, -1.0)}
    for i, (a, sa) in src.items():
        for j, (b, sb) in src.items():
            out[6 * i + j] = sa * sb * cov[9 * a + b]
    return out


# -- from ROS 2 -------------------------------------------------------------------------------


class NotConvertibleError(ValueError):
    """A ROS 2 message Seaway cannot take as it is (a frame it does not know, a value not finite)."""


def path_waypoints_ned(path: Mapping[str, Any]) -> list[tuple[float, float]]:
    """The (north, east) waypoints [m] of a ``nav_msgs/Path`` (decoded), in the order given.

    Its frame must be ``map``, the frame the face publishes in (the path's header; a pose's own
    header may leave it empty or say ``map``): Seaway has no transform tree to take another.
    Positions must be finite; ``z`` and the orientations are not used (a mission is waypoints)."""
    frame = path["header"]["frame_id"]
    if frame != MAP_FRAME:
        raise NotConvertibleError(f"Path.header.frame_id is {frame!r}: only {MAP_FRAME!r} (ENU at "
                             "Seaway's origin) is taken")
    out = []
    for i, ps in enumerate(path["poses"]):
        if ps["header"]["frame_id"] not in ("", MAP_FRAME):
            raise NotConvertibleError(f"Path.poses[{i}].header.frame_id is {ps['header']['frame_id']!r}: "
                                 f"only {MAP_FRAME!r} or empty is taken")
        p = ps["pose"]["position"]
        if not (math.isfinite(p["x"]) and math.isfinite(p["y"])):
            raise NotConvertibleError(f"Path.poses[{i}].pose.position ({p['x']}, {p['y']}) is not finite")
        out.append(enu_to_ned(p["x"], p["y"]))
    return out


# -- messages ---------------------------------------------------------------------------------


def odometry(s: m.StateEstimate) -> Msg:
    """``nav_msgs/Odometry``: pose in ``map`` (ENU), twist in ``base_link`` (FLU)."""
    u, v_left, _ = frd_to_flu(s.u_mps, s.v_mps)
    _, _, r_up = frd_to_flu(0.0, 0.0, s.r_radps)
    return rt.ODOMETRY.name, {
        "header": header(s.stamp_ns, MAP_FRAME), "child_frame_id": BODY_FRAME,
        "pose": {"pose": pose_ned(s.x_m, s.y_m, s.psi_rad),
                 "covariance": _pose_covariance(s.covariance)},
        "twist": {"twist": {"linear": _vec(u, v_left, 0.0), "angular": _vec(0.0, 0.0, r_up)},
                  "covariance": _twist_covariance(s.covariance)},
    }


# MAVLink GPS_FIX_TYPE -> NavSatStatus.status: no fix (0, 1), SBAS/DGPS (4), RTK (5, 6), else fix.
_NO_FIX, _FIX, _SBAS, _GBAS = -1, 0, 1, 2
_SERVICE_GPS = 1
_COV_UNKNOWN, _COV_APPROXIMATED = 0, 1


def nav_sat_fix(g: m.GnssFix) -> Msg:
    """``sensor_msgs/NavSatFix`` in degrees; the horizontal 1-sigma, when known, as an approximated
    diagonal covariance (east, north; up unknown: 0)."""
    status = (_NO_FIX if g.fix_type <= 1 else _SBAS if g.fix_type == 4
              else _GBAS if g.fix_type in (5, 6) else _FIX)
    cov = [0.0] * 9
    kind = _COV_UNKNOWN
    if g.horizontal_std_m is not None:
        cov[0] = cov[4] = g.horizontal_std_m ** 2
        kind = _COV_APPROXIMATED
    return rt.NAV_SAT_FIX.name, {
        "header": header(g.stamp_ns, BODY_FRAME), "status": {"status": status, "service": _SERVICE_GPS},
        "latitude": math.degrees(g.lat_rad), "longitude": math.degrees(g.lon_rad),
        "altitude": g.alt_m, "position_covariance": cov, "position_covariance_type": kind,
    }


def path_ned(stamp_ns: int, points: Sequence[tuple[float, float, float]]) -> Msg:
    """``nav_msgs/Path`` in ``map`` through NED (north, east, heading) points, each pose stamped
    with the path's stamp."""
    return rt.PATH.name, {
        "header": header(stamp_ns, MAP_FRAME),
        "poses": [{"header": header(stamp_ns, MAP_FRAME), "pose": pose_ned(n, e, psi)}
                  for n, e, psi in points],
    }


def mission_path(a: m.MissionAccepted) -> Msg:
    """The accepted mission's waypoints P_0..P_N as ``nav_msgs/Path``, each pose facing along its
    leg (the last one along the last leg)."""
    wps = a.waypoints_m()
    pts = []
    for i, (n, e) in enumerate(wps):
        (n0, e0), (n1, e1) = (wps[i], wps[i + 1]) if i + 1 < len(wps) else (wps[i - 1], wps[i])
        pts.append((n, e, math.atan2(e1 - e0, n1 - n0)))
    return path_ned(a.stamp_ns, pts)


def predicted_path(s: m.SolveRecord) -> Msg:
    """The MPC's predicted trajectory as ``nav_msgs/Path`` (headings where the solve gave them)."""
    psi = s.predicted_psi_rad if len(s.predicted_psi_rad) == len(s.predicted_x_m) else None
    pts = [(x, y, psi[i] if psi else 0.0)
           for i, (x, y) in enumerate(zip(s.predicted_x_m, s.predicted_y_m, strict=False))]
    return path_ned(s.stamp_ns, pts)


def thrust_wrench(t: m.ThrustCommand, vessel: VesselParams) -> Msg:
    """The commanded thrust as ``geometry_msgs/WrenchStamped`` in ``base_link`` (FLU): surge force
    T1 + T2 and yaw moment from the vessel's thruster arm (``seaway.vessel.model.wrench``)."""
    surge_n, sway_n, yaw_nm = wrench((t.thrust_port_n, t.thrust_starboard_n), vessel)
    fx, fy, _ = frd_to_flu(surge_n, sway_n)
    _, _, mz = frd_to_flu(0.0, 0.0, yaw_nm)
    return rt.WRENCH_STAMPED.name, {
        "header": header(t.stamp_ns, BODY_FRAME),
        "wrench": {"force": _vec(fx, fy, 0.0), "torque": _vec(0.0, 0.0, mz)},
    }


_DISCHARGING, _STATUS_UNKNOWN = 2, 0


def battery_state(b: m.BatteryState) -> Msg:
    """``sensor_msgs/BatteryState``: NaN where Seaway does not know; the current negative while
    discharging (ROS's sign), the percentage as a fraction 0..1 (ROS's unit)."""
    def num(x: float | None) -> float:
        return NAN if x is None else float(x)

    current = NAN if b.current_a is None else -float(b.current_a)
    return rt.BATTERY_STATE.name, {
        "header": header(b.stamp_ns, BODY_FRAME), "voltage": num(b.voltage_v),
        "temperature": NAN, "current": current, "charge": NAN, "capacity": NAN,
        "design_capacity": NAN, "percentage": num(b.remaining_frac),
        "power_supply_status": _DISCHARGING if (b.current_a or 0.0) > 0 else _STATUS_UNKNOWN,
        "power_supply_health": 0, "power_supply_technology": 0, "present": True,
        "cell_voltage": [], "cell_temperature": [], "location": "propulsion",
        "serial_number": "",
    }


OK, WARN, ERROR, STALE = 0, 1, 2, 3
"""diagnostic_msgs/DiagnosticStatus levels."""


def diagnostics(stamp_ns: int, vessel: str, services: Mapping[str, bool],
                status: m.VehicleStatus | None) -> Msg:
    """``diagnostic_msgs/DiagnosticArray``: one status per service seen (OK while its health token
    lives, ERROR once it is gone) and the vehicle's (ERROR without a link, WARN in a failsafe)."""
    out = [{"level": OK if alive else ERROR, "name": f"seaway {service}",
            "message": "alive" if alive else "gone (health token withdrawn)",
            "hardware_id": vessel, "values": []}
           for service, alive in sorted(services.items())]
    if status is not None:
        level = ERROR if not status.link_ok else WARN if status.failsafe or status.hold_reason else OK
        values = {"autopilot": status.autopilot, "armed": str(status.armed).lower(),
                  "mode": status.mode, "failsafe": status.failsafe or "",
                  "hold_reason": status.hold_reason or "",
                  "thrust_withheld": status.thrust_withheld or ""}
        out.append({"level": level, "name": "seaway vehicle",
                    "message": "no autopilot link" if not status.link_ok
                    else status.failsafe or status.hold_reason or status.mode,
                    "hardware_id": vessel,
                    "values": [{"key": k, "value": v} for k, v in values.items()]})
    return rt.DIAGNOSTIC_ARRAY.name, {"header": header(stamp_ns, ""), "status": out}
