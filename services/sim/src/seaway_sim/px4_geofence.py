"""The simulated PX4's geofence and rally points: its side of MAVLink's mission protocol for
``MAV_MISSION_TYPE_FENCE`` and ``MAV_MISSION_TYPE_RALLY``, and the fence check. Pure: decoded
messages and the time in, messages out.

As PX4 1.18 (``mavlink_mission.cpp``, ``navigator/geofence.cpp``, ``dataman``):

* upload: MISSION_COUNT -> MISSION_REQUEST_INT(0) ... each MISSION_ITEM_INT in order ->
  MISSION_ACK ACCEPTED after the last; more than ``MAX_ITEMS`` (dataman's
  ``DM_KEY_FENCE_POINTS_MAX`` 64, ``DM_KEY_SAFE_POINTS_MAX`` 32) -> MISSION_ACK NO_SPACE; a
  polygon vertex whose param1 (the vertex count) is below 3 -> "Fence: too few vertices" and
  MISSION_ACK INVALID_PARAM1; an item out of order -> the expected one asked again. A count of 0
  clears the list;
* download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT(seq) -> MISSION_ITEM_INT;
* the fence: every polygon and circle is a zone; a point is inside the fence when it passes every
  zone (inside each inclusion, outside each exclusion). A zone that does not contain home, or
  (armed, ``GF_ACTION`` not 0) the vehicle's position, is discarded when the fence is loaded, with
  PX4's texts "Geofence invalid, doesn't contain Home position" / "... current vehicle position".

**Differs**: the mission type itself (MAV_MISSION_TYPE_MISSION) is refused with UNSUPPORTED (the
sim cannot fly missions); the server never re-asks on its own (PX4 re-requests after 250 ms): the
client's resend covers a lost item; polygons are tested in a local plane at their first vertex,
not on latitude/longitude directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pymavlink.dialects.v20 import common as mavlink
from seaway.area.geometry import point_in_polygon
from seaway.vessel.frames import GeoOrigin

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
RALLY = mavlink.MAV_MISSION_TYPE_RALLY
MAX_ITEMS = {FENCE: 64, RALLY: 32}
INCLUSION_POLYGON = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
EXCLUSION_POLYGON = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
INCLUSION_CIRCLE = mavlink.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
EXCLUSION_CIRCLE = mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
POLYGONS = (INCLUSION_POLYGON, EXCLUSION_POLYGON)
CIRCLES = (INCLUSION_CIRCLE, EXCLUSION_CIRCLE)
SEVERITY_CRITICAL = mavlink.MAV_SEVERITY_CRITICAL


@dataclass(frozen=True)
class StoredItem:
    seq: int
    frame: int
    command: int
    param1: float
    x: int  # latitude [deg x 1e7]
    y: int  # longitude [deg x 1e7]
    z: float


@dataclass(frozen=True)
class Zone:
    """One polygon or circle of the fence, in a local plane (north, east) [m] at ``origin``."""

    command: int
    origin: GeoOrigin
    points_m: tuple[tuple[float, float], ...]
    radius_m: float = 0.0

    def passes(self, lat_rad: float, lon_rad: float) -> bool:
        """Whether a position satisfies this zone (inside an inclusion, outside an exclusion)."""
        north, east, _ = self.origin.to_ned(lat_rad, lon_rad)
        if self.command in CIRCLES:
            c = self.points_m[0]
            inside = math.hypot(north - c[0], east - c[1]) < self.radius_m
        else:
            inside = point_in_polygon((north, east), self.points_m)
        return inside if self.command in (INCLUSION_POLYGON, INCLUSION_CIRCLE) else not inside


def _rad(e7: int) -> float:
    return math.radians(e7 / 1e7)


class Px4Geofence:
    """The fence and rally lists of one simulated PX4, and their mission-protocol server."""

    def __init__(self, sysid: int, compid: int) -> None:
        self.sysid, self.compid = sysid, compid
        self.items: dict[int, list[StoredItem]] = {FENCE: [], RALLY: []}
        self.zones: list[Zone] = []
        self.texts: list[tuple[int, str]] = []  # STATUSTEXT (severity, text) to send
        self._incoming: dict[int, list[StoredItem]] = {}
        self._expected: dict[int, int] = {}
        self.loaded = 0  # fences loaded (a new upload, or cleared): the autopilot checks again

    def handle(self, msg: Any) -> list[Any]:
        """A mission-protocol message addressed to this autopilot; the replies."""
        kind = msg.get_type()
        mtype = int(getattr(msg, "mission_type", 0))
        if mtype not in MAX_ITEMS:
            return [self._ack(msg, mavlink.MAV_MISSION_UNSUPPORTED, mtype)]
        if kind == "MISSION_COUNT":
            return self._on_count(msg, mtype)
        if kind == "MISSION_ITEM_INT":
            return self._on_item(msg, mtype)
        if kind == "MISSION_REQUEST_LIST":
            return [mavlink.MAVLink_mission_count_message(msg.get_srcSystem(), msg.get_srcComponent(),
                                                          len(self.items[mtype]), mtype)]
        if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            stored = self.items[mtype]
            if not 0 <= msg.seq < len(stored):
                return [self._ack(msg, mavlink.MAV_MISSION_INVALID_SEQUENCE, mtype)]
            i = stored[msg.seq]
            return [mavlink.MAVLink_mission_item_int_message(
                msg.get_srcSystem(), msg.get_srcComponent(), i.seq, i.frame, i.command, 0, 1,
                i.param1, 0, 0, 0, i.x, i.y, i.z, mtype)]
        return []  # MISSION_ACK from the client: the download is over

    def _on_count(self, msg: Any, mtype: int) -> list[Any]:
        if msg.count > MAX_ITEMS[mtype]:
            return [self._ack(msg, mavlink.MAV_MISSION_NO_SPACE, mtype)]
        if msg.count == 0:
            self._commit(mtype, [])
            return [self._ack(msg, mavlink.MAV_MISSION_ACCEPTED, mtype)]
        self._incoming[mtype] = []
        self._expected[mtype] = msg.count
        return [self._request(msg, 0, mtype)]

    def _on_item(self, msg: Any, mtype: int) -> list[Any]:
        got = self._incoming.get(mtype)
        if got is None:
            return []  # no upload under way
        if msg.seq != len(got):
            return [self._request(msg, len(got), mtype)]
        if msg.command in POLYGONS and msg.param1 < 3:
            self.texts.append((SEVERITY_CRITICAL, "Fence: too few vertices"))
            del self._incoming[mtype]
            return [self._ack(msg, mavlink.MAV_MISSION_INVALID_PARAM1, mtype)]
        got.append(StoredItem(msg.seq, msg.frame, msg.command, float(msg.param1), int(msg.x),
                              int(msg.y), float(msg.z)))
        if len(got) < self._expected[mtype]:
            return [self._request(msg, len(got), mtype)]
        del self._incoming[mtype]
        self._commit(mtype, got)
        return [self._ack(msg, mavlink.MAV_MISSION_ACCEPTED, mtype)]

    def _commit(self, mtype: int, items: list[StoredItem]) -> None:
        self.items[mtype] = items
        if mtype == FENCE:
            self.loaded += 1

    def load(self, home: tuple[float, float] | None, position: tuple[float, float] | None) -> None:
        """Build the zones from the stored fence (navigator's ``_updateFence``): each zone must
        contain ``home`` (lat, lon [rad], when known) and ``position`` (when the fence acts while
        armed), else it is discarded with PX4's text."""
        self.zones = []
        items = self.items[FENCE]
        k = 0
        while k < len(items):
            first = items[k]
            origin = GeoOrigin(_rad(first.x), _rad(first.y))
            if first.command in CIRCLES:
                zone = Zone(first.command, origin, ((0.0, 0.0),), first.param1)
                k += 1
            elif first.command in POLYGONS:
                n = max(1, int(first.param1))
                pts = tuple(origin.to_ned(_rad(i.x), _rad(i.y))[:2] for i in items[k:k + n])
                zone = Zone(first.command, origin, pts)
                k += n
            else:
                k += 1
                continue
            if home is not None and not zone.passes(*home):
                self.texts.append((SEVERITY_CRITICAL,
                                   "Geofence invalid, doesn't contain Home position"))
            elif position is not None and not zone.passes(*position):
                self.texts.append((SEVERITY_CRITICAL,
                                   "Geofence invalid, doesn't contain current vehicle position"))
            else:
                self.zones.append(zone)

    def inside(self, lat_rad: float, lon_rad: float) -> bool:
        """Whether a position is inside the fence (no zones: anywhere is)."""
        return all(z.passes(lat_rad, lon_rad) for z in self.zones)

    def _ack(self, msg: Any, result: int, mtype: int) -> Any:
        return mavlink.MAVLink_mission_ack_message(msg.get_srcSystem(), msg.get_srcComponent(),
                                                   result, mtype)

    def _request(self, msg: Any, seq: int, mtype: int) -> Any:
        return mavlink.MAVLink_mission_request_int_message(msg.get_srcSystem(),
                                                           msg.get_srcComponent(), seq, mtype)
