"""The operating area as files write it: TOML, QGroundControl ``.plan`` and GeoJSON.

Every format reads into an ``AreaSpec``, which keeps positions as the file gave them (local NED
metres or WGS84 degrees) and becomes an ``OperatingArea`` in local NED metres with ``to_area``
(through the run's origin when it holds degrees). Writing goes the other way: ``spec_of`` turns an
area into degrees (with an origin) or keeps metres.

* TOML (a scenario's or a vessel deployment's ``[area]`` table, or a file of its own)::

      [area]
      keep_in = { vertices_m = [[-10.0, -10.0], [35.0, -10.0], [35.0, 30.0], [-10.0, 30.0]] }
      [[area.keep_out]]                 # a polygon: vertices_m or vertices_deg ([lat, lon])
      vertices_deg = [[28.1801, 112.9401], [28.1802, 112.9401], [28.1802, 112.9402]]
      [[area.keep_out]]                 # a circle: center_m or center_deg, and radius_m
      center_m = [10.0, 9.0]
      radius_m = 3.0
      [[area.rally]]
      position_m = [0.0, 0.0]
      name = "jetty"

* QGroundControl ``.plan``: ``geoFence`` (version 2) holds ``polygons`` (``{"version": 1,
  "inclusion": bool, "polygon": [[lat, lon], ...]}``) and ``circles`` (``{"version": 1,
  "inclusion": bool, "circle": {"center": [lat, lon], "radius": m}}``); ``rallyPoints`` (version 2)
  holds ``points`` as ``[lat, lon, alt]``. One inclusion polygon becomes the keep-in area;
  exclusion polygons and circles the keep-out areas. An inclusion circle, or a second inclusion
  polygon, is refused: Seaway's keep-in area is one polygon. ``breachReturn`` is not read.
* GeoJSON (RFC 7946, ``[lon, lat]``): Features whose ``properties.area`` is ``"keep_in"`` or
  ``"keep_out"`` (a Polygon, one ring; or a Point with ``properties.radius_m`` for a circle), or
  ``"rally"`` (a Point). Features without ``area`` (e.g. the mission's LineString) are not read
  here.

Every refusal is an ``AreaError`` naming the file kind and the item at fault.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import Field, ValidationError, model_validator

from seaway.area.model import (
    MAX_KEEP_OUT,
    MAX_NAME_CHARS,
    MAX_RALLY_POINTS,
    MAX_RANGE_M,
    MAX_VERTICES,
    AreaError,
    OperatingArea,
    parse_area,
)
from seaway.contract.config import ConfigModel, describe_validation_error
from seaway.contract.missions import LatDeg, LonDeg
from seaway.vessel.frames import GeoOrigin

GEOFENCE_VERSION = 2
"""The ``geoFence`` version QGroundControl reads and writes (it ignores version 1)."""
FENCE_ITEM_VERSION = 1
"""The ``version`` of each QGroundControl fence polygon and circle."""
RALLY_VERSION = 2
"""The ``rallyPoints`` version QGroundControl reads and writes."""
RALLY_ALT_M = 0.0
"""Altitude written for a rally point [m]: a surface vessel's are at the surface."""

_Coord = tuple[float, float]
_Deg = tuple[LatDeg, LonDeg]


class ZoneSpec(ConfigModel):
    """One polygon (``vertices_m`` or ``vertices_deg``) or circle (``center_m`` or ``center_deg``
    with ``radius_m``); degrees are [lat, lon]."""

    name: str = Field(default="", max_length=MAX_NAME_CHARS)
    vertices_m: tuple[_Coord, ...] | None = Field(default=None, min_length=3, max_length=MAX_VERTICES)
    vertices_deg: tuple[_Deg, ...] | None = Field(default=None, min_length=3, max_length=MAX_VERTICES)
    center_m: _Coord | None = None
    center_deg: _Deg | None = None
    radius_m: float | None = Field(
        default=None, gt=0, le=MAX_RANGE_M, description="circle radius [m], (0, 100 km]"
    )

    @model_validator(mode="after")
    def _one_shape(self) -> ZoneSpec:
        given = [
            k
            for k in ("vertices_m", "vertices_deg", "center_m", "center_deg")
            if getattr(self, k) is not None
        ]
        if len(given) != 1:
            raise ValueError(
                "give exactly one of vertices_m, vertices_deg (a polygon), center_m, "
                f"center_deg (a circle, with radius_m); got {', '.join(given) or 'none'}"
            )
        if self.is_circle != (self.radius_m is not None):
            raise ValueError("radius_m goes with a circle (center_m or center_deg) and only with one")
        return self

    @property
    def is_circle(self) -> bool:
        return self.center_m is not None or self.center_deg is not None

    @property
    def in_degrees(self) -> bool:
        return self.vertices_deg is not None or self.center_deg is not None


