"""Mission files from other tools: QGroundControl ``.plan`` and GeoJSON, read (the ground
station's import, ``seaway mission check``); ``seaway.mission_export`` writes them (the ground
station's export).

Pure functions over parsed JSON documents (no bus, no web framework). Both formats carry a path as
WGS84 latitude/longitude in degrees; Seaway's ``MissionRequest`` takes the same (``Waypoint.lat_deg``
/ ``lon_deg``) and the controller converts them to local NED through the published origin.

* ``.plan`` (QGroundControl's JSON plan, ``fileType: "Plan"``, mission ``version`` 2): each mission
  item is a ``SimpleItem`` with a MAVLink ``command`` and seven ``params``; a NAV_WAYPOINT (16) in a
  global frame has latitude and longitude in ``params[4]`` and ``params[5]`` [deg] and its
  acceptance radius in ``params[1]`` [m]; a DO_CHANGE_SPEED (178) sets the speed of the waypoints
  after it (``params[1]`` [m/s]). Anything else (takeoff, loiter, survey ``ComplexItem`` s) is
  refused naming the item, or skipped and listed with ``skip_unsupported``; so is a waypoint's
  hold time (``params[0]`` [s]), which Seaway does not fly (it passes through).
  Its ``geoFence`` and ``rallyPoints`` are the operating area (``seaway.area.files``); its
  ``plannedHomePosition`` is not read (the mission gives no home: the vessel's own applies).
* GeoJSON (RFC 7946): a ``LineString`` as a bare geometry, a ``Feature`` or a
  ``FeatureCollection`` with exactly one; positions are ``[lon, lat]`` or ``[lon, lat, alt]``
  (longitude first). A Feature's ``properties`` may carry Seaway's mission parameters, which an
  export writes and an import offers as defaults, and ``speeds_mps`` (one per position). A
  FeatureCollection may also carry the operating area: features whose ``properties.area`` is
  ``keep_in``, ``keep_out`` or ``rally``
  (``seaway.area.files``).

Every refusal is a ``PlanError`` whose text names the file kind and the item at fault. The text
must be UTF-8 JSON of at most ``MAX_FILE_BYTES``, each object's keys unique.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Annotated, Any, Literal, get_args, get_origin

from seaway import json_files
from seaway.area.geojson import AREA_PROPERTY, spec_from_geojson
from seaway.area.model import AreaError
from seaway.area.plan import spec_from_plan
from seaway.area.spec import AreaSpec, read_lat_lon
from seaway.contract.messages.requests import MAX_SPEED_HINT_MPS, MISSION_OPTIONS, MissionOptions
from seaway.contract.units import finite_number
from seaway.json_files import MAX_FILE_BYTES, shown

NAV_WAYPOINT = 16
"""MAV_CMD_NAV_WAYPOINT: the only mission item that becomes a Seaway waypoint."""
DO_CHANGE_SPEED = 178
"""MAV_CMD_DO_CHANGE_SPEED: the speed [m/s] in ``params[1]`` (-1: no change) holds for the
waypoints after it; read as their speed, not flown as an item."""
MAX_SPEED_MPS = MAX_SPEED_HINT_MPS
"""Bound on a speed a file may give [m/s]: a mission's speed hint's, since the first becomes it."""
MAV_CMD_NAMES: dict[int, str] = {
    16: "NAV_WAYPOINT", 17: "NAV_LOITER_UNLIM", 18: "NAV_LOITER_TURNS", 19: "NAV_LOITER_TIME",
    20: "NAV_RETURN_TO_LAUNCH", 21: "NAV_LAND", 22: "NAV_TAKEOFF", 31: "NAV_LOITER_TO_ALT",
    82: "NAV_SPLINE_WAYPOINT", 93: "NAV_DELAY", 112: "CONDITION_DELAY", 177: "DO_JUMP",
    178: "DO_CHANGE_SPEED", 179: "DO_SET_HOME", 183: "DO_SET_SERVO", 189: "DO_LAND_START",
    201: "DO_SET_ROI", 203: "DO_DIGICAM_CONTROL", 205: "DO_MOUNT_CONTROL",
    206: "DO_SET_CAM_TRIGG_DIST", 530: "SET_CAMERA_MODE", 2000: "IMAGE_START_CAPTURE",
    2001: "IMAGE_STOP_CAPTURE", 2500: "VIDEO_START_CAPTURE", 2501: "VIDEO_STOP_CAPTURE",
}
"""Names of the MAV_CMD values met in QGroundControl plans, for error messages."""
_LOITER = "; the vessel neither goes to its position nor waits there"
_SKIP_EFFECTS: dict[int, str] = {
    17: _LOITER, 18: _LOITER, 19: _LOITER, 31: _LOITER,
    177: "; its repeats are not flown: each waypoint once, in order",
    179: "; the mission gives no home (the vessel's own applies)",
}
"""What leaving out an item of these commands changes in the mission flown, said when it is."""
GLOBAL_FRAMES: dict[int, str] = {
    0: "GLOBAL", 3: "GLOBAL_RELATIVE_ALT", 5: "GLOBAL_INT", 6: "GLOBAL_RELATIVE_ALT_INT",
    10: "GLOBAL_TERRAIN_ALT", 11: "GLOBAL_TERRAIN_ALT_INT",
}
"""MAV_FRAME values whose x/y (params[4], params[5]) are WGS84 latitude/longitude [deg]."""
PLAN_MISSION_VERSION = 2
"""The mission ``version`` QGroundControl writes (items with a ``params`` array)."""
MAV_TYPE_SURFACE_BOAT = 11
MAV_AUTOPILOT_GENERIC = 0
MAX_WAYPOINTS = 1000
"""Default bound on the waypoints one file may give (the API passes its own)."""
MAX_ITEMS_PER_WAYPOINT = 10
"""Bound on a plan's mission items, per waypoint it may give: a waypoint and a few commands beside
it (speed, camera); the skipped ones are listed, one line each, in the reply."""
MissionFormat = Literal["plan", "geojson"]


class PlanError(ValueError):
    """A mission file that cannot become a mission; the text names the file kind and the item."""


class _UnsupportedError(PlanError):
    """A well-formed item of a kind Seaway does not fly: refused, or skipped on request."""


@dataclass(frozen=True)
class ImportedPath:
    """A path read from a file: WGS84 points [deg], what was skipped, and the file's own hints.

    ``hints`` holds mission parameters the file states (``coa_radius_m`` from a plan's acceptance
    radius, or a GeoJSON Feature's Seaway properties); a request's own values take precedence.
    """

    source: MissionFormat
    points_deg: tuple[tuple[float, float], ...]
    """(lat_deg, lon_deg) of each waypoint, in order."""
    skipped: tuple[str, ...] = ()
    hints: dict[str, Any] = field(default_factory=dict)
    area: AreaSpec | None = None
    """The operating area and rally points the file carries, in degrees, or None."""
    speeds_mps: tuple[float | None, ...] = ()
    """Each waypoint's speed from the file [m/s] (None: none given), or () if the file gives none.
    The controller takes one cruise hint per mission (``speed_hint_mps``: the first one given)."""


# ---------------------------------------------------------------------------------------------
# Reading
# ---------------------------------------------------------------------------------------------


def mission_request(path: ImportedPath, params: dict[str, Any], stamp_ns: int) -> Any:
    """The ``MissionRequest`` an imported path becomes: ``params`` over the file's hints, its
    points as WGS84 waypoints. PlanError naming the field when a needed one is given by neither,
    or a value is refused."""
    from seaway.contract.messages import MessageError, MissionRequest, Waypoint

    merged = {**path.hints, **params}
    for needed in ("coa_radius_m", "task_power_w"):
        if needed not in merged:
            raise PlanError(f"{needed} is required: the {path.source} file does not give it")
    mission_id = str(merged.pop("mission_id", "") or "")
    try:
        return MissionRequest.make(
            stamp_ns=stamp_ns, mission_id=mission_id,
            waypoints=[Waypoint(lat_deg=lat, lon_deg=lon) for lat, lon in path.points_deg], **merged)
    except (MessageError, TypeError) as err:
        raise PlanError(str(err)) from None


def load_json(data: bytes | str, what: str = "mission file", max_bytes: int = MAX_FILE_BYTES) -> Any:
    """``seaway.json_files.load_json`` (UTF-8, bounded, strict), its refusals as PlanError."""
    try:
        return json_files.load_json(data, what, max_bytes)
    except json_files.JsonFileError as err:
        raise PlanError(str(err)) from None


def detect_format(doc: Any) -> MissionFormat:
    """``plan`` for a QGroundControl plan, ``geojson`` for a GeoJSON object; PlanError otherwise."""
    if isinstance(doc, dict):
        if doc.get("fileType") == "Plan" or "mission" in doc:
            return "plan"
        if isinstance(doc.get("type"), str):
            return "geojson"
    raise PlanError("mission file: neither a QGroundControl plan (fileType \"Plan\") nor a GeoJSON "
                    "object (a \"type\" member)")


def parse_document(doc: Any, *, skip_unsupported: bool = False,
                   max_waypoints: int = MAX_WAYPOINTS) -> ImportedPath:
    """Read a plan or GeoJSON document, whichever it is (``detect_format``)."""
    if detect_format(doc) == "plan":
        return parse_plan(doc, skip_unsupported=skip_unsupported, max_waypoints=max_waypoints)
    return parse_geojson(doc, skip_unsupported=skip_unsupported, max_waypoints=max_waypoints)


def _lat_lon(lat: Any, lon: Any, where: str) -> tuple[float, float]:
    """(lat_deg, lon_deg), read as an area's positions are (``read_lat_lon``); PlanError if not."""
    try:
        return read_lat_lon([lat, lon], where)
    except AreaError as err:
        raise PlanError(str(err)) from None


def _check_count(kind: str, points: Sequence[tuple[float, float]], skipped: Sequence[str],
                 max_waypoints: int) -> None:
    if len(points) < 2:
        extra = f" ({len(skipped)} item(s) skipped: {'; '.join(skipped)})" if skipped else ""
        raise PlanError(f"{kind}: a mission needs at least 2 waypoints, the file gives "
                        f"{len(points)}{extra}")
    if len(points) > max_waypoints:
        raise PlanError(f"{kind}: {len(points)} waypoints, more than the {max_waypoints} allowed")


def _item_name(i: int, item: Any) -> str:
    jump = item.get("doJumpId") if isinstance(item, dict) else None
    return f"plan mission.items[{i}]" + (f" (doJumpId {jump})" if jump is not None else "")


def _plan_item(i: int, item: Any) -> tuple[float, float, float | None, float]:
    """(lat_deg, lon_deg, acceptance radius [m] or None, hold time [s]) of one NAV_WAYPOINT
    SimpleItem.

    Raises PlanError naming the item when it is anything else; ``_UnsupportedError`` when it is a
    well-formed item Seaway cannot fly (a skip candidate)."""
    name = _item_name(i, item)
    if not isinstance(item, dict):
        raise PlanError(f"{name}: expected an object, got {type(item).__name__}")
    kind = item.get("type")
    if kind == "ComplexItem":
        sort = str(item.get("complexItemType", "unknown"))[:40]
        raise _UnsupportedError(f"{name}: a ComplexItem ({sort}) is not supported; only SimpleItem "
                                "NAV_WAYPOINT (command 16) items are")
    if kind != "SimpleItem":
        raise PlanError(f"{name}: type {shown(kind)} is not a QGroundControl mission item "
                        "(SimpleItem)")
    command = item.get("command")
    if isinstance(command, bool) or not isinstance(command, int):
        raise PlanError(f"{name}: command {shown(command)} is not a MAVLink command number")
    if command != NAV_WAYPOINT:
        label = MAV_CMD_NAMES.get(command, "unknown")
        raise _UnsupportedError(f"{name}: command {command} ({label}) is not a waypoint; only NAV_WAYPOINT "
                           f"(command 16) items can be imported{_SKIP_EFFECTS.get(command, '')}")
    frame = item.get("frame")
    # a list or an object here is unhashable (a TypeError, a 500 from the API); false == 0 GLOBAL
    if isinstance(frame, bool) or not isinstance(frame, int | float) or frame not in GLOBAL_FRAMES:
        frames = ", ".join(f"{k} {v}" for k, v in GLOBAL_FRAMES.items())
        raise PlanError(f"{name}: frame {shown(frame)} has no latitude/longitude; Seaway reads "
                        f"waypoints in a global frame ({frames})")
    params = item.get("params")
    if not isinstance(params, list) or len(params) != 7:
        raise PlanError(f"{name}: params must be a list of 7 values, got {shown(params, 80)}")
    lat, lon = _lat_lon(params[4], params[5], name)
    radius_m = finite_number(params[1])
    if radius_m is None and params[1] is not None:  # null: QGroundControl's NaN, no radius given
        raise PlanError(f"{name}: acceptance radius params[1] {shown(params[1])} is not a "
                        "finite number of metres (0 or null: the autopilot's default)")
    if radius_m is not None and radius_m <= 0:
        radius_m = None  # QGroundControl writes 0 for "the autopilot's default"
    hold_s = finite_number(params[0])
    if (hold_s is None and params[0] is not None) or (hold_s is not None and hold_s < 0):
        raise PlanError(f"{name}: hold time params[0] {shown(params[0])} is not a number of "
                        "seconds >= 0 (0: pass through)")
    return lat, lon, radius_m, hold_s or 0.0


def parse_plan(doc: Any, *, skip_unsupported: bool = False,
               max_waypoints: int = MAX_WAYPOINTS) -> ImportedPath:
    """Read a QGroundControl plan: its NAV_WAYPOINT items in order, as WGS84 points [deg].

    ``skip_unsupported``: leave out items Seaway cannot fly (takeoff, loiter, speed changes,
    ComplexItems) and list them in ``skipped``, instead of refusing the file. A malformed item is
    refused either way. Hint: ``coa_radius_m`` when every waypoint gives the same acceptance radius
    (not ``cruiseSpeed``: QGroundControl writes its aircraft default there, 15 m/s).
    """
    if not isinstance(doc, dict):
        raise PlanError("plan: expected a JSON object")
    if doc.get("fileType") != "Plan":
        raise PlanError(f"plan: fileType is {shown(doc.get('fileType'))}, not \"Plan\"")
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise PlanError("plan: no mission object")
    version = mission.get("version", PLAN_MISSION_VERSION)
    if version != PLAN_MISSION_VERSION:
        raise PlanError(f"plan: mission version {shown(version)} is not supported (QGroundControl "
                        f"writes {PLAN_MISSION_VERSION})")
    items = mission.get("items")
    if not isinstance(items, list):
        raise PlanError("plan: mission.items must be a list")
    if len(items) > MAX_ITEMS_PER_WAYPOINT * max_waypoints:  # before reading (and listing) each
        raise PlanError(f"plan: {len(items)} mission items, more than the "
                        f"{MAX_ITEMS_PER_WAYPOINT * max_waypoints} allowed ({MAX_ITEMS_PER_WAYPOINT} "
                        f"per waypoint, at most {max_waypoints} waypoints)")
    points: list[tuple[float, float]] = []
    radii: list[float | None] = []
    speeds: list[float | None] = []
    speed: float | None = None
    skipped: list[str] = []
    for i, item in enumerate(items):
        if isinstance(item, dict) and item.get("type") == "SimpleItem" \
                and item.get("command") == DO_CHANGE_SPEED:
            speed = _plan_speed(i, item, speed)
            continue
        try:
            lat, lon, radius_m, hold_s = _plan_item(i, item)
        except _UnsupportedError as err:
            _skip(str(err), skip_unsupported, skipped, "to leave such items out")
            continue
        if hold_s > 0:  # flying through it is another mission than the file's: refused, or said
            _skip(f"{_item_name(i, item)}: hold time params[0] {hold_s:g} s is not flown; Seaway "
                  "passes through waypoints (0: no hold)", skip_unsupported, skipped,
                  "to fly through it")
        points.append((lat, lon))
        radii.append(radius_m)
        speeds.append(speed)
    _check_count("plan", points, skipped, max_waypoints)
    hints: dict[str, Any] = {}
    if radii and radii[0] is not None and all(r == radii[0] for r in radii):
        hints["coa_radius_m"] = radii[0]
    return ImportedPath("plan", tuple(points), tuple(skipped), _with_speed_hint(hints, speeds),
                        _area(spec_from_plan, doc), _speeds_or_none(speeds))


def _skip(msg: str, skip_unsupported: bool, skipped: list[str], how: str) -> None:
    """List ``msg`` in ``skipped`` if the caller chose ``skip_unsupported``, else refuse with it."""
    if not skip_unsupported:
        raise PlanError(f"{msg} (import with skip_unsupported {how})") from None
    skipped.append(msg)


def _plan_speed(i: int, item: dict[str, Any], before: float | None) -> float | None:
    """The speed a DO_CHANGE_SPEED item sets [m/s] (``before`` for -1, "no change")."""
    params = item.get("params")
    if not isinstance(params, list) or len(params) != 7:
        raise PlanError(f"{_item_name(i, item)} (DO_CHANGE_SPEED): params must be a list of 7 "
                        f"values, got {shown(params, 80)}")
    value = params[1]
    if value == -1:
        return before
    return _speed(value, f"{_item_name(i, item)} (DO_CHANGE_SPEED) params[1]")


def _speed(value: Any, where: str) -> float:
    number = finite_number(value)
    if number is None or not 0 < number <= MAX_SPEED_MPS:
        raise PlanError(f"{where}: speed {shown(value)} must be a number of m/s in "
                        f"(0, {MAX_SPEED_MPS:g}]")
    return number


def _speeds_or_none(speeds: list[float | None]) -> tuple[float | None, ...]:
    return tuple(speeds) if any(v is not None for v in speeds) else ()


def _with_speed_hint(hints: dict[str, Any], speeds: Sequence[float | None]) -> dict[str, Any]:
    """``hints`` with the mission's cruise hint: the file's own, else its first waypoint speed."""
    first = next((v for v in speeds if v is not None), None)
    if first is not None and "speed_hint_mps" not in hints:
        return {**hints, "speed_hint_mps": first}
    return hints


def _area(read: Any, doc: Any) -> AreaSpec | None:
    """The operating area ``read`` finds in ``doc``, its refusal as a PlanError."""
    try:
        return read(doc)
    except AreaError as err:
        raise PlanError(str(err)) from None


FILE_OPTIONS: tuple[str, ...] = tuple(o for o in MISSION_OPTIONS if o != "force")
"""The mission options a GeoJSON mission carries as Feature properties (what
``mission_export.to_geojson`` writes and an import reads back as hints): all but ``force``, which is
the operator's choice when sending, never a file's."""


def _json_types(option: str) -> tuple[type, ...]:
    """The JSON types an option's property may have: a number, true or false, or text (a name or
    a policy). ``MissionRequest`` would turn ``"yes"`` into True and ``{"x": 1}`` into a mission id,
    so the type is checked before it bounds the value."""
    annotation = MissionOptions.model_fields[option].annotation
    kind = next((a for a in get_args(annotation) if a is not type(None)), annotation)
    if get_origin(kind) is Annotated:  # an optional bounded number: its bounds are the request's
        kind = get_args(kind)[0]
    return (bool,) if kind is bool else (int, float) if kind is float else (str,)


_HINT_PROPERTIES: dict[str, tuple[type, ...]] = {o: _json_types(o) for o in FILE_OPTIONS}
"""GeoJSON Feature properties read back as mission options, and the JSON types each may have."""
SPEEDS_PROPERTY = "speeds_mps"
"""A GeoJSON Feature's per-waypoint speeds [m/s]: a list, one number or null per position."""


def _geojson_line(geometry: Any, where: str, max_waypoints: int) -> list[tuple[float, float]]:
    if not isinstance(geometry, dict):
        raise PlanError(f"{where}: expected a geometry object, got {shown(geometry, 60)}")
    if geometry.get("type") != "LineString":
        raise _UnsupportedError(f"{where}: geometry type {shown(geometry.get('type'))} is not a "
                           "LineString")
    coords = geometry.get("coordinates")
    if not isinstance(coords, list):
        raise PlanError(f"{where}: coordinates must be a list of positions")
    if len(coords) > max_waypoints:  # before reading each
        raise PlanError(f"geojson: {len(coords)} waypoints, more than the {max_waypoints} allowed")
    out = []
    for k, pos in enumerate(coords):
        if not isinstance(pos, list) or len(pos) not in (2, 3):
            raise PlanError(f"{where}: coordinates[{k}] must be [lon, lat] or [lon, lat, alt], got "
                            f"{shown(pos, 60)}")
        lon, lat = pos[0], pos[1]  # RFC 7946: longitude first
        out.append(_lat_lon(lat, lon, f"{where} coordinates[{k}]"))
    return out


def _check_crs(doc: dict[str, Any]) -> None:
    crs = doc.get("crs")
    if crs is None:
        return
    props = crs.get("properties") if isinstance(crs, dict) else None  # any JSON: not only objects
    name = str(props.get("name", "")) if isinstance(props, dict) else ""
    if not (name.endswith("CRS84") or name.endswith("4326")):
        raise PlanError(f"geojson: crs {shown(crs, 80)} is not WGS84 longitude/latitude "
                        "(RFC 7946 positions are WGS84 degrees)")


def parse_geojson(doc: Any, *, skip_unsupported: bool = False,
                  max_waypoints: int = MAX_WAYPOINTS) -> ImportedPath:
    """Read one LineString (bare, a Feature, or the only one of a FeatureCollection) as WGS84 points.

    ``skip_unsupported``: features of other geometry types in a collection (e.g. Point markers) are
    left out and listed in ``skipped`` instead of refusing the file. Hints: the Feature's Seaway
    properties (``coa_radius_m``, ``task_power_w``, ``controller``, ...).
    """
    if not isinstance(doc, dict):
        raise PlanError("geojson: expected a JSON object")
    _check_crs(doc)
    kind = doc.get("type")
    skipped: list[str] = []
    properties: Any = None
    if kind == "FeatureCollection":
        features = doc.get("features")
        if not isinstance(features, list):
            raise PlanError("geojson: FeatureCollection.features must be a list")
        lines: list[tuple[int, Any]] = []
        for i, feature in enumerate(features):
            where = f"geojson features[{i}]"
            if not isinstance(feature, dict) or feature.get("type") != "Feature":
                raise PlanError(f"{where}: not a Feature")
            geometry = feature.get("geometry")
            if isinstance(geometry, dict) and geometry.get("type") == "LineString":
                lines.append((i, feature))
                continue
            if isinstance(feature.get("properties"), dict) and AREA_PROPERTY in feature["properties"]:
                continue  # the operating area's: read below
            gtype = geometry.get("type") if isinstance(geometry, dict) else None
            msg = f"{where}: geometry type {shown(gtype)} is not a LineString"
            if not skip_unsupported:
                raise PlanError(f"{msg}; the collection must hold exactly one LineString (import "
                                "with skip_unsupported to leave other features out)")
            skipped.append(msg)
        if len(lines) != 1:
            extra = f" ({len(skipped)} skipped: {'; '.join(skipped)})"[:200] if skipped else ""
            raise PlanError(f"geojson: the FeatureCollection holds {len(lines)} LineString features "
                            f"(at {', '.join(f'features[{i}]' for i, _ in lines) or 'none'}); "
                            f"a mission is exactly one{extra}")
        i, feature = lines[0]
        points = _geojson_line(feature.get("geometry"), f"geojson features[{i}]", max_waypoints)
        properties = feature.get("properties")
    elif kind == "Feature":
        try:
            points = _geojson_line(doc.get("geometry"), "geojson Feature", max_waypoints)
        except _UnsupportedError as err:
            raise PlanError(f"{err}; a mission is one LineString") from None
        properties = doc.get("properties")
    elif kind == "LineString":
        points = _geojson_line(doc, "geojson LineString", max_waypoints)
    else:
        raise PlanError(f"geojson: type {shown(kind)} is not supported; give a LineString, a "
                        "Feature with a LineString geometry, or a FeatureCollection with one")
    _check_count("geojson", points, skipped, max_waypoints)
    if properties is not None and not isinstance(properties, dict):  # RFC 7946 3.2
        raise PlanError(f"geojson properties: expected an object or null, got {shown(properties)}")
    hints = _geojson_hints(properties)
    speeds = _geojson_speeds(properties, len(points))
    return ImportedPath("geojson", tuple(points), tuple(skipped), _with_speed_hint(hints, speeds),
                        _area(spec_from_geojson, doc), _speeds_or_none(speeds))


def _geojson_hints(properties: Any) -> dict[str, Any]:
    """A Feature's mission parameters, each of its JSON type (PlanError naming one that is not);
    their values are the ``MissionRequest``'s to bound."""
    if not isinstance(properties, dict):
        return {}
    hints: dict[str, Any] = {}
    for name, types in _HINT_PROPERTIES.items():
        value = properties.get(name)
        if value is None:
            continue
        number = float in types
        if not isinstance(value, types) or (bool not in types and isinstance(value, bool)) \
                or (number and finite_number(value) is None):
            kind = ("text" if types == (str,) else "true or false" if types == (bool,)
                    else "a finite number")
            raise PlanError(f"geojson properties.{name}: {shown(value)} is not {kind}")
        hints[name] = value
    return hints


def _geojson_speeds(properties: Any, n: int) -> list[float | None]:
    """A Feature's ``speeds_mps``: one speed [m/s] or null per position of its LineString."""
    raw = properties.get(SPEEDS_PROPERTY) if isinstance(properties, dict) else None
    if raw is None:
        return []
    if not isinstance(raw, list) or len(raw) != n:
        raise PlanError(f"geojson properties.{SPEEDS_PROPERTY}: expected a list of {n} speeds [m/s] "
                        f"or nulls, one per position, got {shown(raw, 60)}")
    return [None if v is None else _speed(v, f"geojson properties.{SPEEDS_PROPERTY}[{k}]")
            for k, v in enumerate(raw)]


def check_points(points_deg: Sequence[tuple[float, float]]) -> None:
    """PlanError naming the first waypoint whose (lat, lon) [deg] is not a WGS84 position."""
    for i, (lat, lon) in enumerate(points_deg):
        _lat_lon(lat, lon, f"waypoint {i}")
