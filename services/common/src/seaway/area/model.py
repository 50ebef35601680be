"""A vessel's operating area in local NED metres, its validation, and the checks against it.

The area is one keep-in polygon (where the vessel may be; none: anywhere), any number of keep-out
polygons and circles (where it must not be), and rally points (where it may go to wait or return
to). Every position is (north_m, east_m) in the local NED frame at the run's origin [m]; files that
give degrees are converted at the edge (``seaway.area.files``). Boundaries are closed: the keep-in
boundary is allowed, a keep-out boundary is not.

The checks are pure: ``check_path`` (a mission's legs, from the vessel to the first waypoint on),
``check_trajectory`` (a predicted polyline, e.g. the MPC's horizon), ``check_point`` and
``margin_m`` (signed distance to the nearest boundary).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

from pydantic import Field, ValidationError, model_validator

from seaway.area import geometry as g
from seaway.contract.config import ConfigModel, describe_validation_error
from seaway.vessel.frames import MAX_RANGE_M

Point = g.Point

MAX_VERTICES = 100
"""Vertices of one polygon: enough for a shoreline traced by hand, few enough that every check of a
horizon stays cheap in a control period and that the fence fits an autopilot's fence storage."""
MAX_KEEP_OUT = 32
"""Keep-out polygons and circles, together."""
MAX_RALLY_POINTS = 32
MIN_POLYGON_AREA_M2 = 1.0
"""A polygon smaller than this is a mistake (repeated or collinear vertices), not an area."""
MAX_NAME_CHARS = 64

_Coord = tuple[float, float]


def _check_coord(p: Sequence[float], where: str) -> None:
    for axis, v in zip(("north", "east"), p, strict=True):
        if abs(v) > MAX_RANGE_M:
            raise ValueError(
                f"{where}: {axis} {v:g} m is more than {MAX_RANGE_M:g} m from the "
                "origin (allowed: within +-100 km of the run's origin on each axis)"
            )


class AreaPolygon(ConfigModel):
    """A simple polygon: 3 to ``MAX_VERTICES`` vertices in order, not intersecting itself."""

    vertices_m: tuple[_Coord, ...] = Field(
        min_length=3, max_length=MAX_VERTICES, description="[north, east] of each vertex, local NED [m]"
    )
    name: str = Field(default="", max_length=MAX_NAME_CHARS)

    @model_validator(mode="after")
    def _simple(self) -> AreaPolygon:
        vs = self.vertices_m
        for i, p in enumerate(vs):
            _check_coord(p, f"vertices_m[{i}]")
        # Named before the crossing test, which would call either of these "edges cross".
        for i in range(len(vs)):
            if vs[i] == vs[i - 1]:
                raise ValueError(
                    f"vertices_m: vertex {i} repeats vertex {(i - 1) % len(vs)}; give each corner "
                    "once (leave out a closed ring's last point, which repeats its first)")
        (n0, e0), (n1, e1) = vs[0], vs[1]
        if all(abs((n1 - n0) * (e - e0) - (e1 - e0) * (n - n0)) <= 1e-9 * (1.0 + abs(n1 - n0)
               + abs(e1 - e0)) ** 2 for n, e in vs[2:]):
            raise ValueError("vertices_m: every vertex lies on one line; a polygon encloses an area")
        crossing = g.self_intersection(self.vertices_m)
        if crossing is not None:
            i, j = crossing
            raise ValueError(
                f"vertices_m: edge {i} (vertex {i} to {(i + 1) % len(self.vertices_m)}) "
                f"and edge {j} cross; a polygon must not intersect itself (give its "
                "vertices in order around it)"
            )
        area = abs(g.polygon_area_m2(self.vertices_m))
        if area < MIN_POLYGON_AREA_M2:
            raise ValueError(
                f"vertices_m: the polygon encloses {area:.3g} m^2; at least "
                f"{MIN_POLYGON_AREA_M2:g} m^2 is required (repeated or collinear vertices?)"
            )
        return self

    def contains(self, p: Point) -> bool:
        """True if ``p`` is inside or on the boundary."""
        return g.point_in_polygon(p, self.vertices_m)


class AreaCircle(ConfigModel):
    """A circle: centre and radius (0, ``MAX_RANGE_M``]."""

    center_m: _Coord = Field(description="[north, east] of the centre, local NED [m]")
    radius_m: float = Field(gt=0, le=MAX_RANGE_M, description="radius [m], (0, 100 km]")
    name: str = Field(default="", max_length=MAX_NAME_CHARS)

    @model_validator(mode="after")
    def _in_range(self) -> AreaCircle:
        _check_coord(self.center_m, "center_m")
        return self

    def contains(self, p: Point) -> bool:
        """True if ``p`` is inside or on the circle."""
        return (p[0] - self.center_m[0]) ** 2 + (p[1] - self.center_m[1]) ** 2 <= self.radius_m**2