class RallySpec(ConfigModel):
    """A rally point: ``position_m`` [north, east] or ``position_deg`` [lat, lon]."""

    name: str = Field(default="", max_length=MAX_NAME_CHARS)
    position_m: _Coord | None = None
    position_deg: _Deg | None = None

    @model_validator(mode="after")
    def _one_position(self) -> RallySpec:
        if (self.position_m is None) == (self.position_deg is None):
            raise ValueError("give exactly one of position_m and position_deg")
        return self


class AreaSpec(ConfigModel):
    """An operating area as a file gives it (the module's docstring shows the TOML form)."""

    keep_in: ZoneSpec | None = None
    keep_out: tuple[ZoneSpec, ...] = Field(default=(), max_length=MAX_KEEP_OUT)
    rally: tuple[RallySpec, ...] = Field(default=(), max_length=MAX_RALLY_POINTS)

    @model_validator(mode="after")
    def _keep_in_is_a_polygon(self) -> AreaSpec:
        if self.keep_in is not None and self.keep_in.is_circle:
            raise ValueError(
                "keep_in: must be a polygon (vertices_m or vertices_deg); a keep-in circle is not supported"
            )
        return self

    @property
    def in_degrees(self) -> bool:
        """True if any position is in degrees (``to_area`` then needs the origin)."""
        zones = ([self.keep_in] if self.keep_in else []) + list(self.keep_out)
        return any(z.in_degrees for z in zones) or any(r.position_deg is not None for r in self.rally)

    def to_area(self, origin: GeoOrigin | None, where: str = "area") -> OperatingArea:
        """The area in local NED metres, degrees converted through ``origin``; AreaError naming
        the field if the result is not a valid area, or if degrees come with no origin."""
        if origin is None and self.in_degrees:
            raise AreaError(
                f"{where}: positions in degrees need the run's origin to become local "
                "NED metres, and there is none here; give them in metres (_m)"
            )

        def ned(deg: Sequence[float]) -> list[float]:
            assert origin is not None
            n, e, _ = origin.to_ned(math.radians(deg[0]), math.radians(deg[1]), origin.alt_m)
            return [n, e]

        def zone(z: ZoneSpec) -> dict[str, Any]:
            out: dict[str, Any] = {"name": z.name}
            if z.is_circle:
                out["center_m"] = list(z.center_m) if z.center_m is not None else ned(z.center_deg or ())
                out["radius_m"] = z.radius_m
            else:
                out["vertices_m"] = (
                    [list(v) for v in z.vertices_m]
                    if z.vertices_m is not None
                    else [ned(v) for v in z.vertices_deg or ()]
                )
            return out

        zones = [(i, zone(z)) for i, z in enumerate(self.keep_out)]
        doc = {
            "keep_in": None if self.keep_in is None else zone(self.keep_in),
            "keep_out_polygons": [z for _, z in zones if "vertices_m" in z],
            "keep_out_circles": [z for _, z in zones if "center_m" in z],
            "rally_points": [
                {
                    "name": r.name,
                    "position_m": list(r.position_m)
                    if r.position_m is not None
                    else ned(r.position_deg or ()),
                }
                for r in self.rally
            ],
        }
        return parse_area(doc, where)


