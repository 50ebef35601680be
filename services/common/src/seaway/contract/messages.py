"""Every message that travels on Seaway's bus, defined once.

Wire format: UTF-8 JSON of the model's fields. The same bytes go into MCAP recordings
(``message_encoding=json``) with the JSON Schema generated from the type (``schema_encoding=jsonschema``).

Rules every type here follows (design.md, "Messages, units, frames, time"):

* a versioned schema name in ``SCHEMA`` (``seaway.v1.ThrustCommand``);
* SI units, the unit in the field name (``_m``, ``_mps``, ``_rad``, ``_radps``, ``_n``, ``_nm``, ``_w``,
  ``_j``, ``_s``, ``_ns``);
* ``stamp_ns``: nanoseconds since the Unix epoch (wall clock, live) or since the simulation epoch
  (simulation) at which the data is valid;
* world frame: local NED at the published origin (x north, y east, psi from north, clockwise);
  body frame: forward-right-down. Thruster 1 is the port (left) one, thruster 2 the starboard one, so
  that the paper's yaw moment (T1 - T2) * l is positive (clockwise from above) as NED requires;
* no NaN or infinity: refused at construction with an error that names the field; unknown is
  ``None``, which the wire form leaves out: a field that may be unknown defaults to ``None``, so
  that its absence decodes to it, and the JSON Schema names its type alone (``wire_json_schema``);
* decoding ignores unknown fields, so that an old reader survives a newer log; except requests
  (``Request``: they change what a service does), which refuse unknown fields, and each of which
  says what it asks for in a required field (``ArmRequest.arm``, ``ScenarioRequest.action``, ...).

Instances are immutable: once validated, a message cannot become non-finite.
"""

from __future__ import annotations

import json
import math
from types import UnionType
from typing import Annotated, Any, ClassVar, Literal, Self, Union, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, ValidationError, model_validator

from seaway.contract.units import in_range


class MessageError(ValueError):
    """A message could not be built, encoded or decoded; the text names the type and the field."""


def _describe(err: ValidationError, type_name: str) -> str:
    parts = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"]) or "(message)"
        msg = ("unknown field, refused (a request takes only the fields it defines)"
               if e["type"] == "extra_forbidden" else e["msg"])
        parts.append(f"{type_name}.{loc}: {msg}")
    return "; ".join(parts)


def _first_non_finite(value: Any, path: str) -> str | None:
    """Path of the first NaN or infinity inside ``value`` (a dumped model), or None."""
    if isinstance(value, float):
        return None if math.isfinite(value) else path
    if isinstance(value, dict):
        for k, v in value.items():
            found = _first_non_finite(v, f"{path}.{k}" if path else str(k))
            if found:
                return found
    if isinstance(value, list | tuple):
        for i, v in enumerate(value):
            found = _first_non_finite(v, f"{path}[{i}]")
            if found:
                return found
    return None


class Message(BaseModel):
    """Base of every bus message: immutable, finite, tolerant of unknown fields when decoded."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True, ser_json_inf_nan="constants")

    SCHEMA: ClassVar[str]
    stamp_ns: int = Field(ge=0, description="time the data is valid at [ns since epoch]")

    @classmethod
    def make(cls, **fields: Any) -> Self:
        """Build and validate; a bad field raises MessageError naming it (e.g. a NaN)."""
        try:
            return cls(**fields)
        except ValidationError as err:
            raise MessageError(_describe(err, cls.__name__)) from None

    def encode(self) -> bytes:
        """JSON bytes for the wire. Refuses non-finite numbers, naming the field.

        Instances built through the constructor are already finite; this also catches ones made with
        ``model_construct`` (which skips validation). The substring test keeps the common path cheap.
        """
        # The serializer's bytes as they are (``model_dump_json`` is them decoded to a str).
        data = self.__pydantic_serializer__.to_json(self, exclude_none=True)
        if b"NaN" in data or b"Infinity" in data:
            bad = _first_non_finite(self.model_dump(), "")
            if bad:
                raise MessageError(f"{type(self).__name__}.{bad}: not finite; publishing refused")
        return data

    @classmethod
    def decode(cls, data: bytes | bytearray | memoryview | str) -> Self:
        """Parse and validate wire bytes; raises MessageError naming what is wrong."""
        try:
            return cls.model_validate_json(bytes(data) if not isinstance(data, str) else data)
        except ValidationError as err:
            raise MessageError(_describe(err, cls.__name__)) from None

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        """JSON Schema (draft 2020-12) of the wire form, titled with the versioned schema name."""
        return wire_json_schema(cls, cls.SCHEMA)

    @classmethod
    def json_schema_text(cls) -> str:
        return json.dumps(cls.json_schema(), sort_keys=True)


def wire_json_schema(model: type[BaseModel], title: str) -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of ``model``'s wire form, where an unknown field is left out.

    pydantic names a field that may be ``None`` ``anyOf: [X, null]`` with ``default: null``; on the
    wire (``Message.encode``: ``exclude_none``) such a field is X or absent, never null, so its
    property here is X alone, and absent is allowed because it is not ``required``. A field whose
    ``None`` is not its default could not be left out: ``nullable_fields_without_default`` finds
    them (a contract test keeps that list empty). ``None`` inside a list or a map is kept as null
    and stays in the schema.
    """
    schema = model.model_json_schema(mode="serialization")
    for obj in [schema, *schema.get("$defs", {}).values()]:
        for name, prop in obj.get("properties", {}).items():
            alts = prop.get("anyOf")
            if "default" not in prop or prop["default"] is not None or not isinstance(alts, list):
                continue
            rest = [a for a in alts if a != {"type": "null"}]
            if len(rest) == len(alts):
                continue
            del prop["default"], prop["anyOf"]
            obj["properties"][name] = {**rest[0], **prop} if len(rest) == 1 else {"anyOf": rest, **prop}
    schema["title"] = title
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    return schema


