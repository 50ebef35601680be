"""Request bodies of the ground station's API and the bus messages they become (pure).

Waypoints are local NED metres (``x_m`` north, ``y_m`` east of the published origin) or WGS84
degrees (``lat_deg``, ``lon_deg``); the controller converts degrees through the origin. Every body
refuses unknown fields and non-finite numbers, so a typo is an error, not a silent default.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, field_validator, model_validator
from seaway.area.model import MAX_RANGE_M
from seaway.contract import keys
from seaway.contract.messages import (
    AreaBreachPolicy,
    ArmRequest,
    AtRest,
    CoaRadiusM,
    ControllerName,
    HomeRequest,
    LowEnergyPolicy,
    Message,
    MessageError,
    MissionCommand,
    MissionId,
    MissionOptions,
    MissionRequest,
    ModeRequest,
    ScenarioRequest,
    SpeedHintMps,
    TaskPowerW,
    Waypoint,
)
from seaway.mission_files import FILE_OPTIONS, MAX_WAYPOINTS, ImportedPath, PlanError, mission_request
from seaway.vessel.frames import GeoOrigin


class _Body(BaseModel):
    # Strict: JSON types as the schema states them (no "1" for 1, no false for 0), so what the
    # schema calls invalid is refused (the fuzz checks both ways).
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


def _refuse_nulls(data: Any) -> Any:
    """An explicit null where a value or nothing is meant is refused (the schema has no nulls)."""
    if isinstance(data, dict):
        nulls = [k for k, v in data.items() if v is None]
        if nulls:
            raise ValueError(f"{', '.join(nulls)}: null; give a value or leave it out")
    return data


MAX_DOCUMENT_DEPTH = 64
"""Deepest nesting of objects and arrays in a free-form document (a scenario, a mission file):
real ones nest a handful of levels, while the bus's serializer gives up a few hundred deep and
Python's recursion limit not much further (a 500 and a traceback, not an answer)."""


def too_deep(value: Any, path: str, max_depth: int = MAX_DOCUMENT_DEPTH) -> str | None:
    """Where in a free-form document (``path``: its name) objects and arrays nest more than
    ``max_depth`` levels, as ``path.key[index]``; None when none does. Iterative: a document too
    deep for recursion is measured, not a RecursionError."""
    stack: list[tuple[Any, str, int]] = [(value, path, 0)]
    while stack:
        node, where, depth = stack.pop()
        if not isinstance(node, dict | list):
            continue
        if depth >= max_depth:
            return where
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for k, v in items:
            if isinstance(v, dict | list):
                stack.append((v, f"{where}.{k}" if isinstance(node, dict) else f"{where}[{k}]",
                              depth + 1))
    return None


def depth_message(where: str, max_depth: int = MAX_DOCUMENT_DEPTH) -> str:
    """The refusal of a document nested too deep at ``where`` (``too_deep``'s answer; a long path
    is cut to its start, which names the branch)."""
    shown = where if len(where) <= 80 else where[:80] + "..."
    return (f"{shown}: objects and arrays nested more than {max_depth} levels deep; a document "
            f"may nest at most {max_depth} levels")


def non_finite_fields(value: Any, path: str) -> list[str]:
    """Where in a free-form document (``path``: its name) a number is NaN or infinite, as
    ``path.key[index]`` each, in document order; empty when every number is finite.
    ``allow_inf_nan=False`` checks typed fields only, and Python's JSON reads NaN, Infinity and
    1e400 as floats. Only floats are tested: an integer is finite however large (and
    ``math.isfinite`` raises OverflowError on one beyond a float's range). Iterative, so a deep
    document cannot exhaust the stack (bound its depth with ``too_deep`` first all the same)."""
    out: list[str] = []
    stack: list[tuple[Any, str]] = [(value, path)]
    while stack:
        node, where = stack.pop()
        if isinstance(node, float) and not math.isfinite(node):
            out.append(f"{where} ({node!r})")
        elif isinstance(node, dict):
            stack += [(v, f"{where}.{k}") for k, v in reversed(node.items())]
        elif isinstance(node, list):
            stack += [(v, f"{where}[{i}]") for i, v in reversed(list(enumerate(node)))]
    return out


