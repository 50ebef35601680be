"""Requests and replies (queryables)."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal, get_args

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, model_validator

from seaway.contract.messages.base import Message
from seaway.contract.messages.control import AreaBreachPolicy, AtRest, LowEnergyPolicy
from seaway.contract.units import in_range


class Reply(Message):
    """The answer to every request: accepted, or refused with a reason a person can act on."""

    SCHEMA: ClassVar[str] = "seaway.v1.Reply"
    accepted: bool
    reason: str = ""
    detail: dict[str, Any] = Field(default_factory=dict)

    @classmethod
    def accept(cls, stamp_ns: int, reason: str = "", **detail: Any) -> Reply:
        return cls.make(stamp_ns=stamp_ns, accepted=True, reason=reason, detail=detail)

    @classmethod
    def refuse(cls, stamp_ns: int, reason: str, **detail: Any) -> Reply:
        return cls.make(stamp_ns=stamp_ns, accepted=False, reason=reason, detail=detail)


class Request(Message):
    """Base of every request (a queryable's input): what it asks for changes what a service does, so
    a request says so in a required field, and an unknown field is refused rather than ignored (a
    typo, or a sender that expects something this service does not do, must not become a default
    action: ``{"stamp_ns": 1, "junk": 2}`` is no scenario restart)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True,
                              ser_json_inf_nan="constants")


class ArmRequest(Request):
    """Arm or disarm the vehicle (MAV_CMD_COMPONENT_ARM_DISARM)."""

    SCHEMA: ClassVar[str] = "seaway.v1.ArmRequest"
    arm: bool
    force: bool = False


class ModeRequest(Request):
    """Change the autopilot mode, by Seaway's mode name ('MANUAL', 'HOLD', ...)."""

    SCHEMA: ClassVar[str] = "seaway.v1.ModeRequest"
    mode: str = Field(min_length=1, max_length=32)


class ScenarioRequest(Request):
    """Load a scenario (the scenario document itself) or restart the current one."""

    SCHEMA: ClassVar[str] = "seaway.v1.ScenarioRequest"
    action: Literal["load", "restart"] = Field(description="'load' the document in 'scenario', or "
                                               "'restart' the current scenario from its start")
    scenario: dict[str, Any] | None = Field(default=None, description="the scenario document to "
                                            "load (action 'load' only)")

    @model_validator(mode="after")
    def _document_matches_action(self) -> ScenarioRequest:
        if self.action == "load" and self.scenario is None:
            raise ValueError("action 'load' needs the scenario document in 'scenario'")
        if self.action == "restart" and self.scenario is not None:
            raise ValueError("action 'restart' restarts the current scenario: leave 'scenario' out "
                             "(or use action 'load')")
        return self


BuiltinControllerName = Literal["cc-empc", "eo-empc", "nmpc"]
"""The controllers Seaway ships: the paper's CC-EMPC and its two baselines, EO-EMPC and NMPC
(section V). The one spelling of that set: the controller package registers exactly these names
(``seaway_controller.controllers`` checks it at import)."""
CONTROLLER_NAMES: tuple[BuiltinControllerName, ...] = get_args(BuiltinControllerName)
CONTROLLER_NAME_PATTERN = r"^[a-z][a-z0-9-]{0,31}$"
"""How a controller's name is spelled: lower case letters, digits and '-', starting with a letter,
at most 32 characters (it names run folders and solver files)."""
ControllerName = Annotated[str, StringConstraints(pattern=CONTROLLER_NAME_PATTERN)]
"""The controller a mission asks for: a shipped one (``CONTROLLER_NAMES``) or one a
``--controller-module`` registered (``seaway_controller.controllers.load_module``). The wire allows
any well-spelled name; the controller refuses a mission naming one it has not registered, the reply
naming those it has."""
DEFAULT_CONTROLLER: BuiltinControllerName = "cc-empc"


class Waypoint(BaseModel):
    """One waypoint: local NED metres, or WGS84 degrees converted through the published origin.

    Degrees appear here because this is a human edge (mission files, the UI); the controller converts
    them to NED before anything else sees them.
    """

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, frozen=True)
    x_m: float | None = Field(default=None, description="north of the origin [m]")
    y_m: float | None = Field(default=None, description="east of the origin [m]")
    lat_deg: Annotated[float | None, in_range(-90, 90, "deg")] = Field(default=None, ge=-90, le=90)
    lon_deg: Annotated[float | None, in_range(-180, 180, "deg")] = Field(default=None, ge=-180,
                                                                         le=180)


