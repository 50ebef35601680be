"""The operating area in a QGroundControl ``.plan``: its ``geoFence`` and ``rallyPoints``, in
the layout QGroundControl writes (``seaway.area.files`` describes it)."""

from __future__ import annotations

import json
from typing import Any

from seaway.area.model import AreaError
from seaway.area.spec import AreaSpec, parse_spec, read_lat_lon, read_number, require_degrees

GEOFENCE_VERSION = 2
"""The ``geoFence`` version QGroundControl reads and writes (it ignores version 1)."""
FENCE_ITEM_VERSION = 1
"""The ``version`` of each QGroundControl fence polygon and circle."""
RALLY_VERSION = 2
"""The ``rallyPoints`` version QGroundControl reads and writes."""
RALLY_ALT_M = 0.0
"""Altitude written for a rally point [m]: a surface vessel's are at the surface."""


def _version(obj: dict[str, Any], expected: int, where: str) -> None:
    if obj.get("version") != expected:
        raise AreaError(
            f"{where}: version {json.dumps(obj.get('version'))} is not supported "
            f"(QGroundControl writes {expected})"
        )


def spec_from_plan(plan: Any) -> AreaSpec | None:
    """The ``geoFence`` and ``rallyPoints`` of a QGroundControl plan as an area in degrees, or None
    when the plan has neither (or both are empty)."""
    if not isinstance(plan, dict):
        raise AreaError("plan: expected a JSON object")
    fence, rally = plan.get("geoFence"), plan.get("rallyPoints")
    keep_in: list[dict[str, Any]] = []
    keep_out: list[dict[str, Any]] = []
    points: list[dict[str, Any]] = []
    if fence is not None:
        if not isinstance(fence, dict):
            raise AreaError("plan geoFence: expected an object")
        _version(fence, GEOFENCE_VERSION, "plan geoFence")
        for key in ("polygons", "circles"):
            if not isinstance(fence.get(key, []), list):
                raise AreaError(f"plan geoFence.{key}: expected a list")
        for i, item in enumerate(fence.get("polygons", [])):
            where = f"plan geoFence.polygons[{i}]"
            if not isinstance(item, dict):
                raise AreaError(f"{where}: expected an object")
            _version(item, FENCE_ITEM_VERSION, where)
            inclusion = item.get("inclusion")
            if not isinstance(inclusion, bool):
                raise AreaError(f"{where}: inclusion must be true or false")
            vertices = item.get("polygon")
            if not isinstance(vertices, list):
                raise AreaError(f"{where}: polygon must be a list of [lat, lon]")
            zone = {
                "vertices_deg": [read_lat_lon(v, f"{where} polygon[{k}]") for k, v in enumerate(vertices)]
            }
            (keep_in if inclusion else keep_out).append(zone)
        for i, item in enumerate(fence.get("circles", [])):
            where = f"plan geoFence.circles[{i}]"
            if not isinstance(item, dict) or not isinstance(item.get("circle"), dict):
                raise AreaError(f"{where}: expected an object with a circle object")
            _version(item, FENCE_ITEM_VERSION, where)
            if item.get("inclusion") is not False:
                raise AreaError(
                    f"{where}: an inclusion circle is not supported; Seaway's keep-in "
                    "area is one polygon (draw it as an inclusion polygon)"
                )
            circle = item["circle"]
            keep_out.append(
                {
                    "center_deg": read_lat_lon(circle.get("center"), f"{where} circle.center"),
                    "radius_m": read_number(circle.get("radius"), f"{where} circle.radius"),
                }
            )
        if len(keep_in) > 1:
            raise AreaError(
                f"plan geoFence: {len(keep_in)} inclusion polygons; Seaway's keep-in area is one polygon"
            )
    if rally is not None:
        if not isinstance(rally, dict) or not isinstance(rally.get("points", []), list):
            raise AreaError("plan rallyPoints: expected an object with a points list")
        _version(rally, RALLY_VERSION, "plan rallyPoints")
        points = [
            {"position_deg": read_lat_lon(p, f"plan rallyPoints.points[{i}]")}
            for i, p in enumerate(rally.get("points", []))
        ]
    if not (keep_in or keep_out or points):
        return None
    return parse_spec(
        {"keep_in": keep_in[0] if keep_in else None, "keep_out": keep_out, "rally": points},
        "plan geoFence/rallyPoints",
    )


def plan_sections(spec: AreaSpec | None) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(geoFence, rallyPoints)`` of a QGroundControl plan for an area in degrees (empty ones for
    None)."""
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    points: list[list[float]] = []
    if spec is not None:
        require_degrees(spec, "plan geoFence")
        zones = ([(True, spec.keep_in)] if spec.keep_in else []) + [(False, z) for z in spec.keep_out]
        for inclusion, z in zones:
            if z.is_circle:
                circles.append(
                    {
                        "circle": {"center": list(z.center_deg or ()), "radius": z.radius_m},
                        "inclusion": inclusion,
                        "version": FENCE_ITEM_VERSION,
                    }
                )
            else:
                polygons.append(
                    {
                        "inclusion": inclusion,
                        "polygon": [list(v) for v in z.vertices_deg or ()],
                        "version": FENCE_ITEM_VERSION,
                    }
                )
        points = [[*r.position_deg, RALLY_ALT_M] for r in spec.rally if r.position_deg]
    return (
        {"circles": circles, "polygons": polygons, "version": GEOFENCE_VERSION},
        {"points": points, "version": RALLY_VERSION},
    )