def _one_position_pair(schema: dict[str, Any]) -> None:
    """The JSON Schema says what the validator checks: exactly one complete pair, no nulls."""
    props = schema["properties"]
    for name in ("x_m", "y_m", "lat_deg", "lon_deg"):
        number = next(s for s in props[name].pop("anyOf") if s.get("type") == "number")
        props[name].update(number)
        props[name].pop("default", None)
    schema["oneOf"] = [
        {"required": ["x_m", "y_m"], "properties": {"lat_deg": False, "lon_deg": False}},
        {"required": ["lat_deg", "lon_deg"], "properties": {"x_m": False, "y_m": False}},
    ]


class WaypointIn(_Body):
    """One waypoint: ``x_m``/``y_m`` (local NED [m]) or ``lat_deg``/``lon_deg`` (WGS84 [deg])."""

    model_config = ConfigDict(json_schema_extra=_one_position_pair)

    # Metres within MAX_RANGE_M of the origin, the operating area's bound: farther is no place a
    # vessel goes in a local frame, and an export turned 1e9 m into an ordinary-looking lat/lon.
    x_m: float | None = Field(default=None, ge=-MAX_RANGE_M, le=MAX_RANGE_M,
                              description=f"north of the origin [m], within +-{MAX_RANGE_M:g} m of it")
    y_m: float | None = Field(default=None, ge=-MAX_RANGE_M, le=MAX_RANGE_M,
                              description=f"east of the origin [m], within +-{MAX_RANGE_M:g} m of it")
    lat_deg: float | None = Field(default=None, ge=-90, le=90, description="WGS84 latitude [deg]")
    lon_deg: float | None = Field(default=None, ge=-180, le=180, description="WGS84 longitude [deg]")

    @model_validator(mode="before")
    @classmethod
    def _no_nulls(cls, data: Any) -> Any:
        return _refuse_nulls(data)

    @model_validator(mode="after")
    def _one_pair(self) -> WaypointIn:
        xy = (self.x_m is not None, self.y_m is not None)
        ll = (self.lat_deg is not None, self.lon_deg is not None)
        if any(xy) and any(ll):
            raise ValueError("give either x_m/y_m or lat_deg/lon_deg, not both")
        if xy == (True, True) or ll == (True, True):
            return self
        if any(xy):
            raise ValueError("needs both x_m and y_m")
        if any(ll):
            raise ValueError("needs both lat_deg and lon_deg")
        raise ValueError("has no position: give x_m/y_m or lat_deg/lon_deg")

    def to_waypoint(self) -> Waypoint:
        return Waypoint(x_m=self.x_m, y_m=self.y_m, lat_deg=self.lat_deg, lon_deg=self.lon_deg)


class MissionParams(MissionOptions, _Body):
    """A mission's parameters: the ``MissionOptions`` of the bus request (circle of acceptance
    r_COA, task power T^w, controller, policies), strict as every body here."""


class MissionBody(MissionParams):
    """A mission to send: at least two waypoints, in metres or degrees, and its parameters."""

    waypoints: list[WaypointIn] = Field(min_length=2, max_length=MAX_WAYPOINTS)


class ImportParams(_Body):
    """Parameters of an imported mission; each one not given is taken from the file (a plan's
    acceptance radius, a GeoJSON Feature's properties), and ``coa_radius_m`` and ``task_power_w``
    must come from one or the other."""

    # Lax: multipart form fields are text ("2.5", "true"); a JSON body is validated strictly.
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=False)

    mission_id: MissionId | None = None
    coa_radius_m: CoaRadiusM | None = None
    task_power_w: TaskPowerW | None = None
    controller: ControllerName | None = None
    predict_disturbance: bool | None = None
    speed_hint_mps: SpeedHintMps | None = None
    on_low_energy: LowEnergyPolicy | None = None
    join_first_leg: bool | None = None
    at_rest: AtRest | None = None
    on_area_breach: AreaBreachPolicy | None = None
    force: bool | None = None
    skip_unsupported: bool = Field(default=False, description="leave out items that are not "
                                   "waypoints (takeoff, loiter, survey, ...) instead of refusing")


def _shallow_document(doc: dict[str, Any]) -> dict[str, Any]:
    """A mission file's document, refused when it nests deeper than any real one (a .plan's
    complex items nest about ten levels) before a reader walks it."""
    where = too_deep(doc, "document")
    if where is not None:
        raise ValueError(depth_message(where))
    return doc