MAX_TASK_POWER_W = 10_000.0
"""Upper bound of a mission's task power T^w [W]. T^w is the power a payload carried by a small
surface vessel draws: the paper's 0.49 W, the lake boat's 250 W. 10 kW is far above any such
payload and above the full-thrust propulsion power of every vessel file here (4.9 kW for
paper-boat), past which the economic speed is the top speed anyway; beyond it nothing changes for
the boat, only the cost terms' scale, which at 1e300 W overflows (every step a math domain error).
The lower bound is > 0: with no task power the economic controllers' best speed is zero, and the
boat would never arrive."""


MAX_COA_RADIUS_M = 10_000.0
"""Upper bound of a mission's circle-of-acceptance radius r_COA [m]. A small surface vessel's legs
are metres to kilometres long and the mission check refuses an r_COA not under a fraction of the
shortest leg anyway; 10 km bounds what a file or a request may carry before that check, so that a
typo (or 1e308 from a plan file) is refused by name at the edge, not carried into the energy model."""

MAX_SPEED_HINT_MPS = 50.0
"""Upper bound of a mission's cruise hint [m/s] (about 97 kn): far above any small surface
vessel's top speed, which the controller's envelope caps the hint at in any case; it bounds what
a file or a request may carry."""


MissionId = Annotated[str, Field(max_length=64, description="the mission's name, at most 64 "
                                  "characters ('' for none)")]
# Each bound twice on purpose: ``Field``'s for the JSON Schema (first: after a validator pydantic
# would write ``gt`` itself into the schema), ``in_range``'s for an error that names the range.
CoaRadiusM = Annotated[float, Field(
    gt=0, le=MAX_COA_RADIUS_M, description="circle-of-acceptance radius r_COA [m], (0, 10 km]"),
    in_range(0, MAX_COA_RADIUS_M, "m", lo_open=True)]
TaskPowerW = Annotated[float, Field(
    gt=0, le=MAX_TASK_POWER_W, description="T^w, power of the task carried [W], (0, 10 kW]"),
    in_range(0, MAX_TASK_POWER_W, "W", lo_open=True)]
SpeedHintMps = Annotated[float, Field(
    gt=0, le=MAX_SPEED_HINT_MPS, description="cruise hint [m/s], (0, 50]"),
    in_range(0, MAX_SPEED_HINT_MPS, "m/s", lo_open=True)]


class MissionOptions(BaseModel):
    """What a mission asks for beside its path and home: the one declaration of these options,
    their bounds, defaults and meaning. A ``MissionRequest`` carries them on the bus, a scenario's
    ``[mission]`` table or mission file (``seaway.contract.missions.MissionSpec``) and the ground
    station's mission bodies take them from people, each with its own config on top."""

    mission_id: MissionId = ""
    coa_radius_m: CoaRadiusM
    task_power_w: TaskPowerW
    controller: ControllerName = Field(default=DEFAULT_CONTROLLER, description="who flies it: "
                                       "'cc-empc' (the paper's, default), its baselines 'eo-empc' "
                                       "and 'nmpc', or one a --controller-module registered")
    predict_disturbance: bool = Field(default=False, description="predict with the estimator's tau_d "
                                      "instead of tau_d = 0 (the paper's)")
    speed_hint_mps: SpeedHintMps | None = None
    on_low_energy: LowEnergyPolicy = Field(default="return", description="when the energy to get "
                                           "home plus the battery's reserve reaches what is left: "
                                           "'warn', 'return' home (default) or 'hold'")
    join_first_leg: bool = Field(default=False, description="join the leg P_0 -> P_1 from where the "
                                 "vessel is; by default it first goes to P_0 (into its circle of "
                                 "acceptance), as QGroundControl and ArduPilot do")
    at_rest: AtRest = Field(default="hold", description="after the last waypoint and while paused "
                            "by the operator: 'hold' station (default) or 'drift' (zero thrust)")
    on_area_breach: AreaBreachPolicy = Field(default="hold", description="when the vessel or the "
                                             "predicted course would leave the operating area: "
                                             "'hold' station there (default) or 'return' home")
    force: bool = Field(default=False, description="fly it although the mission check refuses it "
                        "on energy (the operator's explicit choice; recorded as MissionAccepted.forced)")


MISSION_OPTIONS: tuple[str, ...] = tuple(MissionOptions.model_fields)
"""The options' names, in declaration order."""


class MissionRequest(MissionOptions, Request):
    """A mission: ordered waypoints P_0..P_N and home, and its ``MissionOptions`` (circle of
    acceptance, task power T^w, controller, whether it predicts with the estimated disturbance,
    its policies)."""

    SCHEMA: ClassVar[str] = "seaway.v1.MissionRequest"
    waypoints: list[Waypoint]
    home: Waypoint | None = Field(default=None, description="where home is; default the first "
                                  "waypoint P_0")