def nullable_fields_without_default(model: type[BaseModel]) -> list[str]:
    """Fields of ``model`` (and of the models inside it) that admit ``None`` without defaulting to
    it: the wire form leaves ``None`` out, so such a field would not survive a round trip."""
    out: list[str] = []
    seen: set[type[BaseModel]] = set()

    def nested(ann: Any) -> list[type[BaseModel]]:
        found = [ann] if isinstance(ann, type) and issubclass(ann, BaseModel) else []
        for a in get_args(ann):
            found.extend(nested(a))
        return found

    def walk(cls: type[BaseModel], path: str) -> None:
        if cls in seen:
            return
        seen.add(cls)
        for name, field in cls.model_fields.items():
            if _admits_none(field.annotation) and (field.is_required() or field.default is not None):
                out.append(f"{path}.{name}")
            for sub in nested(field.annotation):
                walk(sub, f"{path}.{name}")

    walk(model, model.__name__)
    return out


def _admits_none(ann: Any) -> bool:
    if ann is None or ann is type(None) or ann is Any:
        return True
    origin = get_origin(ann)
    if origin is Annotated:
        return _admits_none(get_args(ann)[0])
    return origin in (Union, UnionType) and any(_admits_none(a) for a in get_args(ann))


JSON_ENCODING = "application/json"
"""Encoding of every typed message and reply on the wire; a typed topic adds its schema name after
``;`` (``message_encoding``)."""


def message_encoding(message: type[Message]) -> str:
    """The encoding a message type is published with: JSON with the versioned schema name."""
    return f"{JSON_ENCODING};{message.SCHEMA}"


# ---------------------------------------------------------------------------------------------
# Sensors (producer: vehicle_io, from the autopilot; the sim reaches the bus through vehicle_io)
# ---------------------------------------------------------------------------------------------


class GnssFix(Message):
    """GNSS fix from the autopilot. WGS84 geodetic position; velocity over ground in NED."""

    SCHEMA: ClassVar[str] = "seaway.v1.GnssFix"
    lat_rad: float = Field(ge=-math.pi / 2, le=math.pi / 2, description="WGS84 latitude [rad]")
    lon_rad: float = Field(ge=-math.pi, le=math.pi, description="WGS84 longitude [rad]")
    alt_m: float = Field(description="height above the WGS84 ellipsoid or MSL as the source says [m]")
    fix_type: int = Field(ge=0, le=8, description="MAVLink GPS_FIX_TYPE (0 none, 3 3D, 6 RTK fixed)")
    vel_n_mps: float | None = Field(default=None, description="velocity over ground, north [m/s]")
    vel_e_mps: float | None = Field(default=None, description="velocity over ground, east [m/s]")
    horizontal_std_m: float | None = Field(default=None, ge=0, description="1-sigma position [m]")
    satellites: int | None = Field(default=None, ge=0)


class Attitude(Message):
    """Vehicle attitude and body rates. Angles NED/FRD (Fossen), yaw = heading from north."""

    SCHEMA: ClassVar[str] = "seaway.v1.Attitude"
    roll_rad: float
    pitch_rad: float
    yaw_rad: float = Field(ge=-math.pi, le=math.pi, description="heading, clockwise from north [rad]")
    roll_rate_radps: float
    pitch_rate_radps: float
    yaw_rate_radps: float = Field(description="r, body z rate, positive clockwise from above [rad/s]")


class LocalPosition(Message):
    """The autopilot's own local position estimate (its NED origin, not necessarily ours)."""

    SCHEMA: ClassVar[str] = "seaway.v1.LocalPosition"
    x_m: float
    y_m: float
    z_m: float
    vx_mps: float
    vy_mps: float
    vz_mps: float


