"""What the page needs of geodesy, computed here so the page does no geodesy of its own (pure).

* ``GeoFrameView``: the local NED frame's origin and its scale at the origin (metres per degree of
  latitude and of longitude, by finite differences of ``GeoOrigin.to_ned``). The page converts the
  cursor's metres to latitude/longitude for display and places map tiles with it; over a mission
  area of a few hundred metres the linearisation is off by millimetres (d^2 / R).
* ``mission_plan``: a mission's waypoints in local metres, lat/lon ones through the origin (the
  same conversion the controller applies), for drawing the path and circles of acceptance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from pydantic import BaseModel, Field
from seaway.contract.messages import MissionRequest, NavOrigin, Waypoint
from seaway.vessel.frames import GeoOrigin

_STEP_DEG = 1e-4
"""Finite-difference step for the scale [deg] (about 11 m)."""


class GeoFrameView(BaseModel):
    """The local NED frame's origin and its scale there, for display (cursor readout, map tiles)."""

    lat0_deg: float = Field(description="origin latitude, WGS84 [deg]")
    lon0_deg: float = Field(description="origin longitude, WGS84 [deg]")
    north_m_per_deg: float = Field(description="metres north per degree of latitude at the origin")
    east_m_per_deg: float = Field(description="metres east per degree of longitude at the origin")


class MissionPlanView(BaseModel):
    """A mission as drawn on the map: its waypoints in local NED metres and its parameters."""

    mission_id: str
    waypoints_m: list[tuple[float, float]] = Field(description="[(x_m north, y_m east), ...] [m]")
    coa_radius_m: float = Field(description="circle-of-acceptance radius r_COA [m]")
    task_power_w: float
    controller: str
    predict_disturbance: bool
    source: str = Field(description="where the ground station learned it: 'groundstation' (sent "
                                    "from here), 'launcher' (the run's mission.json), 'recording'")


def geo_origin(origin: NavOrigin | None) -> GeoOrigin | None:
    return None if origin is None else GeoOrigin(origin.lat_rad, origin.lon_rad, origin.alt_m)


def frame_view(origin: GeoOrigin | None) -> GeoFrameView | None:
    """The origin and its metres per degree (None without an origin)."""
    if origin is None:
        return None
    lat0, lon0 = math.degrees(origin.lat_rad), math.degrees(origin.lon_rad)
    step = math.radians(_STEP_DEG)
    north, _, _ = origin.to_ned(origin.lat_rad + step, origin.lon_rad, origin.alt_m)
    _, east, _ = origin.to_ned(origin.lat_rad, origin.lon_rad + step, origin.alt_m)
    return GeoFrameView(lat0_deg=lat0, lon0_deg=lon0, north_m_per_deg=north / _STEP_DEG,
                        east_m_per_deg=east / _STEP_DEG)


class NoOriginError(ValueError):
    """Latitude/longitude waypoints and no NED origin to convert them with."""


def waypoints_m(waypoints: Sequence[Waypoint], origin: GeoOrigin | None) -> list[tuple[float, float]]:
    """Each waypoint in local metres: as given, or latitude/longitude through ``origin``."""
    out = []
    for i, wp in enumerate(waypoints):
        if wp.x_m is not None and wp.y_m is not None:
            out.append((wp.x_m, wp.y_m))
        elif wp.lat_deg is not None and wp.lon_deg is not None:
            if origin is None:
                raise NoOriginError(f"waypoint {i} is in latitude/longitude and no NED origin is known")
            north, east, _ = origin.to_ned(math.radians(wp.lat_deg), math.radians(wp.lon_deg),
                                           origin.alt_m)
            out.append((north, east))
        else:
            raise NoOriginError(f"waypoint {i} has no position")
    return out


def points_m(points_deg: Sequence[tuple[float, float]], origin: GeoOrigin | None
             ) -> list[tuple[float, float]] | None:
    """(lat_deg, lon_deg) points in local metres through ``origin`` (None without one)."""
    if origin is None:
        return None
    return waypoints_m([Waypoint(lat_deg=a, lon_deg=b) for a, b in points_deg], origin)


def mission_plan(req: MissionRequest, origin: GeoOrigin | None, source: str) -> MissionPlanView:
    """``req`` as drawn on the map; NoOriginError for lat/lon waypoints with no origin."""
    return MissionPlanView(mission_id=req.mission_id, waypoints_m=waypoints_m(req.waypoints, origin),
                           coa_radius_m=req.coa_radius_m, task_power_w=req.task_power_w,
                           controller=req.controller, predict_disturbance=req.predict_disturbance,
                           source=source)
