"""What the ground station's API answers with: typed views of the fleet and of request outcomes.

Pydantic models only (no web framework), so the pure core builds them and the OpenAPI schema
documents them. Ages are seconds since the ground station received a message (its own monotonic
clock), not since the message's ``stamp_ns`` (which is simulated time in a simulation).
"""

from __future__ import annotations

from typing import Any, Generic, Literal, TypeVar

from pydantic import BaseModel, Field
from seaway.contract import keys
from seaway.contract.messages import (
    ActiveArea,
    BatteryState,
    EnergyBudget,
    GnssFix,
    Message,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
    VehicleStatus,
)

from seaway_groundstation.geo import GeoFrameView, MissionPlanView

M = TypeVar("M", bound=Message)


class Timed(BaseModel, Generic[M]):
    """The latest message of one kind from one vessel, with how old it is."""

    age_s: float = Field(ge=0, description="time since the ground station received it [s]")
    stale: bool = Field(description="older than the ground station's stale threshold")
    message: M


class VesselView(BaseModel):
    """One vessel as the ground station sees it: its services and the latest of each message."""

    vessel: str
    services: list[str] = Field(description="services whose health token is present now")
    simulated: bool = Field(description="a sim service runs for this vessel (scenarios can be loaded)")
    last_heard_age_s: float | None = Field(
        description="time since the last message or health change from this vessel [s]")
    stale: bool = Field(description="nothing heard for longer than the stale threshold")
    state: Timed[StateEstimate] | None = None
    vehicle: Timed[VehicleStatus] | None = None
    mission: Timed[MissionStatus] | None = None
    solve: Timed[SolveRecord] | None = Field(
        default=None, description="the controller's latest solve, with its predicted trajectory "
                                  "(predicted_x_m/predicted_y_m, local NED [m])")
    origin: Timed[NavOrigin] | None = Field(default=None, description="the local NED frame's origin")
    thrust: Timed[ThrustCommand] | None = Field(default=None, description="the controller's latest "
                                                                          "thrust command [N]")
    energy: Timed[EnergyBudget] | None = Field(
        default=None, description="the controller's energy budget of the active mission: energy "
                                  "used, to finish and to get home (with their bands), the battery "
                                  "left, reserve and margin, the point of no return (local NED [m]) "
                                  "and the decision ('none' until the margin reached 0) [J]")
    area: Timed[ActiveArea] | None = Field(
        default=None, description="the operating area the controller enforces: keep-in polygon, "
                                  "keep-out polygons and circles, rally points (local NED [m])")
    battery: Timed[BatteryState] | None = Field(
        default=None, description="the propulsion battery as the autopilot reports it: voltage, "
                                  "remaining fraction and energy, its own low/critical flag")
    gnss: Timed[GnssFix] | None = Field(default=None, description="the latest GNSS fix: fix type, "
                                        "satellites, accuracy, velocity over ground")
    last_mission: MissionRequest | None = Field(
        default=None, description="the last mission this ground station sent and the vessel accepted")
    active_mission: MissionPlanView | None = Field(
        default=None, description="the mission the vessel's status names, in local metres, when the "
                                  "ground station knows its waypoints (sent from here, or the run's)")
    geo: GeoFrameView | None = Field(
        default=None, description="the NED origin (published, else the run's) and metres per degree")


class FleetView(BaseModel):
    """Every vessel seen, from health tokens and messages."""

    stale_after_s: float = Field(description="age beyond which a message is shown as stale [s]")
    vessels: list[VesselView]
    max_vessels: int = Field(default=0, description="vessels the ground station keeps at once")
    vessels_refused: int = Field(
        default=0, description="messages and health changes dropped since start: from a vessel name "
                               "not valid, or new when there was no room (max_vessels)")
    vessels_forgotten: int = Field(
        default=0, description="vessels forgotten since start (silent, no service's health token) "
                               "to make room for a new name")


Outcome = Literal["accepted", "refused", "no_reply", "error_reply"]


class CommandNote(BaseModel):
    """A request this ground station relayed to a vessel, as every page hears it on the stream
    (kind ``command``): so each tab and client sees what another one commanded."""

    request: str = Field(description="the bus request: its key suffix, e.g. "
                                     f"{keys.VEHICLE_MODE.suffix!r}")
    what: str = Field(description="the request in a few words, e.g. 'mode HOLD', 'pause'")
    outcome: Outcome
    reason: str = ""
    client: str = Field(description="the sending page's own id (its X-Seaway-Client header; '' "
                                    "from a client without one)")
    stamp_ns: int = Field(description="when the vessel answered, Unix time [ns]")


class CommandReply(BaseModel):
    """The vessel's answer to one request: accepted, or refused with a reason a person can act on."""

    vessel: str
    request: str = Field(description="the bus request it became: its key suffix, e.g. "
                                     f"{keys.VEHICLE_ARM.suffix!r}")
    outcome: Outcome = Field(description="'accepted', 'refused' (by the service), 'no_reply' (nobody "
                                         "answered in time) or 'error_reply' (the transport failed)")
    accepted: bool
    reason: str = ""
    detail: dict[str, Any] = Field(default_factory=dict)


class MissionReply(CommandReply):
    """The answer to a mission upload, with the mission as sent."""

    mission: MissionRequest
    skipped: list[str] = Field(default_factory=list,
                               description="what of an imported file was left out: its items "
                                           "skipped (skip_unsupported), and its operating area "
                                           "(the vessel keeps to its run's)")


class ParsedMission(BaseModel):
    """A mission file read into waypoints, without sending anything."""

    source: Literal["plan", "geojson"]
    waypoints: list[dict[str, float]] = Field(description="[{lat_deg, lon_deg}, ...] in order")
    waypoints_m: list[dict[str, float]] | None = Field(
        default=None, description="[{x_m, y_m}, ...] through the NED origin of the vessel named in "
                                  "the request (None: no vessel named, or no origin known)")
    skipped: list[str] = Field(default_factory=list,
                               description="what a mission sent from the file leaves out of it: "
                                           "its items skipped (skip_unsupported), and its "
                                           "operating area (the vessel keeps to its run's)")
    hints: dict[str, Any] = Field(default_factory=dict,
                                  description="mission parameters the file states")
    speeds_mps: list[float | None] = Field(
        default_factory=list, description="each waypoint's speed from the file (a .plan's "
                                          "DO_CHANGE_SPEED, a GeoJSON speeds_mps property) [m/s], or "
                                          "[]: the controller takes the first as the mission's hint")
    area: dict[str, Any] | None = Field(
        default=None, description="the operating area and rally points the file carries (a .plan's "
                                  "geoFence and rallyPoints, GeoJSON area features), in degrees, as "
                                  "seaway.area.spec.AreaSpec writes it; None: the file has none")


class ErrorBody(BaseModel):
    """An error that is not a vessel's reply (unknown vessel, bad token, rate limit, size)."""

    detail: str


class FieldError(BaseModel):
    """One field at fault in a request (FastAPI's validation error)."""

    loc: list[str | int] = Field(description="where: body/query/path, then the field's path")
    msg: str
    type: str


class UnprocessableBody(BaseModel):
    """422: the fields at fault (a request that does not fit the schema), or one sentence for
    content the schema cannot describe (a mission file that is not a plan, a recording that does
    not read, parameters that do not make a mission)."""

    detail: list[FieldError] | str
