"""The operating area as the autopilot's own fence: its mission items, its parameters and limits per
autopilot, and the comparison of what the autopilot holds with what was meant. Pure.

Items (MAVLink common.xml; both firmwares' mission protocol, ``MAV_MISSION_TYPE_FENCE`` and
``MAV_MISSION_TYPE_RALLY``), positions in WGS84 degrees x 1e7 (``MAV_FRAME_GLOBAL`` in
MISSION_ITEM_INT, as QGroundControl sends them):

* the keep-in polygon: one ``MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION`` per vertex, param1 =
  the polygon's vertex count;
* each keep-out polygon: ``MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION`` the same way;
* each keep-out circle: one ``MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION``, param1 = radius [m];
* each rally point: one ``MAV_CMD_NAV_RALLY_POINT`` (``MAV_FRAME_GLOBAL_RELATIVE_ALT``, z = 0).

The fence's action is **Hold** on both autopilots: the vessel stops where it meets the line and
waits for the operator. A return (RTL) would drive straight for home or a rally point, possibly
across a keep-out area, with nobody checking the path; Hold is also what Seaway itself does when a
failsafe takes the vessel (it pauses with zero thrust).

* ArduPilot Rover (``AC_Fence``; ``Rover/fence.cpp`` acts on a new breach whenever armed, in any
  mode): ``FENCE_TYPE = 4`` (bit 2: the uploaded inclusion/exclusion polygons and circles; not bit
  1, the circle round home of ``FENCE_RADIUS``, which knows nothing of the area), ``FENCE_ACTION =
  2`` (Hold), then ``FENCE_ENABLE = 1`` (last: enabled with no fence stored, it fails its arming
  check "Fences enabled, but none selected"). The number of items it stores depends on the
  board's fence storage (84 on a Pixhawk); more are refused with MISSION_ACK ``NO_SPACE``.
  An empty area uploads no items and sets ``FENCE_ENABLE = 0``.
* PX4 (navigator's ``Geofence``): the fence is in force whenever it holds items; ``GF_ACTION = 2``
  (Hold mode). Its dataman stores at most ``DM_KEY_FENCE_POINTS_MAX`` = 64 fence items and 32
  rally (safe) points: more are refused here before sending, naming the fields.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from seaway.area.model import OperatingArea
from seaway.vessel.frames import GeoOrigin

from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import MissionItem

VERTEX_INCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
VERTEX_EXCLUSION = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
CIRCLE_EXCLUSION = mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RALLY_POINT = mavlink.MAV_CMD_NAV_RALLY_POINT
MAV_PARAM_TYPE_INT8 = 2
MAV_PARAM_TYPE_INT32 = 6
DISCARD_TEXT = "geofence invalid"
"""What PX4 says when its navigator discards a zone it accepted (``Geofence::_updateFence``:
"Geofence invalid, doesn't contain Home position" / "... current vehicle position")."""
LATLON_TOLERANCE_E7 = 1  # a firmware storing degrees as double may round by one unit (~1 cm)
RADIUS_TOLERANCE_M = 0.01


@dataclass(frozen=True)
class FenceParam:
    """One parameter vehicle_io sets for the fence: the value meant and how it goes on the wire."""

    name: str
    value: int
    param_type: int
    bytewise: bool  # PX4 copies an integer's bytes into PARAM_SET's float; ArduPilot casts
    meaning: str

    def wire_value(self) -> float:
        if self.bytewise:
            return float(struct.unpack("<f", struct.pack("<i", self.value))[0])
        return float(self.value)


@dataclass(frozen=True)
class AutopilotFence:
    """What one autopilot needs to hold the area as its fence (see the module docstring)."""

    enable: tuple[FenceParam, ...]
    disable: tuple[FenceParam, ...]
    max_fence_items: int | None  # None: the firmware says (MISSION_ACK NO_SPACE)
    max_rally_points: int | None
    limit_source: str


FENCES: dict[str, AutopilotFence] = {
    "ardupilot": AutopilotFence(
        enable=(FenceParam("FENCE_TYPE", 4, MAV_PARAM_TYPE_INT8, False,
                           "inclusion/exclusion polygons and circles"),
                FenceParam("FENCE_ACTION", 2, MAV_PARAM_TYPE_INT8, False, "Hold"),
                FenceParam("FENCE_ENABLE", 1, MAV_PARAM_TYPE_INT8, False, "enabled")),
        disable=(FenceParam("FENCE_ENABLE", 0, MAV_PARAM_TYPE_INT8, False, "disabled"),),
        max_fence_items=None, max_rally_points=None,
        limit_source="its fence storage"),
    "px4": AutopilotFence(
        enable=(FenceParam("GF_ACTION", 2, MAV_PARAM_TYPE_INT32, True, "Hold mode"),),
        disable=(),
        max_fence_items=64, max_rally_points=32,
        limit_source="PX4's dataman (DM_KEY_FENCE_POINTS_MAX 64, DM_KEY_SAFE_POINTS_MAX 32)"),
}


def _e7(rad: float) -> int:
    return round(math.degrees(rad) * 1e7)


def _at(origin: GeoOrigin, north_m: float, east_m: float) -> tuple[int, int]:
    lat, lon, _ = origin.to_geodetic(north_m, east_m, 0.0)
    return _e7(lat), _e7(lon)


def fence_items(area: OperatingArea, origin: GeoOrigin) -> tuple[MissionItem, ...]:
    """The fence items of ``area`` (local NED at ``origin``): keep-in vertices, then each keep-out
    polygon's, then the keep-out circles."""
    frame = mavlink.MAV_FRAME_GLOBAL
    items: list[MissionItem] = []
    polygons = ([(VERTEX_INCLUSION, area.keep_in)] if area.keep_in is not None else []) + [
        (VERTEX_EXCLUSION, p) for p in area.keep_out_polygons]
    for command, poly in polygons:
        n = len(poly.vertices_m)
        items += [MissionItem(command, frame, float(n), *_at(origin, *v)) for v in poly.vertices_m]
    items += [MissionItem(CIRCLE_EXCLUSION, frame, float(c.radius_m), *_at(origin, *c.center_m))
              for c in area.keep_out_circles]
    return tuple(items)