class MissionCommand(Request):
    """Pause, resume or abort the active mission."""

    SCHEMA: ClassVar[str] = "seaway.v1.MissionCommand"
    command: Literal["pause", "resume", "abort"]


class HomeRequest(Request):
    """Set the vessel's home (``mission/home``): where the energy budget's return and an area
    breach's 'return' go, and the home of every mission that does not give its own. ``home`` is a
    waypoint (local NED metres or WGS84 degrees), or ``"here"``: where the vessel is now, as the
    estimator has it. Until set, home is where the vessel was armed."""

    SCHEMA: ClassVar[str] = "seaway.v1.HomeRequest"
    home: Waypoint | Literal["here"] = Field(description="the new home, or 'here'")


class MissionAccepted(Message):
    """The mission the controller accepted and flies (``mission/accepted``): a ``MissionRequest``
    as the controller validated it, with its waypoints in local NED metres (converted through the
    origin if they were sent in degrees) and the controller's settings it is flown with.

    Requests are queries, which a recording does not hold; this is how a report, a replay or a
    ground station that joins late learns the path actually flown. Published when the controller
    accepts a mission (a request, a resumed checkpoint, a lockstep episode restarting it), and in
    real time again once a second while it is the controller's mission, the same but for
    ``stamp_ns`` (the time of publication): ``accepted_ns`` tells a re-publication from a new
    acceptance. In lockstep it is one of the messages of the period that answers the acceptance,
    stamped with that period.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.MissionAccepted"
    accepted_ns: int = Field(ge=0, description="when the controller accepted it, on its clock "
                             "(the stamp of the period in lockstep) [ns]")
    mission_id: MissionId = ""
    waypoints: list[Waypoint] = Field(min_length=2, description="P_0..P_N in local NED metres "
                                      "(x_m, y_m) at the published origin")
    coa_radius_m: CoaRadiusM
    task_power_w: TaskPowerW
    controller: ControllerName
    predict_disturbance: bool = Field(description="flown predicting with the estimator's tau_d "
                                      "(asked by the mission or the controller's flag), else tau_d = 0")
    speed_hint_mps: SpeedHintMps | None = None
    on_low_energy: LowEnergyPolicy = Field(default="return", description="the request's policy")
    home_x_m: float | None = Field(default=None, description="home, local NED north [m]: the "
                                   "request's, or P_0 (None only in recordings made before it)")
    home_y_m: float | None = Field(default=None, description="home, local NED east [m]")
    join_first_leg: bool = Field(default=False, description="the request's: joined P_0 -> P_1 from "
                                 "where the vessel was, instead of going to P_0 first")
    at_rest: AtRest = Field(default="hold", description="the request's: 'hold' station or 'drift' "
                            "after the last waypoint and on pause")
    on_area_breach: AreaBreachPolicy = Field(default="hold", description="the request's: 'hold' "
                                             "or 'return' at the operating area's edge")
    forced: bool = Field(default=False, description="the request forced it past a refusal of the "
                         "mission check (energy)")
    resumed: bool = Field(default=False, description="re-announced by a restarted controller that "
                          "resumed it from its checkpoint: the same flight going on, not a new one")
    controller_settings: dict[Annotated[str, StringConstraints(max_length=64)], float] = Field(
        default_factory=dict, max_length=32,
        description="the controller's settings it is flown with, each named with its unit "
                    "(horizon_steps, dt_s, profile_n, ...; the NMPC's weights for nmpc)")

    @model_validator(mode="after")
    def _local_metres(self) -> MissionAccepted:
        for i, w in enumerate(self.waypoints):
            if w.x_m is None or w.y_m is None or w.lat_deg is not None or w.lon_deg is not None:
                raise ValueError(f"waypoint {i}: an accepted mission's waypoints are local x_m/y_m "
                                 "only (the controller converts degrees before it accepts)")
        return self

    def waypoints_m(self) -> list[tuple[float, float]]:
        """P_0..P_N as (x_m north, y_m east) [m]."""
        return [(float(w.x_m), float(w.y_m)) for w in self.waypoints]  # type: ignore[arg-type]


class NavResetRequest(Request):
    """Re-initialise the estimator from the next measurements."""

    SCHEMA: ClassVar[str] = "seaway.v1.NavResetRequest"
    keep_origin: bool = Field(description="keep the NED origin (positions on the bus stay in the "
                              "same frame), or forget it too (true or false: a reset says which)")
    reason: str = Field(default="", max_length=200)