def spec_of(area: OperatingArea, origin: GeoOrigin | None = None) -> AreaSpec:
    """An area as a file writes it: in degrees through ``origin``, else in local NED metres."""

    def deg(p: Sequence[float]) -> tuple[float, float]:
        assert origin is not None
        lat, lon, _ = origin.to_geodetic(p[0], p[1], 0.0)
        return math.degrees(lat), math.degrees(lon)

    def poly(z: Any) -> ZoneSpec:
        if origin is None:
            return ZoneSpec(name=z.name, vertices_m=z.vertices_m)
        return ZoneSpec(name=z.name, vertices_deg=tuple(deg(v) for v in z.vertices_m))

    circles = [
        ZoneSpec(
            name=c.name,
            radius_m=c.radius_m,
            **({"center_m": c.center_m} if origin is None else {"center_deg": deg(c.center_m)}),
        )
        for c in area.keep_out_circles
    ]
    return AreaSpec(
        keep_in=None if area.keep_in is None else poly(area.keep_in),
        keep_out=tuple([poly(p) for p in area.keep_out_polygons] + circles),
        rally=tuple(
            RallySpec(
                name=r.name,
                **({"position_m": r.position_m} if origin is None else {"position_deg": deg(r.position_m)}),
            )
            for r in area.rally_points
        ),
    )


def parse_spec(doc: Any, where: str = "area") -> AreaSpec:
    """Validate an ``[area]`` table (TOML or JSON); AreaError naming each field at fault."""
    if not isinstance(doc, dict):
        raise AreaError(f"{where}: expected a table/object, got {type(doc).__name__}")
    try:
        return AreaSpec.model_validate(doc)
    except ValidationError as err:
        raise AreaError(describe_validation_error(err, where)) from None


# ---------------------------------------------------------------------------------------------
# TOML
# ---------------------------------------------------------------------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, float | int) and not isinstance(v, bool):
        return repr(float(v))
    return "[" + ", ".join(_toml_value(x) for x in v) + "]"


def _toml_fields(model: ConfigModel) -> list[str]:
    return [
        f"{k} = {_toml_value(v)}"
        for k, v in model.model_dump(exclude_none=True).items()
        if not (k == "name" and v == "")
    ]


def to_toml(spec: AreaSpec) -> str:
    """The ``[area]`` table (with its ``[[area.keep_out]]`` and ``[[area.rally]]``) as TOML text;
    ``tomllib`` reads it back into the same spec."""
    lines = ["[area]"]
    if spec.keep_in is not None:
        lines += ["", "[area.keep_in]", *_toml_fields(spec.keep_in)]
    for z in spec.keep_out:
        lines += ["", "[[area.keep_out]]", *_toml_fields(z)]
    for r in spec.rally:
        lines += ["", "[[area.rally]]", *_toml_fields(r)]
    return "\n".join(lines) + "\n"


def load_area_file(path: str | Path) -> AreaSpec | None:
    """An area from a file, by its suffix: ``.toml`` (its ``[area]`` table), ``.plan`` (its
    ``geoFence`` and ``rallyPoints``), ``.geojson`` or ``.json`` (GeoJSON area features). None when
    a .plan or GeoJSON file carries no area; AreaError naming the file and what is wrong."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as err:
        raise AreaError(f"{p}: cannot read: {err}") from None
    if p.suffix == ".toml":
        return from_toml(text, str(p))
    if p.suffix not in (".plan", ".geojson", ".json"):
        raise AreaError(
            f"{p}: unknown file type {p.suffix!r}; an area is read from .toml, .plan, .geojson or .json"
        )
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        raise AreaError(f"{p}: not JSON: {err.msg} at line {err.lineno} column {err.colno}") from None
    try:
        return spec_from_plan(doc) if p.suffix == ".plan" else spec_from_geojson(doc)
    except AreaError as err:
        raise AreaError(f"{p}: {err}") from None


def from_toml(text: str, where: str = "area file") -> AreaSpec:
    """Read TOML text holding an ``[area]`` table; AreaError naming what is wrong."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise AreaError(f"{where}: not valid TOML: {err}") from None
    if not isinstance(doc.get("area"), dict):
        raise AreaError(f"{where}: no [area] table")
    return parse_spec(doc["area"], f"{where} [area]")


