"""An operating area as a file gives it (``AreaSpec``: positions in metres or degrees, as
written), its TOML form, and the readers every file format shares. The formats:
``seaway.area.files``."""

from __future__ import annotations

import json
import math
import tomllib
from collections.abc import Sequence
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
from seaway.contract.units import finite_number
from seaway.vessel.frames import GeoOrigin

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


def read_number(value: Any, where: str) -> float:
    """A finite JSON number; AreaError naming ``where`` otherwise."""
    number = finite_number(value)
    if number is None:
        raise AreaError(f"{where}: expected a finite number, got {json.dumps(value)[:40]}")
    return number


def read_lat_lon(pos: Any, where: str, lon_first: bool = False) -> tuple[float, float]:
    """(lat_deg, lon_deg) of a JSON position ``[lat, lon(, alt)]`` (``[lon, lat(, alt)]`` with
    ``lon_first``, GeoJSON's order); AreaError naming ``where`` if it is not one."""
    if not isinstance(pos, list) or len(pos) not in (2, 3):
        form = "[lon, lat] or [lon, lat, alt]" if lon_first else "[lat, lon] or [lat, lon, alt]"
        raise AreaError(f"{where}: expected {form}, got {json.dumps(pos)[:60]}")
    lat, lon = (pos[1], pos[0]) if lon_first else (pos[0], pos[1])
    lat_deg, lon_deg = read_number(lat, f"{where} latitude"), read_number(lon, f"{where} longitude")
    if not -90.0 <= lat_deg <= 90.0:
        raise AreaError(f"{where}: latitude {lat_deg} deg is outside [-90, 90]")
    if not -180.0 <= lon_deg <= 180.0:
        raise AreaError(f"{where}: longitude {lon_deg} deg is outside [-180, 180]")
    return lat_deg, lon_deg


def require_degrees(spec: AreaSpec, what: str) -> None:
    """AreaError naming ``what`` unless every position of ``spec`` is in degrees."""
    zones = ([spec.keep_in] if spec.keep_in else []) + list(spec.keep_out)
    if any(not z.in_degrees for z in zones) or any(r.position_deg is None for r in spec.rally):
        raise AreaError(
            f"{what}: every position must be in degrees; convert the area with spec_of(area, origin) first"
        )


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


AREA_TABLES = ("keep_in", "keep_out", "rally")
"""The tables of an ``[area]`` (``[area.keep_in]``, ``[[area.keep_out]]``, ``[[area.rally]]``)."""


def from_toml(text: str, where: str = "area file") -> AreaSpec:
    """Read TOML text holding an ``[area]`` table; AreaError naming what is wrong."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise AreaError(f"{where}: not valid TOML: {err}") from None
    # A zone written without the "area." prefix ([[keep_out]], or [keep_in] after [area]) is a
    # table of its own that nobody reads: the file would pass with the zone silently left out.
    misplaced = [k for k in AREA_TABLES if k in doc]
    if misplaced:
        raise AreaError(f"{where}: {', '.join(misplaced)} at the top level, where it is not read; an "
                        "area's zones are [area.keep_in], [[area.keep_out]] and [[area.rally]]")
    if not isinstance(doc.get("area"), dict):
        raise AreaError(f"{where}: no [area] table")
    spec = parse_spec(doc["area"], f"{where} [area]")
    if spec.keep_in is None and not spec.keep_out:
        raise AreaError(f"{where} [area]: no zone; give [area.keep_in], [[area.keep_out]] or both "
                        "(an area file that bounds nothing is a mistake, not an area)")
    return spec