ThrustWithheld = Literal["no_link", "disarmed", "mode", "autopilot_config", "autopilot_unhealthy"]
THRUST_APPLIED_ANYWAY: frozenset[str] = frozenset({"autopilot_unhealthy"})
"""``ThrustWithheld`` values under which the autopilot still applies what is commanded: a mission
waits for them to clear, but a thrust commanded meanwhile moves the boat (the estimator predicts
with it)."""
HoldReason = Literal["gcs_mode_change", "battery", "fence", "radio_loss", "gcs_link_loss", "other"]
"""Why the autopilot took the vessel from Seaway (``VehicleStatus.hold_reason``): a mode change
nobody in Seaway asked for ('gcs_mode_change'), or the failsafe it named: 'battery', 'fence',
'radio_loss' (RC / manual control), 'gcs_link_loss' (its ground-station link), 'other' (a failsafe
it did not name, e.g. ArduPilot's EKF failsafe)."""
HOLD_REASON_TEXT: dict[str, str] = {
    "gcs_mode_change": "a mode change Seaway did not ask for (another ground station, the RC)",
    "battery": "the autopilot's battery failsafe",
    "fence": "the autopilot's geofence breach (its fence action took the vessel)",
    "radio_loss": "the autopilot's radio (RC) failsafe",
    "gcs_link_loss": "the autopilot's ground-station link failsafe",
    "other": "a failsafe the autopilot did not name",
}
"""Each HoldReason for a person (the mission's reason, the page)."""
"""Why the autopilot does not apply the commanded thrust (``VehicleStatus.thrust_withheld``)."""


AutopilotFenceState = Literal["uploading", "verified", "mismatch", "failed", "refused"]
"""Where the operating area stands as the autopilot's own fence (``AutopilotFence.state``)."""


