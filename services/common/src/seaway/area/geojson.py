"""The operating area in GeoJSON (RFC 7946): Features whose ``properties.area`` says what they
are (``seaway.area.files`` describes them)."""

from __future__ import annotations

import json
from typing import Any

from seaway.area.model import AreaError
from seaway.area.spec import AreaSpec, parse_spec, read_lat_lon, read_number, require_degrees

AREA_PROPERTY = "area"
"""The GeoJSON Feature property saying what a feature is: ``keep_in``, ``keep_out`` or ``rally``."""
_ROLES = ("keep_in", "keep_out", "rally")


def _ring(geometry: dict[str, Any], where: str) -> list[tuple[float, float]]:
    rings = geometry.get("coordinates")
    if not isinstance(rings, list) or len(rings) != 1:
        n = len(rings) if isinstance(rings, list) else "no"
        raise AreaError(
            f"{where}: a Polygon with exactly one ring is supported (holes are not), got {n} rings"
        )
    ring = rings[0]
    if not isinstance(ring, list) or len(ring) < 4:
        raise AreaError(
            f"{where}: the ring must be a list of at least 4 positions (RFC 7946: "
            "3 vertices and the first repeated last)"
        )
    pts = [read_lat_lon(p, f"{where} coordinates[0][{k}]", lon_first=True) for k, p in enumerate(ring)]
    if pts[0] != pts[-1]:
        raise AreaError(f"{where}: the ring's last position must repeat its first (RFC 7946)")
    return pts[:-1]


def spec_from_geojson(doc: Any) -> AreaSpec | None:
    """The area features of a GeoJSON Feature or FeatureCollection (see the module's docstring),
    in degrees, or None when it has none."""
    if not isinstance(doc, dict):
        raise AreaError("geojson: expected a JSON object")
    if doc.get("type") == "FeatureCollection":
        features = doc.get("features")
        if not isinstance(features, list):
            raise AreaError("geojson: FeatureCollection.features must be a list")
        named = [(f"geojson features[{i}]", f) for i, f in enumerate(features)]
    elif doc.get("type") == "Feature":
        named = [("geojson Feature", doc)]
    else:
        return None
    keep_in: list[dict[str, Any]] = []
    keep_out: list[dict[str, Any]] = []
    rally: list[dict[str, Any]] = []
    for where, feature in named:
        if not isinstance(feature, dict):
            raise AreaError(f"{where}: not a Feature")
        props = feature.get("properties") if isinstance(feature.get("properties"), dict) else {}
        role = props.get(AREA_PROPERTY)
        if role is None:
            continue
        if role not in _ROLES:
            raise AreaError(
                f"{where}: properties.{AREA_PROPERTY} {json.dumps(role)[:40]} is not one "
                f"of {', '.join(_ROLES)}"
            )
        geometry = feature.get("geometry")
        gtype = geometry.get("type") if isinstance(geometry, dict) else None
        name = props.get("name", "")
        base: dict[str, Any] = {"name": name} if isinstance(name, str) and name else {}
        if role == "rally" or (gtype == "Point" and role == "keep_out"):
            if gtype != "Point":
                raise AreaError(f"{where}: a {role} feature must be a Point, got {json.dumps(gtype)}")
            pos = read_lat_lon((geometry or {}).get("coordinates"), f"{where} coordinates", lon_first=True)
            if role == "rally":
                rally.append({**base, "position_deg": pos})
            else:
                keep_out.append(
                    {
                        **base,
                        "center_deg": pos,
                        "radius_m": read_number(props.get("radius_m"), f"{where} properties.radius_m"),
                    }
                )
            continue
        if gtype != "Polygon":
            raise AreaError(
                f"{where}: a {role} feature must be a Polygon"
                f"{' (or a Point with radius_m)' if role == 'keep_out' else ''}, got "
                f"{json.dumps(gtype)}"
            )
        zone = {**base, "vertices_deg": _ring(geometry or {}, where)}
        (keep_in if role == "keep_in" else keep_out).append(zone)
    if len(keep_in) > 1:
        raise AreaError(f"geojson: {len(keep_in)} keep_in features; an operating area has one")
    if not (keep_in or keep_out or rally):
        return None
    return parse_spec(
        {"keep_in": keep_in[0] if keep_in else None, "keep_out": keep_out, "rally": rally}, "geojson area"
    )


def geojson_features(spec: AreaSpec) -> list[dict[str, Any]]:
    """The area as GeoJSON Features (``[lon, lat]``; polygons closed as RFC 7946 asks), for a
    FeatureCollection of their own or next to a mission's LineString."""
    require_degrees(spec, "geojson area")
    out: list[dict[str, Any]] = []

    def props(role: str, name: str, **more: Any) -> dict[str, Any]:
        return {AREA_PROPERTY: role, **({"name": name} if name else {}), **more}

    zones = ([("keep_in", spec.keep_in)] if spec.keep_in else []) + [("keep_out", z) for z in spec.keep_out]
    for role, z in zones:
        if z.is_circle and z.center_deg is not None:
            lat, lon = z.center_deg
            out.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "Point", "coordinates": [lon, lat]},
                    "properties": props(role, z.name, radius_m=z.radius_m),
                }
            )
        else:
            ring = [[lon, lat] for lat, lon in z.vertices_deg or ()]
            out.append(
                {
                    "type": "Feature",
                    "geometry": {"type": "Polygon", "coordinates": [ring + ring[:1]]},
                    "properties": props(role, z.name),
                }
            )
    for r in spec.rally:
        lat, lon = r.position_deg or (0.0, 0.0)
        out.append(
            {
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [lon, lat]},
                "properties": props("rally", r.name),
            }
        )
    return out


def to_geojson(spec: AreaSpec) -> dict[str, Any]:
    """The area as a GeoJSON FeatureCollection (``geojson_features``)."""
    return {"type": "FeatureCollection", "features": geojson_features(spec)}
