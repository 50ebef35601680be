"""Mission documents: a scenario's ``[mission]`` table or a mission file, and the bus request each
becomes. The controller validates the request again (range, waypoints, legs)."""

from __future__ import annotations

from typing import Annotated

from pydantic import Field, ValidationError, model_validator

from seaway.contract.config import ConfigModel
from seaway.contract.messages import (
    DEFAULT_CONTROLLER,
    MAX_COA_RADIUS_M,
    MAX_TASK_POWER_W,
    AreaBreachPolicy,
    AtRest,
    ControllerName,
    LowEnergyPolicy,
    MessageError,
    MissionRequest,
    Waypoint,
)
from seaway.contract.units import in_range

LatDeg = Annotated[float, in_range(-90, 90, "deg"), Field(ge=-90, le=90,
                                                          description="WGS84 latitude [deg]")]
LonDeg = Annotated[float, in_range(-180, 180, "deg"), Field(ge=-180, le=180,
                                                            description="WGS84 longitude [deg]")]


class MissionSpec(ConfigModel):
    """A mission as written in a file: a scenario's ``[mission]`` table or a mission file.

    Waypoints are local NED metres (``waypoints_m``, [[north, east], ...]) or WGS84 degrees
    (``waypoints_deg``, [[lat, lon], ...], converted by the controller through the published origin).
    """

    mission_id: str = Field(default="", max_length=64)
    waypoints_m: list[tuple[float, float]] | None = Field(default=None, min_length=2)
    waypoints_deg: list[tuple[LatDeg, LonDeg]] | None = Field(default=None, min_length=2)
    coa_radius_m: float = Field(gt=0, le=MAX_COA_RADIUS_M)
    task_power_w: Annotated[float, in_range(0, MAX_TASK_POWER_W, "W", lo_open=True)] = Field(
        gt=0, le=MAX_TASK_POWER_W, description="T^w [W], (0, 10 kW] "
        "(seaway.contract.messages.MAX_TASK_POWER_W says why)")
    controller: ControllerName = DEFAULT_CONTROLLER
    predict_disturbance: bool = Field(default=False, description="predict with the estimator's tau_d "
                                      "instead of tau_d = 0 (the paper's)")
    on_low_energy: LowEnergyPolicy = Field(default="return", description="when the energy to get "
                                           "home plus the reserve reaches what the battery has "
                                           "left: 'warn', 'return' (default) or 'hold'")
    home_m: tuple[float, float] | None = Field(default=None, description="home [north, east] in "
                                               "local NED metres; default the vessel's home")
    join_first_leg: bool = Field(default=False, description="join P_0 -> P_1 from where the vessel "
                                 "is instead of going to P_0 first")
    at_rest: AtRest = Field(default="hold", description="after the last waypoint and on pause: "
                            "'hold' station (default) or 'drift'")
    on_area_breach: AreaBreachPolicy = Field(default="hold", description="at the operating area's "
                                             "edge in flight: 'hold' (default) or 'return'")
    force: bool = Field(default=False, description="fly it although the mission check refuses it "
                        "on energy (the operator's explicit choice)")

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
        return MissionRequest.make(
            stamp_ns=stamp_ns, mission_id=self.mission_id or mission_id, waypoints=wps,
            coa_radius_m=self.coa_radius_m,
            task_power_w=self.task_power_w if task_power_w is None else task_power_w,
            controller=controller or self.controller,
            predict_disturbance=(self.predict_disturbance if predict_disturbance is None
                                 else predict_disturbance),
            on_low_energy=self.on_low_energy,
            home=None if self.home_m is None else Waypoint(x_m=self.home_m[0], y_m=self.home_m[1]),
            join_first_leg=self.join_first_leg, at_rest=self.at_rest,
            on_area_breach=self.on_area_breach, force=self.force)
