"""Mission documents: a scenario's ``[mission]`` table or a mission file, and the bus request each
becomes. The controller validates the request again (range, waypoints, legs)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, ValidationError, model_validator

from seaway.contract.config import ConfigModel
from seaway.contract.messages import (
    MISSION_OPTIONS,
    ControllerName,
    MessageError,
    MissionOptions,
    MissionRequest,
    Waypoint,
)
from seaway.contract.units import in_range

# The Field before the check: after a validator pydantic writes ``ge`` itself into the JSON Schema.
LatDeg = Annotated[float, Field(ge=-90, le=90, description="WGS84 latitude [deg]"),
                   in_range(-90, 90, "deg")]
LonDeg = Annotated[float, Field(ge=-180, le=180, description="WGS84 longitude [deg]"),
                   in_range(-180, 180, "deg")]


class MissionSpec(MissionOptions, ConfigModel):
    """A mission as written in a file: a scenario's ``[mission]`` table or a mission file.

    Waypoints are local NED metres (``waypoints_m``, [[north, east], ...]) or WGS84 degrees
    (``waypoints_deg``, [[lat, lon], ...], converted by the controller through the published origin);
    the other fields are the ``MissionOptions`` a request carries.
    """

    waypoints_m: list[tuple[float, float]] | None = Field(default=None, min_length=2)
    waypoints_deg: list[tuple[LatDeg, LonDeg]] | None = Field(default=None, min_length=2)
    home_m: tuple[float, float] | None = Field(default=None, description="home [north, east] in "
                                               "local NED metres; default the vessel's home")

    @model_validator(mode="after")
    def _one_kind_of_waypoints(self) -> MissionSpec:
        if (self.waypoints_m is None) == (self.waypoints_deg is None):
            raise ValueError("give exactly one of waypoints_m and waypoints_deg")
        return self

    def to_request(self, stamp_ns: int, mission_id: str = "",
                   controller: ControllerName | None = None, *,
                   predict_disturbance: bool | None = None,
                   task_power_w: float | None = None) -> MissionRequest:
        """The bus request for this mission (the controller validates it again).

        ``mission_id`` names it when the mission has no id of its own. The others, when not None,
        replace the mission's own value: ``controller`` flies it with another controller,
        ``predict_disturbance`` switches the disturbance prediction on or off, ``task_power_w``
        carries another task power T^w. MessageError, naming the field and its allowed range, if
        the result is not a valid request (e.g. T^w outside (0, 10 kW]).
        """
        try:
            if self.waypoints_m is not None:
                wps = [Waypoint(x_m=x, y_m=y) for x, y in self.waypoints_m]
            else:
                wps = [Waypoint(lat_deg=a, lon_deg=b) for a, b in self.waypoints_deg or []]
        except ValidationError as err:  # a spec built without validation (model_construct)
            raise MessageError(f"MissionRequest.waypoints: {err.errors()[0]['msg']}") from None
        options = self.model_dump(include=set(MISSION_OPTIONS))
        options.update(mission_id=self.mission_id or mission_id,
                       controller=controller or self.controller)
        if predict_disturbance is not None:
            options["predict_disturbance"] = predict_disturbance
        if task_power_w is not None:
            options["task_power_w"] = task_power_w
        home = None if self.home_m is None else Waypoint(x_m=self.home_m[0], y_m=self.home_m[1])
        return MissionRequest.make(stamp_ns=stamp_ns, waypoints=wps, home=home, **options)