class AutopilotFence(BaseModel):
    """The operating area as the autopilot's own fence (vehicle_io uploads it over MAVLink's
    mission protocol and sets the fence's parameters): 'uploading' (under way), 'verified' (read
    back: the items and the parameters are those meant), 'mismatch' (read back, and they differ:
    ``detail`` says where), 'failed' (the transfer got no answer or a refusal; retried), 'refused'
    (the area does not fit the autopilot, ``detail`` names the field; not retried until it
    changes)."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True)
    state: AutopilotFenceState
    detail: str = Field(default="", max_length=2000)
    area_since_ns: int = Field(ge=0, description="ActiveArea.since_ns of the area it is")
    fence_items: int = Field(ge=0, description="fence items uploaded (vertices and circles)")
    rally_points: int = Field(ge=0)
    action: str = Field(default="", max_length=200,
                        description="the fence parameters set, e.g. 'FENCE_ACTION=2 (Hold)'")


class VehicleStatus(Message):
    """Link, arming, mode, failsafe and battery state of the autopilot as vehicle_io sees it."""

    SCHEMA: ClassVar[str] = "seaway.v1.VehicleStatus"
    autopilot: str = Field(description="'px4', 'ardupilot' or 'unknown'")
    link_ok: bool
    armed: bool
    mode: str = Field(description="autopilot mode name, e.g. 'MANUAL'")
    failsafe: str | None = Field(default=None, description="active failsafe, e.g. 'thrust_stale'")
    battery_voltage_v: float | None = None
    battery_remaining_frac: float | None = Field(default=None, ge=0, le=1)
    heartbeat_age_s: float | None = Field(default=None, ge=0)
    rates_hz: dict[str, float] = Field(default_factory=dict, description="received MAVLink rates")
    dropped_messages: int = Field(default=0, ge=0, description="malformed MAVLink messages dropped")
    refused_messages: dict[str, int] = Field(
        default_factory=dict,
        description="MAVLink messages refused, by reason: 'foreign_source' (not the autopilot the "
                    "link is locked to), 'unsigned', 'bad_signature', 'replayed' (signing on)")
    refused_thrust: dict[str, int] = Field(
        default_factory=dict,
        description="ThrustCommands refused before the autopilot, by reason: 'absurd' (beyond twice "
                    "the vessel's thrust bounds), 'stamp_ahead', 'stamp_behind' (seaway.runtime.stamps)")
    autopilot_loss_failsafe: Literal["stops", "takes_over", "none", "unknown"] | None = Field(
        default=None,
        description="what the autopilot does if vehicle_io stops streaming commands, judged from its "
                    "parameters at connection; None until they have been read")
    autopilot_loss_failsafe_summary: str = Field(
        default="", description="the parameters and the action behind that verdict, one line")
    telemetry_rates_short: dict[str, float] | None = Field(
        default=None,
        description="each telemetry message vehicle_io asked for that arrives below its requested "
                    "rate, with the rate measured [Hz]: from the rate check at connection, after a "
                    "reboot or a drop, and kept up to date after it (cleared when the rates "
                    "recover); {} all arrive at their rates; None not checked (yet, or the "
                    "autopilot is not asked)")
    hold_reason: HoldReason | None = Field(
        default=None,
        description="why the autopilot took the vessel from Seaway (HoldReason), decoded from its "
                    "HEARTBEAT, SYS_STATUS, STATUSTEXT and EVENTs; stands until Seaway's own mode "
                    "request is accepted with no failsafe condition left; None: none")
    hold_reason_detail: str = Field(
        default="", description="the autopilot's own words (or the bit) behind hold_reason")
    thrust_withheld: ThrustWithheld | None = Field(
        default=None,
        description="why the commanded thrust does not reach the thrusters now, whatever the "
                    "controller commands: 'no_link' (no autopilot), 'disarmed', 'mode' (a mode in "
                    "which manual control does not drive the thrusters, e.g. HOLD after a "
                    "failsafe), 'autopilot_config' (vehicle_io sends neutral only), "
                    "'autopilot_unhealthy' (armed and in a thrust mode, but the autopilot says it is "
                    "not fit to start a mission: its estimator not using GNSS, a critical status; "
                    "what, in autopilot_unhealthy_detail); None: it does")
    autopilot_unhealthy_detail: str = Field(
        default="", description="what the autopilot lacks to be healthy, in its own terms (the "
                                "HEARTBEAT system_status, SYS_STATUS sensor bits, its estimator's "
                                "flags); '' healthy, or not said")
    failsafe_latched: HoldReason | None = Field(
        default=None,
        description="a failsafe the autopilot still stands in (HoldReason), whatever its mode: its "
                    "health bit for it still unhealthy, or its battery flag low or worse (ArduPilot "
                    "keeps a battery failsafe until reboot); a mission is not resumed onto it; None: none")
    failsafe_latched_detail: str = Field(
        default="", description="the autopilot's words (or the bit) behind failsafe_latched")
    autopilot_fence: AutopilotFence | None = Field(
        default=None, description="the operating area as the autopilot's own fence; None: no "
                                  "area heard, no origin, or not uploaded (autopilot_fence off)")


BatterySource = Literal["autopilot", "sim"]
BatteryLevel = Literal["ok", "low", "critical", "emergency", "failed", "unhealthy", "charging"]
"""The autopilot's own judgement of its battery: MAVLink MAV_BATTERY_CHARGE_STATE (BATTERY_STATUS
``charge_state``), or what it said in STATUSTEXT ("Battery 1 is low"), whichever is worse."""
"""Who measured a ``BatteryState``: the autopilot's battery monitor (through vehicle_io; also the
MAVLink-speaking simulator), or the lockstep simulator itself."""


class BatteryState(Message):
    """The propulsion battery as the autopilot (or the lockstep simulator) reports it, in SI units.

    Measured figures (voltage, current, energy drawn) are the autopilot's; the energies it does not
    report are completed from the vessel file's ``[battery]`` (``seaway.vessel.battery``):
    ``remaining_j`` = remaining fraction x usable energy when the autopilot gives a fraction, else
    usable energy - energy drawn. None: neither the autopilot nor the vessel file says.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.BatteryState"
    source: BatterySource
    voltage_v: float | None = Field(default=None, ge=0, description="pack voltage [V]")
    current_a: float | None = Field(default=None, description="current drawn [A], positive discharging")
    power_w: float | None = Field(default=None, description="power drawn [W]: voltage x current "
                                  "where the autopilot measures both")
    consumed_j: float | None = Field(default=None, ge=0, description="energy drawn since the pack "
                                     "was full (or the autopilot's count started) [J]")
    remaining_j: float | None = Field(default=None, ge=0, description="usable energy left [J]")
    remaining_frac: float | None = Field(default=None, ge=0, le=1,
                                         description="remaining_j over the usable energy")
    capacity_j: float | None = Field(default=None, gt=0, description="usable energy full to empty [J]")
    reserve_j: float | None = Field(default=None, ge=0, description="what a return home must leave [J]")
    autopilot_level: BatteryLevel | None = Field(
        default=None,
        description="the autopilot's own low/critical flag (BatteryLevel): BATTERY_STATUS "
                    "charge_state, raised by its battery STATUSTEXT; None: it says nothing")
    autopilot_level_detail: str = Field(
        default="", description="the autopilot's battery text behind autopilot_level, if any")


# ---------------------------------------------------------------------------------------------
# Navigation (producer: estimator)
# ---------------------------------------------------------------------------------------------


class NavOrigin(Message):
    """Geodetic origin of the local NED frame every position on the bus is expressed in."""

    SCHEMA: ClassVar[str] = "seaway.v1.NavOrigin"
    lat_rad: float = Field(ge=-math.pi / 2, le=math.pi / 2)
    lon_rad: float = Field(ge=-math.pi, le=math.pi)
    alt_m: float


MAX_REASON_CHARS = 300
"""Longest ``MissionStatus.reason`` (and ``StateEstimate.motion_fault_detail``)."""


MotionFaultKind = Literal["not_moving", "not_as_modelled"]
"""A persistent disagreement between what the commanded thrust should do and what the GNSS measures
(``seaway_estimator.mismatch``)."""
MOTION_FAULT_TEXT: dict[str, str] = {
    "not_moving": "the vessel does not move as commanded (grounded, fouled, or held)",
    "not_as_modelled": "the vessel does not move as the model predicts from the thrust "
                       "(a thruster stuck or lost)",
}
"""Each ``MotionFaultKind`` for a person."""


