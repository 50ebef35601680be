"""The operating area (producer: the controller, the area it enforces; ``seaway.area``)."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, model_validator

from seaway.contract.messages.base import Message


class _AreaPart(BaseModel):
    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True)


class AreaVertex(_AreaPart):
    """One point of the area in local NED at the published origin."""

    x_m: float = Field(description="north of the origin [m]")
    y_m: float = Field(description="east of the origin [m]")


class AreaPolygonZone(_AreaPart):
    """A polygon: its vertices in order (closed implicitly)."""

    name: str = Field(default="", max_length=64)
    vertices: list[AreaVertex]


class AreaCircleZone(_AreaPart):
    """A circle: centre in local NED and radius."""

    name: str = Field(default="", max_length=64)
    x_m: float = Field(description="centre, north of the origin [m]")
    y_m: float = Field(description="centre, east of the origin [m]")
    radius_m: float = Field(gt=0, description="radius [m]")


class AreaRallyPoint(_AreaPart):
    """A rally point in local NED."""

    name: str = Field(default="", max_length=64)
    x_m: float = Field(description="north of the origin [m]")
    y_m: float = Field(description="east of the origin [m]")


class ActiveArea(Message):
    """The operating area the controller enforces (``seaway.area.model.OperatingArea`` on the
    bus): one keep-in polygon (None: no outer bound), keep-out polygons and circles, and rally
    points, in local NED metres at the published origin. Published when it comes into force and
    once a second after, so a recording, a report or a late ground station knows it; a message
    always holds a valid area (the same validation as ``OperatingArea``: a polygon of 3 to 100
    vertices that does not cross itself, radii > 0, rally points inside it)."""

    SCHEMA: ClassVar[str] = "seaway.v1.ActiveArea"
    since_ns: int = Field(ge=0, description="when this area came into force, on the producer's "
                          "clock [ns]: tells a re-publication from a new area")
    source: str = Field(default="", max_length=200, description="where it came from: the "
                        "scenario's name, a file, the operator")
    keep_in: AreaPolygonZone | None = None
    keep_out_polygons: list[AreaPolygonZone] = Field(default_factory=list)
    keep_out_circles: list[AreaCircleZone] = Field(default_factory=list)
    rally_points: list[AreaRallyPoint] = Field(default_factory=list)

    @model_validator(mode="after")
    def _valid_area(self) -> ActiveArea:
        from seaway.area.model import AreaError  # the domain's rules, defined once there

        try:
            self.to_area()
        except AreaError as err:
            raise ValueError(str(err).replace("\n", ";")) from None
        return self

    def to_area(self) -> Any:
        """The ``seaway.area.model.OperatingArea`` this message carries (AreaError if invalid)."""
        from seaway.area.model import OperatingArea

        def poly(z: AreaPolygonZone) -> dict[str, Any]:
            return {"name": z.name, "vertices_m": [(v.x_m, v.y_m) for v in z.vertices]}

        return OperatingArea.make(
            keep_in=None if self.keep_in is None else poly(self.keep_in),
            keep_out_polygons=[poly(z) for z in self.keep_out_polygons],
            keep_out_circles=[{"name": c.name, "center_m": (c.x_m, c.y_m), "radius_m": c.radius_m}
                              for c in self.keep_out_circles],
            rally_points=[{"name": r.name, "position_m": (r.x_m, r.y_m)} for r in self.rally_points])

    @classmethod
    def of_area(cls, area: Any, *, stamp_ns: int, since_ns: int, source: str = "") -> ActiveArea:
        """The message carrying a ``seaway.area.model.OperatingArea``."""

        def poly(z: Any) -> dict[str, Any]:
            return {"name": z.name, "vertices": [{"x_m": x, "y_m": y} for x, y in z.vertices_m]}

        return cls.make(
            stamp_ns=stamp_ns, since_ns=since_ns, source=source,
            keep_in=None if area.keep_in is None else poly(area.keep_in),
            keep_out_polygons=[poly(z) for z in area.keep_out_polygons],
            keep_out_circles=[{"name": c.name, "x_m": c.center_m[0], "y_m": c.center_m[1],
                               "radius_m": c.radius_m} for c in area.keep_out_circles],
            rally_points=[{"name": r.name, "x_m": r.position_m[0], "y_m": r.position_m[1]}
                          for r in area.rally_points])
