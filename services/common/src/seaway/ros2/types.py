"""The ROS 2 message types Seaway publishes, defined once: fields, ``.msg`` text, type hashes.

Each type is written here from its ROS 2 definition (common_interfaces and rcl_interfaces as
released for Jazzy and Kilted: the field lists, not the comments). From it come:

* ``msg_definition``: the ``.msg`` text with every type it uses appended, each after a line of 80
  ``=`` and ``MSG: <pkg>/<Name>``, as rosbag2 stores a ``ros2msg`` schema in MCAP;
* ``type_hash``: the RIHS01 hash of REP-2011 (``rosidl_generator_type_description``): SHA-256 over
  the canonical JSON of the type description (the type's fields and those of every type it refers
  to, sorted by name; default values left out), ``RIHS01_<hex>``. Computed here, never copied;
  ``tests/unit/ros2`` checks it against published values and against ``rosbags``;
* ``dds_type_name``: the type as rmw_zenoh names it in key expressions
  (``nav_msgs::msg::dds_::Odometry_``).

Constants are part of the ``.msg`` text but not of the type description (REP-2011), so not of
the hash.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from typing import Any

PRIMITIVE_IDS: dict[str, int] = {
    "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7, "int64": 8,
    "uint64": 9, "float32": 10, "float64": 11, "char": 13, "bool": 15, "byte": 16, "string": 17,
}
"""type_description_interfaces/msg/FieldType ids of the primitive types used here."""
NESTED_TYPE_ID = 1
ARRAY_OFFSET = 48
"""A fixed-size array's type id is its element's + 48; an unbounded sequence's + 144."""
SEQUENCE_OFFSET = 144
SEPARATOR = "=" * 80
"""The line between a ``ros2msg`` schema's types (rosbag2)."""


@dataclass(frozen=True)
class Field:
    """One field: ``type`` is a primitive (``float64``) or a message (``geometry_msgs/msg/Pose``);
    ``array``: a fixed length; ``sequence``: an unbounded sequence."""

    name: str
    type: str
    array: int | None = None
    sequence: bool = False

    @property
    def nested(self) -> bool:
        return self.type not in PRIMITIVE_IDS


@dataclass(frozen=True)
class Constant:
    name: str
    type: str
    value: str


@dataclass(frozen=True)
class MsgType:
    """A ROS 2 message type: ``name`` is ``<pkg>/msg/<Name>``."""

    name: str
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...] = ()


def _t(name: str, *fields: Field, constants: tuple[Constant, ...] = ()) -> MsgType:
    return MsgType(name, fields, constants)


F = Field
TIME = _t("builtin_interfaces/msg/Time", F("sec", "int32"), F("nanosec", "uint32"))
STRING = _t("std_msgs/msg/String", F("data", "string"))
"""Not published: the type whose hash and key expression rmw_zenoh's own documentation shows."""
HEADER = _t("std_msgs/msg/Header", F("stamp", TIME.name), F("frame_id", "string"))
POINT = _t("geometry_msgs/msg/Point", F("x", "float64"), F("y", "float64"), F("z", "float64"))
VECTOR3 = _t("geometry_msgs/msg/Vector3", F("x", "float64"), F("y", "float64"), F("z", "float64"))
QUATERNION = _t("geometry_msgs/msg/Quaternion", F("x", "float64"), F("y", "float64"),
                F("z", "float64"), F("w", "float64"))
POSE = _t("geometry_msgs/msg/Pose", F("position", POINT.name), F("orientation", QUATERNION.name))
POSE_COV = _t("geometry_msgs/msg/PoseWithCovariance", F("pose", POSE.name),
              F("covariance", "float64", array=36))
TWIST = _t("geometry_msgs/msg/Twist", F("linear", VECTOR3.name), F("angular", VECTOR3.name))
TWIST_COV = _t("geometry_msgs/msg/TwistWithCovariance", F("twist", TWIST.name),
               F("covariance", "float64", array=36))