MissionDocument = Annotated[dict[str, Any], AfterValidator(_shallow_document)]


class ImportBody(ImportParams):
    """A mission file given as JSON: ``document`` is the .plan or GeoJSON object itself."""

    document: MissionDocument = Field(description="a QGroundControl .plan or a GeoJSON object")


class ParseBody(_Body):
    """A mission file to read without sending it."""

    document: MissionDocument
    skip_unsupported: bool = False


class ArmBody(_Body):
    force: bool = Field(default=False, description="arm or disarm even if the autopilot's checks fail")


class HomeBody(_Body):
    """The vessel's new home: ``"here"`` (where it is now) or a waypoint."""

    home: Literal["here"] | WaypointIn = Field(description="'here', or x_m/y_m or lat_deg/lon_deg")

    def to_request(self, stamp_ns: int) -> HomeRequest:
        home = self.home if self.home == "here" else self.home.to_waypoint()
        try:
            return HomeRequest.make(stamp_ns=stamp_ns, home=home)
        except MessageError as err:
            raise MissionBuildError(str(err)) from None


class ModeBody(_Body):
    mode: str = Field(min_length=1, max_length=32, pattern=r"^[A-Za-z0-9_]+$",
                      description="Seaway's autopilot mode name, e.g. 'MANUAL' or 'HOLD'")


def _one_of_three(schema: dict[str, Any]) -> None:
    """The JSON Schema says what the validator checks: exactly one of the three, no nulls."""
    props = schema["properties"]
    for name in ("name", "scenario"):
        props[name].update(next(s for s in props[name].pop("anyOf") if s.get("type") != "null"))
        props[name].pop("default", None)
    schema["oneOf"] = [
        {"required": ["name"], "properties": {"scenario": False, "restart": {"const": False}}},
        {"required": ["scenario"], "properties": {"name": False, "restart": {"const": False}}},
        {"required": ["restart"], "properties": {"name": False, "scenario": False,
                                                 "restart": {"const": True}}},
    ]