class RallyPoint(ConfigModel):
    """A place the vessel may go to wait or return to."""

    position_m: _Coord = Field(description="[north, east], local NED [m]")
    name: str = Field(default="", max_length=MAX_NAME_CHARS)

    @model_validator(mode="after")
    def _in_range(self) -> RallyPoint:
        _check_coord(self.position_m, "position_m")
        return self


KeepOut = AreaPolygon | AreaCircle


class AreaError(ValueError):
    """An operating area, or a point asked to be in one, that is not valid; the text names the
    field and what is allowed."""


class OperatingArea(ConfigModel):
    """One vessel's operating area in local NED metres (see the module's docstring)."""

    keep_in: AreaPolygon | None = Field(
        default=None, description="where the vessel may be; None: no outer bound"
    )
    keep_out_polygons: tuple[AreaPolygon, ...] = Field(default=(), max_length=MAX_KEEP_OUT)
    keep_out_circles: tuple[AreaCircle, ...] = Field(default=(), max_length=MAX_KEEP_OUT)
    rally_points: tuple[RallyPoint, ...] = Field(default=(), max_length=MAX_RALLY_POINTS)

    @model_validator(mode="after")
    def _consistent(self) -> OperatingArea:
        if len(self.keep_out_polygons) + len(self.keep_out_circles) > MAX_KEEP_OUT:
            raise ValueError(
                f"keep_out_polygons and keep_out_circles: "
                f"{len(self.keep_out_polygons) + len(self.keep_out_circles)} keep-out "
                f"areas, more than the {MAX_KEEP_OUT} allowed"
            )
        for i, r in enumerate(self.rally_points):
            why = self.why_not_allowed(r.position_m)
            if why is not None:
                raise ValueError(
                    f"rally_points[{i}] {r.name or ''}: {why}; a rally point must be "
                    "inside the keep-in area and outside every keep-out area"
                )
        return self

    @classmethod
    def make(cls, **fields: object) -> OperatingArea:
        """Build and validate; AreaError naming each field at fault."""
        try:
            return cls.model_validate(fields)
        except ValidationError as err:
            raise AreaError(describe_validation_error(err, "operating area")) from None

    def keep_outs(self) -> list[tuple[str, KeepOut]]:
        """Every keep-out area with its label (``keep_out_polygons[0] "pier"``), polygons first."""
        out: list[tuple[str, KeepOut]] = []
        for kind, zones in (
            ("keep_out_polygons", self.keep_out_polygons),
            ("keep_out_circles", self.keep_out_circles),
        ):
            for i, z in enumerate(zones):
                out.append((f"{kind}[{i}]" + (f" {z.name!r}" if z.name else ""), z))
        return out

    @property
    def empty(self) -> bool:
        """True if the area bounds nothing (no keep-in, no keep-out)."""
        return self.keep_in is None and not self.keep_out_polygons and not self.keep_out_circles

    def why_not_allowed(self, p: Point) -> str | None:
        """None if ``p`` is allowed, else what it breaks (outside the keep-in, inside which keep-out)."""
        breach = check_point(self, p)
        return None if breach is None else breach.what()

    def require_inside(self, p: Point, what: str) -> None:
        """AreaError naming ``what`` (e.g. "home") if ``p`` is not allowed."""
        why = self.why_not_allowed(p)
        if why is not None:
            raise AreaError(
                f"{what} at north {p[0]:.1f} m, east {p[1]:.1f} m: {why}; it must be "
                "inside the keep-in area and outside every keep-out area"
            )


def parse_area(doc: object, where: str = "operating area") -> OperatingArea:
    """Validate a document (a dict in this module's field names) as an area; AreaError naming the
    fields at fault, prefixed with ``where``."""
    if not isinstance(doc, dict):
        raise AreaError(f"{where}: expected a table/object, got {type(doc).__name__}")
    try:
        return OperatingArea.model_validate(doc)
    except ValidationError as err:
        raise AreaError(describe_validation_error(err, where)) from None


# ---------------------------------------------------------------------------------------------
# Checks
# ---------------------------------------------------------------------------------------------

BreachKind = Literal["leaves_keep_in", "enters_keep_out"]


@dataclass(frozen=True)
class Breach:
    """One way a point, a leg or a trajectory segment breaks the area.

    ``leg``: for a path, the leg (0: from the vessel to P_0; i: from P_{i-1} to P_i); for a
    trajectory, the segment k from its point k to point k+1; -1 for a single point. ``zone``:
    ``keep_in`` or the keep-out's label. ``at_m``: the first point of it outside what is allowed
    [north, east] (local NED, m)."""

    leg: int
    kind: BreachKind
    zone: str
    at_m: Point

    def what(self) -> str:
        """What is broken, without where along the path (``outside the keep-in area``)."""
        if self.kind == "leaves_keep_in":
            return "outside the keep-in area"
        return f"inside keep-out area {self.zone}"

    def describe(self, leg_name: str = "leg") -> str:
        verb = (
            "leaves the keep-in area"
            if self.kind == "leaves_keep_in"
            else f"enters keep-out area {self.zone}"
        )
        where = f"{leg_name} {self.leg} " if self.leg >= 0 else "the point "
        return f"{where}{verb} at north {self.at_m[0]:.1f} m, east {self.at_m[1]:.1f} m"