ODOMETRY = _t("nav_msgs/msg/Odometry", F("header", HEADER.name), F("child_frame_id", "string"),
              F("pose", POSE_COV.name), F("twist", TWIST_COV.name))
POSE_STAMPED = _t("geometry_msgs/msg/PoseStamped", F("header", HEADER.name), F("pose", POSE.name))
PATH = _t("nav_msgs/msg/Path", F("header", HEADER.name),
          F("poses", POSE_STAMPED.name, sequence=True))
WRENCH = _t("geometry_msgs/msg/Wrench", F("force", VECTOR3.name), F("torque", VECTOR3.name))
WRENCH_STAMPED = _t("geometry_msgs/msg/WrenchStamped", F("header", HEADER.name),
                    F("wrench", WRENCH.name))
NAV_SAT_STATUS = _t(
    "sensor_msgs/msg/NavSatStatus", F("status", "int8"), F("service", "uint16"),
    constants=(Constant("STATUS_NO_FIX", "int8", "-1"), Constant("STATUS_FIX", "int8", "0"),
               Constant("STATUS_SBAS_FIX", "int8", "1"), Constant("STATUS_GBAS_FIX", "int8", "2"),
               Constant("SERVICE_GPS", "uint16", "1"), Constant("SERVICE_GLONASS", "uint16", "2"),
               Constant("SERVICE_COMPASS", "uint16", "4"),
               Constant("SERVICE_GALILEO", "uint16", "8")))
NAV_SAT_FIX = _t(
    "sensor_msgs/msg/NavSatFix", F("header", HEADER.name), F("status", NAV_SAT_STATUS.name),
    F("latitude", "float64"), F("longitude", "float64"), F("altitude", "float64"),
    F("position_covariance", "float64", array=9), F("position_covariance_type", "uint8"),
    constants=(Constant("COVARIANCE_TYPE_UNKNOWN", "uint8", "0"),
               Constant("COVARIANCE_TYPE_APPROXIMATED", "uint8", "1"),
               Constant("COVARIANCE_TYPE_DIAGONAL_KNOWN", "uint8", "2"),
               Constant("COVARIANCE_TYPE_KNOWN", "uint8", "3")))
KEY_VALUE = _t("diagnostic_msgs/msg/KeyValue", F("key", "string"), F("value", "string"))
DIAGNOSTIC_STATUS = _t(
    "diagnostic_msgs/msg/DiagnosticStatus", F("level", "byte"), F("name", "string"),
    F("message", "string"), F("hardware_id", "string"),
    F("values", KEY_VALUE.name, sequence=True),
    constants=(Constant("OK", "byte", "0"), Constant("WARN", "byte", "1"),
               Constant("ERROR", "byte", "2"), Constant("STALE", "byte", "3")))
DIAGNOSTIC_ARRAY = _t("diagnostic_msgs/msg/DiagnosticArray", F("header", HEADER.name),
                      F("status", DIAGNOSTIC_STATUS.name, sequence=True))
BATTERY_STATE = _t(
    "sensor_msgs/msg/BatteryState", F("header", HEADER.name), F("voltage", "float32"),
    F("temperature", "float32"), F("current", "float32"), F("charge", "float32"),
    F("capacity", "float32"), F("design_capacity", "float32"), F("percentage", "float32"),
    F("power_supply_status", "uint8"), F("power_supply_health", "uint8"),
    F("power_supply_technology", "uint8"), F("present", "bool"),
    F("cell_voltage", "float32", sequence=True), F("cell_temperature", "float32", sequence=True),
    F("location", "string"), F("serial_number", "string"),
    constants=(Constant("POWER_SUPPLY_STATUS_UNKNOWN", "uint8", "0"),
               Constant("POWER_SUPPLY_STATUS_CHARGING", "uint8", "1"),
               Constant("POWER_SUPPLY_STATUS_DISCHARGING", "uint8", "2"),
               Constant("POWER_SUPPLY_STATUS_NOT_CHARGING", "uint8", "3"),
               Constant("POWER_SUPPLY_STATUS_FULL", "uint8", "4"),
               Constant("POWER_SUPPLY_HEALTH_UNKNOWN", "uint8", "0"),
               Constant("POWER_SUPPLY_HEALTH_GOOD", "uint8", "1"),
               Constant("POWER_SUPPLY_HEALTH_DEAD", "uint8", "3"),
               Constant("POWER_SUPPLY_TECHNOLOGY_UNKNOWN", "uint8", "0")))

