"""Writing a mission as a QGroundControl ``.plan`` or a GeoJSON Feature, with its operating area:
what the ground station's Export serves, read back by ``seaway.mission_files`` (positions in WGS84
degrees, as there)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from seaway.area.geojson import geojson_features
from seaway.area.model import AreaError
from seaway.area.plan import plan_sections
from seaway.area.spec import AreaSpec
from seaway.mission_files import (
    MAV_AUTOPILOT_GENERIC,
    MAV_TYPE_SURFACE_BOAT,
    NAV_WAYPOINT,
    PLAN_MISSION_VERSION,
    PlanError,
    check_points,
)


def to_plan(points_deg: Sequence[tuple[float, float]], *, coa_radius_m: float | None = None,
            cruise_speed_mps: float | None = None, area: AreaSpec | None = None) -> dict[str, Any]:
    """A QGroundControl plan (``fileType: "Plan"``, mission version 2) with one NAV_WAYPOINT per
    point [deg], in frame GLOBAL_RELATIVE_ALT at altitude 0 m; ``coa_radius_m`` goes into each
    item's acceptance radius (params[1]) and ``cruise_speed_mps`` into ``cruiseSpeed``; ``area``
    (in degrees) into ``geoFence`` and ``rallyPoints``."""
    check_points(points_deg)
    try:
        fence, rally = plan_sections(area)
    except AreaError as err:
        raise PlanError(str(err)) from None
    items = []
    for i, (lat, lon) in enumerate(points_deg):
        items.append({
            "AMSLAltAboveTerrain": None, "Altitude": 0, "AltitudeMode": 1, "autoContinue": True,
            "command": NAV_WAYPOINT, "doJumpId": i + 1, "frame": 3,
            "params": [0, coa_radius_m or 0, 0, None, lat, lon, 0], "type": "SimpleItem",
        })
    home = [points_deg[0][0], points_deg[0][1], 0] if points_deg else [0, 0, 0]
    return {
        "fileType": "Plan",
        "geoFence": fence,
        "groundStation": "Seaway",
        "mission": {
            "cruiseSpeed": cruise_speed_mps or 1.0, "firmwareType": MAV_AUTOPILOT_GENERIC,
            "globalPlanAltitudeMode": 1, "hoverSpeed": cruise_speed_mps or 1.0, "items": items,
            "plannedHomePosition": home, "vehicleType": MAV_TYPE_SURFACE_BOAT,
            "version": PLAN_MISSION_VERSION,
        },
        "rallyPoints": rally,
        "version": 1,
    }


def to_geojson(points_deg: Sequence[tuple[float, float]],
               properties: dict[str, Any] | None = None,
               area: AreaSpec | None = None) -> dict[str, Any]:
    """A GeoJSON Feature with one LineString of the points ([lon, lat] positions, RFC 7946) and
    ``properties`` (Seaway writes the mission's parameters there, read back as hints). With an
    ``area`` (in degrees): a FeatureCollection of that Feature and the area's features."""
    check_points(points_deg)
    line = {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [[lon, lat] for lat, lon in points_deg]},
        "properties": dict(properties or {}),
    }
    if area is None:
        return line
    try:
        return {"type": "FeatureCollection", "features": [line, *geojson_features(area)]}
    except AreaError as err:
        raise PlanError(str(err)) from None