@dataclass(frozen=True)
class AreaVerdict:
    """The result of a check: ``ok``, and each breach in path order (the first of each zone)."""

    breaches: tuple[Breach, ...] = ()
    leg_name: str = "leg"

    @property
    def ok(self) -> bool:
        return not self.breaches

    @property
    def first(self) -> Breach | None:
        """The earliest breach along the path, or None."""
        return self.breaches[0] if self.breaches else None

    @property
    def reason(self) -> str:
        """One line saying what is wrong ('' when ok): each breach, the earliest first."""
        return "; ".join(b.describe(self.leg_name) for b in self.breaches)


def check_point(area: OperatingArea, p: Point) -> Breach | None:
    """The first thing ``p`` breaks (outside the keep-in, then each keep-out), or None."""
    if area.keep_in is not None and not area.keep_in.contains(p):
        return Breach(-1, "leaves_keep_in", "keep_in", (float(p[0]), float(p[1])))
    for label, zone in area.keep_outs():
        if zone.contains(p):
            return Breach(-1, "enters_keep_out", label, (float(p[0]), float(p[1])))
    return None


def check_segment(area: OperatingArea, a: Point, b: Point, leg: int = 0) -> list[Breach]:
    """Each breach of the straight segment a-b (at most one per zone), earliest first."""
    found: list[tuple[float, Breach]] = []

    def at(t: float) -> Point:
        return a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])

    if area.keep_in is not None:
        t = g.segment_leaves_polygon(a, b, area.keep_in.vertices_m)
        if t is not None:
            found.append((t, Breach(leg, "leaves_keep_in", "keep_in", at(t))))
    for label, zone in area.keep_outs():
        if isinstance(zone, AreaCircle):
            t = g.segment_enters_circle(a, b, zone.center_m, zone.radius_m)
        else:
            t = g.segment_enters_polygon(a, b, zone.vertices_m)
        if t is not None:
            found.append((t, Breach(leg, "enters_keep_out", label, at(t))))
    found.sort(key=lambda tb: tb[0])
    return [b for _, b in found]


def check_path(
    area: OperatingArea, waypoints_m: Sequence[Point], position_m: Point | None = None
) -> AreaVerdict:
    """Check a mission's path: leg 0 from the vessel at ``position_m`` to P_0 (left out when the
    position is None, e.g. at the desk), then leg i from P_{i-1} to P_i. Every breach, in path
    order; ``verdict.first.leg`` names the leg to refuse."""
    breaches: list[Breach] = []
    if position_m is not None and waypoints_m:
        breaches += check_segment(area, position_m, waypoints_m[0], 0)
    elif waypoints_m:
        point = check_point(area, waypoints_m[0])
        if point is not None:  # a lone P_0 outside: say so on leg 0's end
            breaches.append(Breach(0, point.kind, point.zone, point.at_m))
    for i in range(1, len(waypoints_m)):
        breaches += check_segment(area, waypoints_m[i - 1], waypoints_m[i], i)
    return AreaVerdict(tuple(breaches), "leg")


def check_trajectory(area: OperatingArea, points_m: Sequence[Point]) -> AreaVerdict:
    """Check a predicted trajectory (a polyline, e.g. the MPC's horizon x_0..x_N): breach ``leg``
    k is the segment from point k to point k+1. Only the first breach is returned: what a
    controller acts on."""
    if len(points_m) == 1:
        point = check_point(area, points_m[0])
        return AreaVerdict(() if point is None else (Breach(0, point.kind, point.zone, point.at_m),), "step")
    for k in range(len(points_m) - 1):
        found = check_segment(area, points_m[k], points_m[k + 1], k)
        if found:
            return AreaVerdict((found[0],), "step")
    return AreaVerdict((), "step")


def margin_m(area: OperatingArea, p: Point) -> float:
    """Signed distance from ``p`` to the nearest boundary that matters [m]: positive where the
    vessel may be (how far it may go before a boundary), negative where it may not (how far in
    the wrong side it is). +inf for an area that bounds nothing."""
    best = float("inf")
    if area.keep_in is not None:
        d = g.distance_to_polygon_boundary_m(p, area.keep_in.vertices_m)
        best = min(best, d if area.keep_in.contains(p) else -d)
    for _, zone in area.keep_outs():
        if isinstance(zone, AreaCircle):
            d = ((p[0] - zone.center_m[0]) ** 2 + (p[1] - zone.center_m[1]) ** 2) ** 0.5 - zone.radius_m
        else:
            d = g.distance_to_polygon_boundary_m(p, zone.vertices_m)
            d = -d if zone.contains(p) else d
        best = min(best, d)
    return best