class StateEstimate(Message):
    """Estimated state [u, v, r, x, y, psi] (paper eq. 1-2) and disturbance tau_d (body frame).

    ``covariance`` is the row-major 9x9 covariance of [u, v, r, x, y, psi, tau_u, tau_v, tau_r]
    in the units of those fields.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.StateEstimate"
    u_mps: float = Field(description="surge speed through the water [m/s]")
    v_mps: float = Field(description="sway speed through the water [m/s]")
    r_radps: float = Field(description="yaw rate [rad/s]")
    x_m: float = Field(description="north of the origin [m]")
    y_m: float = Field(description="east of the origin [m]")
    psi_rad: float = Field(ge=-math.pi, le=math.pi, description="heading from north [rad]")
    tau_d_surge_n: float = 0.0
    tau_d_sway_n: float = 0.0
    tau_d_yaw_nm: float = 0.0
    covariance: list[float] | None = Field(default=None, min_length=81, max_length=81)
    degraded: bool = False
    motion_fault: MotionFaultKind | None = Field(default=None, description="the vessel does not do "
                                                 "what it is told (``MOTION_FAULT_TEXT``); None: "
                                                 "no such fault")
    motion_fault_detail: str | None = Field(default=None, max_length=MAX_REASON_CHARS,
                                            description="the evidence, for a person")


# ---------------------------------------------------------------------------------------------
# Control and mission (producer: controller)
# ---------------------------------------------------------------------------------------------


class ThrustCommand(Message):
    """Thrust per thruster in newtons (paper's T^1 port, T^2 starboard).

    ``stamp_ns`` is the stamp of the state the command was computed from, so latency is measurable.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.ThrustCommand"
    thrust_port_n: float = Field(description="T^1, port thruster, positive ahead [N]")
    thrust_starboard_n: float = Field(description="T^2, starboard thruster, positive ahead [N]")
    source: str = Field(default="", description="who computed it: 'cc-empc', 'los', 'stop', ...")
    seq: int = Field(default=0, ge=0)


SOLVER_NOT_READY = "no solver yet"
"""How a ``SolveRecord.status`` begins for a period with no solver to call yet (its fast solver
being loaded or made, the reference being set up): flown on a fallback, and not a failed solve."""


class SolveRecord(Message):
    """One MPC solve: outcome, timing, prediction and the cost split by term (paper eq. 14)."""

    SCHEMA: ClassVar[str] = "seaway.v1.SolveRecord"
    controller: str
    status: str
    success: bool
    iterations: int = Field(ge=0)
    solve_time_s: float = Field(ge=0)
    fallback_level: int = Field(default=0, ge=0, description="0 solver, 1 shifted plan, 2 LOS, 3 stop")
    fallback_count: int = Field(default=0, ge=0)
    cost_stage_j: float | None = None
    cost_dynamic_j: float | None = Field(default=None, description="E_d = P_d * t_d [J]")
    cost_static_j: float | None = Field(default=None, description="E_s = P_s * t_s [J]")
    cost_track_j: float | None = Field(default=None, description="Y [J]")
    t_d_s: float | None = None
    t_s_s: float | None = None
    leg_energy_to_go_j: float | None = Field(default=None, description="predicted energy to reach "
                                             "the active waypoint: horizon + E_d + E_s [J]")
    cross_track_m: float | None = None
    predicted_x_m: list[float] = Field(default_factory=list)
    predicted_y_m: list[float] = Field(default_factory=list)
    predicted_psi_rad: list[float] = Field(default_factory=list)
    predicted_thrust_port_n: list[float] = Field(default_factory=list)
    predicted_thrust_starboard_n: list[float] = Field(default_factory=list)


MissionState = Literal["idle", "waiting", "active", "paused", "complete", "aborted"]
"""``waiting``: accepted, but the vehicle does not apply the commanded thrust yet (disarmed, a mode
that withholds it, no link); it becomes ``active`` by itself once the vehicle does
(``MissionStatus.reason`` says what it waits for)."""
AtRest = Literal["hold", "drift"]
"""What the vessel does after the last waypoint and while the operator pauses the mission: ``hold``
station at a point (the default) or ``drift`` (zero thrust)."""
"""A mission's state: idle -> active <-> paused -> complete | aborted (the controller's machine)."""


class MissionStatus(Message):
    """Progress of the active mission."""

    SCHEMA: ClassVar[str] = "seaway.v1.MissionStatus"
    state: MissionState
    mission_id: str = ""
    active_leg: int = Field(default=0, ge=0, description="index i of the active waypoint P_i")
    waypoint_count: int = Field(default=0, ge=0)
    distance_to_waypoint_m: float | None = None
    cross_track_m: float | None = None
    energy_used_j: float | None = None
    energy_to_go_j: float | None = Field(default=None, description="predicted energy to finish the "
                                         "mission (``EnergyBudget.energy_to_go_j``) [J]")
    leg_energy_to_go_j: float | None = Field(default=None, description="predicted energy to reach "
                                             "the active waypoint (the MPC's plan) [J]")
    reason: str = Field(default="", max_length=MAX_REASON_CHARS, description="what the operator "
                        "did not ask for but should know about the mission's state: why the "
                        "controller paused it (e.g. the vehicle was disarmed), or how it is flown "
                        "meanwhile; empty otherwise")
    hold_x_m: float | None = Field(default=None, description="holding station at this point, local "
                                   "NED north [m] (after the last waypoint, or paused); None when not")
    hold_y_m: float | None = Field(default=None, description="the hold point, local NED east [m]")
    hold_energy_j: float | None = Field(default=None, description="energy used holding station since "
                                        "the hold began: propulsion + T^w [J]")


LowEnergyPolicy = Literal["warn", "return", "hold"]
AreaBreachPolicy = Literal["hold", "return"]
"""What the controller does when the vessel or the MPC's predicted course would leave the operating
area in flight: 'hold' station where it is, or 'return' home (or to the nearest rally point)."""
"""What a mission does when the energy to get home plus the reserve reaches the battery's remaining
energy: ``warn`` (say so, fly on), ``return`` (fly straight home, the default), ``hold`` (stop)."""
EnergyDecision = Literal["none", "warn", "return", "hold"]


def return_mission_id(mission_id: str) -> str:
    """The id of the return home the energy budget flies in place of ``mission_id`` (64 chars at
    most, the end kept)."""
    return f"{mission_id}/return"[-64:]


BatteryEstimateSource = Literal["count", "autopilot", "voltage"]
"""Where the energy budget's battery figure came from, the lowest of: ``count`` (the first report's
energy less what the controller counted since), ``autopilot`` (the autopilot's latest remaining,
less what was counted since it), ``voltage`` (the pack's voltage on the vessel file's battery
model, ``seaway.vessel.battery``)."""


class EnergyBudget(Message):
    """Will it make it back: the energy to finish and to get home against the battery, at each
    pricing of an active mission's budget (``mission/energy``; ``seaway_controller.budget``: once a
    second, at each new leg, and every control period once the margin is near 0).

    Predictions come from the controller's own model and cost at its economic cruise under the
    estimated disturbance; ``*_low_j``/``*_high_j`` are the band from the estimate's disturbance
    covariance (one standard deviation each way). Frames: local NED [m].
    """

    SCHEMA: ClassVar[str] = "seaway.v1.EnergyBudget"
    mission_id: str = ""
    active_leg: int = Field(default=0, ge=0)
    returning: bool = Field(default=False, description="the mission is the return home")
    energy_used_j: float = Field(ge=0, description="energy used since the mission started [J]")
    leg_energy_to_go_j: float | None = Field(default=None, description="to the active waypoint, "
                                             "from the MPC's plan [J]")
    energy_to_go_j: float | None = Field(default=None, description="to finish the mission [J]")
    energy_to_go_low_j: float | None = None
    energy_to_go_high_j: float | None = None
    energy_to_home_j: float | None = Field(default=None, description="from here straight home [J]")
    energy_to_home_low_j: float | None = None
    energy_to_home_high_j: float | None = None
    home_x_m: float
    home_y_m: float
    battery_remaining_j: float | None = Field(default=None, description="the battery's usable "
                                              "energy left now: its last report less what the "
                                              "controller counted since [J]")
    battery_stamp_ns: int | None = Field(default=None, ge=0, description="stamp of that report")
    reserve_j: float | None = Field(default=None, ge=0)
    margin_j: float | None = Field(default=None, description="remaining - (to home + reserve): the "
                                   "decision is due when it reaches 0 [J]")
    finish_margin_j: float | None = Field(default=None, description="remaining - (to finish + "
                                          "reserve): below 0 the mission cannot end with the "
                                          "reserve left [J]")
    no_return_x_m: float | None = Field(default=None, description="point of no return along the "
                                        "path ahead: where margin_j is predicted to reach 0 [m]")
    no_return_y_m: float | None = None
    no_return_along_m: float | None = Field(default=None, ge=0, description="how far along the "
                                            "path ahead that point is [m]")
    policy: LowEnergyPolicy
    decision: EnergyDecision = Field(description="'none' until the margin reached 0, then what "
                                     "the policy did, from that period on")
    decided_ns: int | None = Field(default=None, ge=0, description="the period it was decided")
    reason: str = Field(default="", max_length=MAX_REASON_CHARS)
    battery_source: BatteryEstimateSource | None = Field(
        default=None,
        description="which estimate battery_remaining_j is, the lowest of them "
                    "(BatteryEstimateSource); None: no battery report yet")


def mission_over(status: MissionStatus | None, budget: EnergyBudget | None,
                 mission_id: str | None = None) -> bool:
    """Whether the newest ``status`` says there is nothing more to fly of ``mission_id`` (None:
    of whatever mission it is): it is complete, or the return home its energy budget decided
    (``return_mission_id``) is, or the budget held it (``budget``: the newest, policy 'hold')."""
    if status is None:
        return False
    if mission_id is not None and status.mission_id not in (mission_id, return_mission_id(mission_id)):
        return False
    held = (status.state == "paused" and budget is not None and budget.decision == "hold"
            and budget.mission_id == status.mission_id)
    return status.state == "complete" or held



# ---------------------------------------------------------------------------------------------
# Simulation (producer: sim)
# ---------------------------------------------------------------------------------------------


class SimTruth(Message):
    """True state of the simulated vessel and the thrust actually applied (after saturation)."""

    SCHEMA: ClassVar[str] = "seaway.v1.SimTruth"
    u_mps: float
    v_mps: float
    r_radps: float
    x_m: float
    y_m: float
    psi_rad: float
    thrust_port_n: float
    thrust_starboard_n: float
    energy_j: float = Field(ge=0, description="propulsion energy sum alpha*T^2 dt since start [J]")


class DisturbanceForce(Message):
    """Disturbance acting on the simulated vessel now, body frame (paper's tau_d), and current."""

    SCHEMA: ClassVar[str] = "seaway.v1.DisturbanceForce"
    surge_n: float
    sway_n: float
    yaw_nm: float
    current_n_mps: float = 0.0
    current_e_mps: float = 0.0


class ClockTick(Message):
    """The simulator's clock: ``stamp_ns`` is simulated time now."""

    SCHEMA: ClassVar[str] = "seaway.v1.ClockTick"
    lockstep: bool
    real_time_factor: float | None = Field(default=None, ge=0)


LOCKSTEP_SERVICES = ("sim", "estimator", "controller", "recorder")
"""The services that take part in lockstep (``seaway.runtime.lockstep``), each on ``lockstep/<service>``."""
LockstepService = Literal["sim", "estimator", "controller", "recorder"]
_MAX_LISTED = 1000  # stamps listed per key in one period: far above any sensor rate x period
StampLists = dict[Annotated[str, StringConstraints(pattern=r"^[a-z_]+/[a-z_]+$", max_length=64)],
                  Annotated[list[Annotated[int, Field(ge=0)]], Field(max_length=_MAX_LISTED)]]


class PeriodDone(Message):
    """One lockstep member's answer to period ``stamp_ns`` (t_k) of episode ``episode``.

    It says what the member published for the period (``published``: key suffix -> the stamps of
    those messages) and, for the sim, what it consumed (``consumed``: the thrust command it applied
    over (t_{k-1}, t_k]), so a receiver knows exactly which messages to wait for and never waits on a
    timeout (``seaway.runtime.lockstep`` states the protocol). ``seq`` numbers a member's answers
    (unique across its restarts); ``covers`` (the recorder) names, per member, the ``seq`` of the
    answer whose messages it has written to disk. ``hold`` (the controller): nothing to fly, so the
    sim does not step until another answer comes (a mission is set). ``resent``: the recorder may
    trail the others by a period, so a member sends its previous bundle again before repeating its
    last one (``seaway.runtime.lockstep``).
    """

    SCHEMA: ClassVar[str] = "seaway.v1.PeriodDone"
    service: LockstepService
    episode: int = Field(ge=0, description="counts the sim's scenario (re)starts; time restarts at 0")
    seq: int = Field(ge=0)
    period_ns: int = Field(gt=0, le=60 * 10**9, description="the run's control period [ns]")
    published: StampLists = Field(default_factory=dict)
    consumed: StampLists = Field(default_factory=dict)
    hold: bool = False
    covers: dict[LockstepService, Annotated[int, Field(ge=0)]] = Field(default_factory=dict)
    members: list[LockstepService] = Field(default_factory=list, max_length=len(LOCKSTEP_SERVICES),
                                           description="sim: the members it waits for")
    resent: bool = Field(default=False, description="a copy of this member's previous answer (with "
                         "its messages), sent again for a recorder that (re)joined: only a "
                         "recorder takes it")

    @classmethod
    def decode(cls, data: bytes | bytearray | memoryview | str) -> Self:
        """The answer of a lockstep bundle (``seaway.contract.bundle``: its first line), or of a
        lone ``PeriodDone``: every reader of an answer reads it the same way, whichever it heard."""
        raw = bytes(data) if not isinstance(data, str) else data.encode()
        return super().decode(raw.split(b"\n", 1)[0])


# ---------------------------------------------------------------------------------------------
# Requests and replies (queryables)
# ---------------------------------------------------------------------------------------------


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


class MissionRequest(Request):
    """A mission: ordered waypoints P_0..P_N, circle of acceptance, task power T^w, controller, and
    whether the controller predicts with the estimated disturbance."""

    SCHEMA: ClassVar[str] = "seaway.v1.MissionRequest"
    mission_id: str = Field(default="", max_length=64)
    waypoints: list[Waypoint]
    coa_radius_m: float = Field(description="circle-of-acceptance radius r_COA [m]")
    task_power_w: Annotated[float, in_range(0, MAX_TASK_POWER_W, "W", lo_open=True)] = Field(
        gt=0, le=MAX_TASK_POWER_W, description="T^w, power of the task carried [W], (0, 10 kW]")
    controller: ControllerName = DEFAULT_CONTROLLER
    predict_disturbance: bool = Field(default=False, description="predict with the estimator's tau_d "
                                      "instead of tau_d = 0 (the paper's)")
    speed_hint_mps: float | None = Field(default=None, gt=0, description="optional cruise hint")
    on_low_energy: LowEnergyPolicy = Field(default="return", description="when the energy to get "
                                           "home plus the battery's reserve reaches what is left: "
                                           "'warn', 'return' home (default) or 'hold'")
    home: Waypoint | None = Field(default=None, description="where home is; default the first "
                                  "waypoint P_0")
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
    mission_id: str = Field(default="", max_length=64)
    waypoints: list[Waypoint] = Field(min_length=2, description="P_0..P_N in local NED metres "
                                      "(x_m, y_m) at the published origin")
    coa_radius_m: float = Field(gt=0, description="circle-of-acceptance radius r_COA [m]")
    task_power_w: Annotated[float, in_range(0, MAX_TASK_POWER_W, "W", lo_open=True)] = Field(
        gt=0, le=MAX_TASK_POWER_W, description="T^w, power of the task carried [W], (0, 10 kW]")
    controller: ControllerName
    predict_disturbance: bool = Field(description="flown predicting with the estimator's tau_d "
                                      "(asked by the mission or the controller's flag), else tau_d = 0")
    speed_hint_mps: float | None = Field(default=None, gt=0, description="the request's cruise hint")
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


# ---------------------------------------------------------------------------------------------
# Authority (producer: every process, about itself; seaway.runtime.refusals)
# ---------------------------------------------------------------------------------------------

MAX_REFUSAL_ENTRIES = 256
"""Distinct (identity, action, key) triples one report lists; more are summed in ``overflow``."""


class RefusalCount(BaseModel):
    """How often one identity was refused one action on one key by the reporting process."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True)
    identity: str = Field(max_length=128, description="certificate common name of the sender, or "
                          "'unauthenticated' for a link refused before any identity was proven")
    action: str = Field(max_length=64, description="'put', 'delete', 'query', 'reply', "
                        "'declare_queryable', 'liveliness_token', ..., or 'connect' (a link)")
    key: str = Field(max_length=512, description="key expression refused ('' for a link)")
    count: int = Field(ge=1)
    last_ns: int = Field(ge=0, description="wall-clock time of the latest one [ns since epoch]")


class Refusals(Message):
    """What one process's access control refused since it started (``refusals/<identity>``).

    Counted by the receiving process from Zenoh's own access-control decisions; published when it
    changes (at most once a second) and answered on request. ``stamp_ns`` is wall-clock time, also
    in lockstep: a refusal is an event in the world, not in the simulation.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.Refusals"
    identity: str = Field(max_length=128, description="the process that refused (its identity)")
    total: int = Field(ge=0, description="every refusal since the process started")
    counts: list[RefusalCount] = Field(default_factory=list, max_length=MAX_REFUSAL_ENTRIES)
    overflow: int = Field(default=0, ge=0, description="refusals on triples beyond those listed")


# ---------------------------------------------------------------------------------------------
# The run's logs (producer: recorder, from the files it tails; seaway_recorder.logtail)
# ---------------------------------------------------------------------------------------------

MAX_LOG_MESSAGE_CHARS = 8300
"""A log line's text as the recorder passes it on: 8,192 characters and its note of what was cut."""


class LogRecord(Message):
    """One line of one process's log, as the recorder read it from the run folder.

    So a viewer that is not on the machine of the run's files (``seaway foxglove`` on the shore)
    shows the same log as the recording. ``stamp_ns`` is the wall-clock time the line was logged
    (the time the line carries, else the line before's), also in lockstep: a log line is an event
    in the world, not in the simulation.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.LogRecord"
    process: str = Field(min_length=1, max_length=64, description="the profile's process name")
    level: str = Field(default="", max_length=16, description="Python's level name (INFO, ...); "
                       "'' when the line says none")
    logger: str = Field(default="", max_length=200, description="the logger's name")
    message: str = Field(max_length=MAX_LOG_MESSAGE_CHARS)


# ---------------------------------------------------------------------------------------------
# The operating area (producer: controller, the area it enforces; seaway.area)
# ---------------------------------------------------------------------------------------------


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


ALL_MESSAGES: tuple[type[Message], ...] = tuple(
    v for v in list(globals().values())
    if isinstance(v, type) and issubclass(v, Message) and "SCHEMA" in vars(v)
)
"""Every message type, in the order defined above: each class with its own ``SCHEMA``."""