class ScenarioBody(_Body):
    """Load a scenario by name (``deploy/scenarios/<name>.toml``) or as a document, or restart the
    current one: exactly one of ``name``, ``scenario`` and ``restart``."""

    model_config = ConfigDict(json_schema_extra=_one_of_three)

    name: str | None = Field(default=None, pattern=r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
    scenario: dict[str, Any] | None = Field(default=None, description="a scenario document")
    restart: bool = False

    @model_validator(mode="before")
    @classmethod
    def _no_nulls(cls, data: Any) -> Any:
        return _refuse_nulls(data)

    @field_validator("scenario")
    @classmethod
    def _finite(cls, doc: dict[str, Any] | None) -> dict[str, Any] | None:
        # Depth first: the bus message cannot be encoded a few hundred levels down (a 500).
        where = too_deep(doc, "scenario")
        if where is not None:
            raise ValueError(depth_message(where))
        bad = non_finite_fields(doc, "scenario")
        if bad:
            raise ValueError(f"{', '.join(bad[:5])}: not a finite number; a scenario's numbers "
                             "must be finite (NaN and Infinity are refused)")
        return doc

    @model_validator(mode="after")
    def _exactly_one(self) -> ScenarioBody:
        given = [self.name is not None, self.scenario is not None, self.restart]
        if sum(given) != 1:
            raise ValueError("give exactly one of name, scenario and restart: true")
        return self


class MissionBuildError(ValueError):
    """Parameters that do not make a valid mission; the text names the field."""


def mission_from_body(body: MissionBody, stamp_ns: int,
                      max_waypoints: int = MAX_WAYPOINTS) -> MissionRequest:
    """The bus request for a mission body (a check's body: its mission, without ``battery_j``).
    ``max_waypoints``: this ground station's bound (``Settings.max_waypoints``); the body's own
    schema allows up to ``MAX_WAYPOINTS``, the most any ground station may be set to."""
    if len(body.waypoints) > max_waypoints:
        raise MissionBuildError(f"waypoints: {len(body.waypoints)} given, more than the "
                                f"{max_waypoints} this ground station allows (max_waypoints)")
    return _make(stamp_ns, body.mission_id, [w.to_waypoint() for w in body.waypoints],
                 body.model_dump(exclude={"mission_id", "waypoints", "battery_j"}))


def mission_from_import(path: ImportedPath, params: ImportParams, stamp_ns: int) -> MissionRequest:
    """The bus request for an imported path: ``params`` first, then the file's hints."""
    given = params.model_dump(exclude={"skip_unsupported", "document"}, exclude_none=True)
    try:
        return mission_request(path, given, stamp_ns)
    except PlanError as err:
        raise MissionBuildError(str(err)) from None


def _make(stamp_ns: int, mission_id: str, waypoints: list[Waypoint],
          params: dict[str, Any]) -> MissionRequest:
    try:
        return MissionRequest.make(stamp_ns=stamp_ns, mission_id=mission_id, waypoints=waypoints,
                                   **params)
    except MessageError as err:
        raise MissionBuildError(str(err)) from None
    except TypeError as err:  # an unexpected hint name cannot reach here; keep the text if it does
        raise MissionBuildError(str(err)) from None


class ExportError(ValueError):
    """A mission that cannot be written as lat/lon (metres with no origin known)."""


class RangeError(MissionBuildError):
    """A position in local metres farther from the NED origin than ``MAX_RANGE_M`` on an axis:
    no vessel reaches it, and through the origin it would become an ordinary-looking latitude and
    longitude somewhere else on the globe. A body's waypoints are bounded by their schema; this
    is for a mission known otherwise (the last one sent, the launcher's)."""


def check_range(wp: Waypoint, what: str) -> None:
    """Refuse ``wp`` (named ``what``) if it is in local metres beyond ``MAX_RANGE_M`` on an axis
    (the operating area's and a scenario's start's bound: a flat local frame is poor beyond)."""
    for axis, v in (("x_m", wp.x_m), ("y_m", wp.y_m)):
        if v is not None and abs(v) > MAX_RANGE_M:
            raise RangeError(f"{what}: {axis} {v:g} m is more than {MAX_RANGE_M:g} m from the NED "
                             f"origin; positions in metres must lie within +-{MAX_RANGE_M:g} m of "
                             "it on each axis (give far points as lat_deg/lon_deg)")


def mission_points_deg(waypoints: Sequence[Waypoint], origin: GeoOrigin | None) -> list[tuple[float, float]]:
    """Each waypoint as (lat_deg, lon_deg): degrees as given, metres through ``origin``.
    RangeError for metres beyond ``MAX_RANGE_M`` (``check_range``), ExportError without an origin."""
    out = []
    for i, wp in enumerate(waypoints):
        if wp.lat_deg is not None and wp.lon_deg is not None:
            out.append((wp.lat_deg, wp.lon_deg))
        elif wp.x_m is not None and wp.y_m is not None:
            check_range(wp, f"waypoint {i}")
            if origin is None:
                raise ExportError(f"waypoint {i} is in local metres and no NED origin is known for "
                                  f"this vessel yet ({keys.NAV_ORIGIN.suffix} not received)")
            lat, lon, _ = origin.to_geodetic(wp.x_m, wp.y_m, 0.0)
            out.append((math.degrees(lat), math.degrees(lon)))
        else:
            raise ExportError(f"waypoint {i} has no position")
    return out


def mission_properties(req: MissionRequest) -> dict[str, Any]:
    """The mission's options as GeoJSON properties (``FILE_OPTIONS``, read back as hints on
    import); an option the request leaves unset (None) is left out."""
    values = {o: getattr(req, o) for o in FILE_OPTIONS}
    return {o: v for o, v in values.items() if v is not None}


def command_words(msg: Message) -> str:
    """A request relayed to a vessel in a few words, as another page shows it ("mode HOLD")."""
    if isinstance(msg, ArmRequest):
        return ("arm" if msg.arm else "disarm") + (" (forced)" if msg.force else "")
    if isinstance(msg, ModeRequest):
        return f"mode {msg.mode}"
    if isinstance(msg, MissionCommand):
        return msg.command
    if isinstance(msg, MissionRequest):
        return f"mission {msg.mission_id}"
    if isinstance(msg, ScenarioRequest):
        return "restart the simulation" if msg.action == "restart" else "load a scenario"
    if isinstance(msg, HomeRequest):
        return "set home here" if msg.home == "here" else "set home"
    return type(msg).__name__
