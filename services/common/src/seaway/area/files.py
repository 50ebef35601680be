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

Every refusal is an ``AreaError`` naming the file kind and the item at fault. The code: ``spec``
(``AreaSpec`` and TOML), ``plan`` (``.plan``), ``geojson``; here, ``load_area_file`` reads any of
them by the file's suffix.
"""

from __future__ import annotations

from pathlib import Path

from seaway import json_files
from seaway.area.geojson import spec_from_geojson
from seaway.area.model import AreaError, OperatingArea
from seaway.area.plan import spec_from_plan
from seaway.area.spec import AreaSpec, from_toml
from seaway.contract.config import unreadable
from seaway.vessel.frames import GeoOrigin


def load_area_file(path: str | Path) -> AreaSpec | None:
    """An area from a file, by its suffix: ``.toml`` (its ``[area]`` table), ``.plan`` (its
    ``geoFence`` and ``rallyPoints``), ``.geojson`` or ``.json`` (GeoJSON area features). None when
    a .plan or GeoJSON file carries no area; AreaError naming the file and what is wrong."""
    p = Path(path)
    try:
        data = json_files.read_bytes(p)  # bounded: a file of gigabytes is refused, not read
    except OSError as err:
        raise AreaError(f"{p}: cannot read: {err}") from None
    except json_files.JsonFileError as err:
        raise AreaError(str(err)) from None
    if p.suffix == ".toml":
        try:
            return from_toml(data.decode("utf-8-sig"), str(p))
        except AreaError:
            raise
        except UnicodeDecodeError as err:
            raise AreaError(f"{p}: cannot read: {err}") from None
        except (ValueError, RecursionError) as err:  # what tomllib raises past its own checks
            raise AreaError(f"{p}: {unreadable(err)}") from None
    if p.suffix not in (".plan", ".geojson", ".json"):
        raise AreaError(
            f"{p}: unknown file type {p.suffix!r}; an area is read from .toml, .plan, .geojson or .json"
        )
    try:  # UTF-8, no NaN, no key twice: as the mission reader reads the same file
        doc = json_files.load_json(data, str(p))
    except json_files.JsonFileError as err:
        raise AreaError(str(err)) from None
    try:
        return spec_from_plan(doc) if p.suffix == ".plan" else spec_from_geojson(doc)
    except AreaError as err:
        raise AreaError(f"{p}: {err}") from None


def run_area(scenario: object | None, area_file: str | Path | None,
             origin: GeoOrigin | None) -> tuple[OperatingArea | None, str]:
    """The operating area of a run and where it came from: ``area_file`` if given (any format
    ``load_area_file`` reads; degrees through the run's ``origin``), else the run's scenario's
    ``[area]`` (a ``seaway.simkit.scenario.Scenario``), else none. AreaError naming the file."""
    if area_file is not None:
        spec = load_area_file(area_file)
        if spec is None:
            raise AreaError(f"{area_file}: carries no operating area")
        return spec.to_area(origin, str(area_file)), str(area_file)
    if scenario is not None:
        area = scenario.operating_area()  # type: ignore[attr-defined]
        if area is not None:
            return area, f"scenario {scenario.name}"  # type: ignore[attr-defined]
    return None, ""
