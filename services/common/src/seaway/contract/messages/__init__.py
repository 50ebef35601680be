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

The types live in one module per producer, as the wire's sections: ``base`` (``Message``,
``MessageError``, the JSON Schema), ``sensors``, ``navigation``, ``control``, ``simulation``,
``lockstep``, ``requests``, ``authority``, ``logs`` and ``area``; every name is imported from
here (``seaway.contract.messages``), which re-exports them all.
"""

from __future__ import annotations

from seaway.contract.messages import (
    area,
    authority,
    base,
    control,
    lockstep,
    logs,
    navigation,
    requests,
    sensors,
    simulation,
)
from seaway.contract.messages.area import (
    ActiveArea,
    AreaCircleZone,
    AreaPolygonZone,
    AreaRallyPoint,
    AreaVertex,
)
from seaway.contract.messages.authority import (
    MAX_REFUSAL_ENTRIES,
    RefusalCount,
    Refusals,
)
from seaway.contract.messages.base import (
    JSON_ENCODING,
    MAX_REASON_CHARS,
    MAX_STAMP_NS,
    NS_DURATION_FIELDS,
    Message,
    MessageError,
    message_encoding,
    nullable_fields_without_default,
    wire_json_schema,
)
from seaway.contract.messages.control import (
    SOLVER_NOT_READY,
    AreaBreachPolicy,
    AtRest,
    BatteryEstimateSource,
    EnergyBudget,
    EnergyDecision,
    LowEnergyPolicy,
    MissionState,
    MissionStatus,
    SolveRecord,
    ThrustCommand,
    mission_over,
    return_mission_id,
)
from seaway.contract.messages.lockstep import (
    LOCKSTEP_SERVICES,
    LockstepService,
    PeriodDone,
    StampLists,
)
from seaway.contract.messages.logs import (
    MAX_LOG_MESSAGE_CHARS,
    LogRecord,
)
from seaway.contract.messages.navigation import (
    MAX_THRUST_SHORT_FRAC,
    MOTION_FAULT_TEXT,
    MotionFaultKind,
    NavOrigin,
    StateEstimate,
    ThrusterSide,
)
from seaway.contract.messages.requests import (
    CONTROLLER_NAME_PATTERN,
    CONTROLLER_NAMES,
    DEFAULT_CONTROLLER,
    MAX_COA_RADIUS_M,
    MAX_SPEED_HINT_MPS,
    MAX_TASK_POWER_W,
    MISSION_OPTIONS,
    ArmRequest,
    BuiltinControllerName,
    CoaRadiusM,
    ControllerName,
    HomeRequest,
    MissionAccepted,
    MissionCommand,
    MissionId,
    MissionOptions,
    MissionRequest,
    ModeRequest,
    NavResetRequest,
    Reply,
    Request,
    ScenarioRequest,
    SpeedHintMps,
    TaskPowerW,
    Waypoint,
)
from seaway.contract.messages.sensors import (
    GNSS_ALT_MAX_M,
    GNSS_ALT_MIN_M,
    HOLD_REASON_TEXT,
    MAX_ATTITUDE_RATE_HZ,
    MAX_GNSS_RATE_HZ,
    MAX_GNSS_STD_M,
    THRUST_APPLIED_ANYWAY,
    Attitude,
    AutopilotFence,
    AutopilotFenceState,
    BatteryLevel,
    BatterySource,
    BatteryState,
    GnssFix,
    HoldReason,
    LocalPosition,
    ThrustWithheld,
    VehicleStatus,
)
from seaway.contract.messages.simulation import (
    ClockTick,
    DisturbanceForce,
    SimTruth,
)

__all__ = [
    "ALL_MESSAGES",
    "CONTROLLER_NAMES",
    "CONTROLLER_NAME_PATTERN",
    "DEFAULT_CONTROLLER",
    "GNSS_ALT_MAX_M",
    "GNSS_ALT_MIN_M",
    "HOLD_REASON_TEXT",
    "JSON_ENCODING",
    "LOCKSTEP_SERVICES",
    "MAX_ATTITUDE_RATE_HZ",
    "MAX_COA_RADIUS_M",
    "MAX_GNSS_RATE_HZ",
    "MAX_GNSS_STD_M",
    "MAX_LOG_MESSAGE_CHARS",
    "MAX_REASON_CHARS",
    "MAX_REFUSAL_ENTRIES",
    "MAX_SPEED_HINT_MPS",
    "MAX_STAMP_NS",
    "MAX_TASK_POWER_W",
    "MAX_THRUST_SHORT_FRAC",
    "MISSION_OPTIONS",
    "MODULES",
    "MOTION_FAULT_TEXT",
    "NS_DURATION_FIELDS",
    "SOLVER_NOT_READY",
    "THRUST_APPLIED_ANYWAY",
    "ActiveArea",
    "AreaBreachPolicy",
    "AreaCircleZone",
    "AreaPolygonZone",
    "AreaRallyPoint",
    "AreaVertex",
    "ArmRequest",
    "AtRest",
    "Attitude",
    "AutopilotFence",
    "AutopilotFenceState",
    "BatteryEstimateSource",
    "BatteryLevel",
    "BatterySource",
    "BatteryState",
    "BuiltinControllerName",
    "ClockTick",
    "CoaRadiusM",
    "ControllerName",
    "DisturbanceForce",
    "EnergyBudget",
    "EnergyDecision",
    "GnssFix",
    "HoldReason",
    "HomeRequest",
    "LocalPosition",
    "LockstepService",
    "LogRecord",
    "LowEnergyPolicy",
    "Message",
    "MessageError",
    "MissionAccepted",
    "MissionCommand",
    "MissionId",
    "MissionOptions",
    "MissionRequest",
    "MissionState",
    "MissionStatus",
    "ModeRequest",
    "MotionFaultKind",
    "NavOrigin",
    "NavResetRequest",
    "PeriodDone",
    "RefusalCount",
    "Refusals",
    "Reply",
    "Request",
    "ScenarioRequest",
    "SimTruth",
    "SolveRecord",
    "SpeedHintMps",
    "StampLists",
    "StateEstimate",
    "TaskPowerW",
    "ThrustCommand",
    "ThrustWithheld",
    "ThrusterSide",
    "VehicleStatus",
    "Waypoint",
    "area",
    "authority",
    "base",
    "control",
    "lockstep",
    "logs",
    "message_encoding",
    "mission_over",
    "navigation",
    "nullable_fields_without_default",
    "requests",
    "return_mission_id",
    "sensors",
    "simulation",
    "wire_json_schema",
]

MODULES = (base, sensors, navigation, control, simulation, lockstep, requests, authority, logs, area)
"""The package's modules, in the order of its sections (the wire's producers)."""

ALL_MESSAGES: tuple[type[Message], ...] = tuple(
    v for module in MODULES for v in vars(module).values()
    if isinstance(v, type) and issubclass(v, Message) and "SCHEMA" in vars(v)
    and v.__module__ == module.__name__
)
"""Every message type, in the order defined (module by module): each class with its own ``SCHEMA``."""