# ---------------------------------------------------------------------------------------------
# QGroundControl .plan
# ---------------------------------------------------------------------------------------------


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise AreaError(f"{where}: expected a finite number, got {json.dumps(value)[:40]}")
    return float(value)


def _lat_lon(pos: Any, where: str, lon_first: bool = False) -> tuple[float, float]:
    if not isinstance(pos, list) or len(pos) not in (2, 3):
        form = "[lon, lat] or [lon, lat, alt]" if lon_first else "[lat, lon] or [lat, lon, alt]"
        raise AreaError(f"{where}: expected {form}, got {json.dumps(pos)[:60]}")
    lat, lon = (pos[1], pos[0]) if lon_first else (pos[0], pos[1])
    lat_deg, lon_deg = _number(lat, f"{where} latitude"), _number(lon, f"{where} longitude")
    if not -90.0 <= lat_deg <= 90.0:
        raise AreaError(f"{where}: latitude {lat_deg} deg is outside [-90, 90]")
    if not -180.0 <= lon_deg <= 180.0:
        raise AreaError(f"{where}: longitude {lon_deg} deg is outside [-180, 180]")
    return lat_deg, lon_deg


def _version(obj: dict[str, Any], expected: int, where: str) -> None:
    if obj.get("version") != expected:
        raise AreaError(
            f"{where}: version {json.dumps(obj.get('version'))} is not supported "
            f"(QGroundControl writes {expected})"
        )


def _spec(doc: dict[str, Any], where: str) -> AreaSpec:
    try:
        return AreaSpec.model_validate(doc)
    except ValidationError as err:
        raise AreaError(describe_validation_error(err, where)) from None


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
            zone = {"vertices_deg": [_lat_lon(v, f"{where} polygon[{k}]") for k, v in enumerate(vertices)]}
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
                    "center_deg": _lat_lon(circle.get("center"), f"{where} circle.center"),
                    "radius_m": _number(circle.get("radius"), f"{where} circle.radius"),
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
            {"position_deg": _lat_lon(p, f"plan rallyPoints.points[{i}]")}
            for i, p in enumerate(rally.get("points", []))
        ]
    if not (keep_in or keep_out or points):
        return None
    return _spec(
        {"keep_in": keep_in[0] if keep_in else None, "keep_out": keep_out, "rally": points},
        "plan geoFence/rallyPoints",
    )


def _require_degrees(spec: AreaSpec, what: str) -> None:
    zones = ([spec.keep_in] if spec.keep_in else []) + list(spec.keep_out)
    if any(not z.in_degrees for z in zones) or any(r.position_deg is None for r in spec.rally):
        raise AreaError(
            f"{what}: every position must be in degrees; convert the area with spec_of(area, origin) first"
        )


def plan_sections(spec: AreaSpec | None) -> tuple[dict[str, Any], dict[str, Any]]:
    """``(geoFence, rallyPoints)`` of a QGroundControl plan for an area in degrees (empty ones for
    None)."""
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    points: list[list[float]] = []
    if spec is not None:
        _require_degrees(spec, "plan geoFence")
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


# ---------------------------------------------------------------------------------------------
# GeoJSON
# ---------------------------------------------------------------------------------------------

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
    pts = [_lat_lon(p, f"{where} coordinates[0][{k}]", lon_first=True) for k, p in enumerate(ring)]
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
            pos = _lat_lon((geometry or {}).get("coordinates"), f"{where} coordinates", lon_first=True)
            if role == "rally":
                rally.append({**base, "position_deg": pos})
            else:
                keep_out.append(
                    {
                        **base,
                        "center_deg": pos,
                        "radius_m": _number(props.get("radius_m"), f"{where} properties.radius_m"),
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
    return _spec(
        {"keep_in": keep_in[0] if keep_in else None, "keep_out": keep_out, "rally": rally}, "geojson area"
    )


def geojson_features(spec: AreaSpec) -> list[dict[str, Any]]:
    """The area as GeoJSON Features (``[lon, lat]``; polygons closed as RFC 7946 asks), for a
    FeatureCollection of their own or next to a mission's LineString."""
    _require_degrees(spec, "geojson area")
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