TYPES: dict[str, MsgType] = {t.name: t for t in list(globals().values()) if isinstance(t, MsgType)}
"""Every type defined above, by name."""


class UnknownTypeError(KeyError):
    """A type name this module does not define."""


def get(name: str) -> MsgType:
    try:
        return TYPES[name]
    except KeyError:
        raise UnknownTypeError(f"ROS 2 type {name!r} is not defined in seaway.ros2.types; "
                               f"defined: {', '.join(sorted(TYPES))}") from None


def dependencies(name: str) -> list[str]:
    """Every type ``name`` refers to, directly or not, each once, depth first in field order."""
    out: list[str] = []

    def walk(t: MsgType) -> None:
        for f in t.fields:
            if f.nested and f.type not in out:
                out.append(f.type)
                walk(get(f.type))

    walk(get(name))
    return out


def _short(name: str) -> str:
    """``pkg/msg/Name`` as a ``.msg`` file refers to it: ``pkg/Name``."""
    pkg, _, msg = name.split("/")
    return f"{pkg}/{msg}"


def _msg_text(t: MsgType) -> str:
    lines = [f"{c.type} {c.name}={c.value}" for c in t.constants]
    for f in t.fields:
        kind = _short(f.type) if f.nested else f.type
        suffix = f"[{f.array}]" if f.array is not None else "[]" if f.sequence else ""
        lines.append(f"{kind}{suffix} {f.name}")
    return "\n".join(lines)


def msg_definition(name: str) -> str:
    """The ``ros2msg`` schema text of ``name``: its ``.msg`` text, then each type it uses."""
    parts = [_msg_text(get(name))]
    for dep in dependencies(name):
        parts.append(f"{SEPARATOR}\nMSG: {_short(dep)}\n{_msg_text(get(dep))}")
    return "\n".join(parts) + "\n"


def _field_type(f: Field) -> dict[str, Any]:
    base = NESTED_TYPE_ID if f.nested else PRIMITIVE_IDS[f.type]
    type_id = base + (ARRAY_OFFSET if f.array is not None else SEQUENCE_OFFSET if f.sequence else 0)
    return {"type_id": type_id, "capacity": f.array or 0, "string_capacity": 0,
            "nested_type_name": f.type if f.nested else ""}


def _description(t: MsgType) -> dict[str, Any]:
    return {"type_name": t.name,
            "fields": [{"name": f.name, "type": _field_type(f)} for f in t.fields]}


def type_description(name: str) -> dict[str, Any]:
    """REP-2011's hashable type description: the type, and every type it refers to by name."""
    return {"type_description": _description(get(name)),
            "referenced_type_descriptions": [_description(get(d)) for d in sorted(dependencies(name))]}


def type_hash(name: str) -> str:
    """``RIHS01_<sha256 hex>`` of the type description's canonical JSON (Python's ``json.dumps``
    with ``', '`` and ``': '`` separators, keys in the order above, ASCII only)."""
    text = json.dumps(type_description(name), ensure_ascii=True, separators=(", ", ": "))
    return "RIHS01_" + hashlib.sha256(text.encode()).hexdigest()


def dds_type_name(name: str) -> str:
    """``nav_msgs/msg/Odometry`` -> ``nav_msgs::msg::dds_::Odometry_`` (rmw_zenoh's type chunk)."""
    pkg, sub, msg = get(name).name.split("/")
    return f"{pkg}::{sub}::dds_::{msg}_"