def rally_items(area: OperatingArea, origin: GeoOrigin) -> tuple[MissionItem, ...]:
    """The rally points of ``area`` as ``MAV_CMD_NAV_RALLY_POINT`` items, at the water (z = 0)."""
    frame = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT
    return tuple(MissionItem(RALLY_POINT, frame, 0.0, *_at(origin, *r.position_m))
                 for r in area.rally_points)


def fence_item_count(area: OperatingArea) -> str:
    """How the fence items of ``area`` add up, by field (for a refusal)."""
    parts = []
    if area.keep_in is not None:
        parts.append(f"keep_in ({len(area.keep_in.vertices_m)} vertices)")
    if area.keep_out_polygons:
        n = sum(len(p.vertices_m) for p in area.keep_out_polygons)
        parts.append(f"keep_out_polygons ({len(area.keep_out_polygons)}, {n} vertices)")
    if area.keep_out_circles:
        parts.append(f"keep_out_circles ({len(area.keep_out_circles)})")
    return " + ".join(parts) or "nothing"


def refusal(area: OperatingArea, fence: AutopilotFence, autopilot: str) -> str | None:
    """Why ``area`` cannot be the autopilot's fence (None: it fits what is known of it)."""
    n = len(area.keep_out_circles) + sum(len(p.vertices_m) for p in area.keep_out_polygons) + (
        len(area.keep_in.vertices_m) if area.keep_in is not None else 0)
    if fence.max_fence_items is not None and n > fence.max_fence_items:
        return (f"the operating area is {n} fence items ({fence_item_count(area)}), more than "
                f"{autopilot} stores ({fence.max_fence_items}, {fence.limit_source}): use fewer "
                "vertices")
    rally = len(area.rally_points)
    if fence.max_rally_points is not None and rally > fence.max_rally_points:
        return (f"rally_points: {rally} rally points, more than {autopilot} stores "
                f"({fence.max_rally_points}, {fence.limit_source})")
    return None


def differences(kind: str, meant: tuple[MissionItem, ...], held: list[MissionItem]) -> list[str]:
    """Where the items the autopilot holds differ from those uploaded (empty: they match)."""
    if len(held) != len(meant):
        return [f"{kind}: the autopilot holds {len(held)} items, {len(meant)} were uploaded"]
    out: list[str] = []
    for i, (m, h) in enumerate(zip(meant, held, strict=True)):
        if h.command != m.command:
            out.append(f"{kind} item {i}: command {h.command}, uploaded {m.command}")
        elif (abs(h.lat_e7 - m.lat_e7) > LATLON_TOLERANCE_E7
              or abs(h.lon_e7 - m.lon_e7) > LATLON_TOLERANCE_E7):
            out.append(f"{kind} item {i}: at {h.lat_e7 / 1e7:.7f}, {h.lon_e7 / 1e7:.7f}, uploaded "
                       f"{m.lat_e7 / 1e7:.7f}, {m.lon_e7 / 1e7:.7f}")
        elif m.command != RALLY_POINT and not abs(h.param1 - m.param1) <= RADIUS_TOLERANCE_M:
            # written so that a NaN held (a corrupt radius or vertex count) differs too
            out.append(f"{kind} item {i}: param1 {h.param1:g}, uploaded {m.param1:g}")
    return out
