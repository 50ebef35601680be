"""What Seaway shows ROS 2: which Seaway key becomes which ROS 2 topic, and the conversion (pure).

``TOPICS`` is the one table of the ROS 2 face: the live bridge (``seaway.ros2.bridge``) publishes
it and ``seaway export ros2`` (``seaway.ros2.export``) writes it into rosbag2 recordings, so a live
subscriber and a recording see the same topics, types and values. Topic names are relative to the
vessel's namespace (``/<vessel>``), except ``/diagnostics`` (where ROS's diagnostic tools look).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from seaway.contract import keys
from seaway.contract import messages as m
from seaway.ros2 import convert
from seaway.ros2 import types as rt
from seaway.vessel.model import VesselParams


@dataclass(frozen=True)
class Topic:
    """One ROS 2 topic: the Seaway key it comes from, its name, its type and the conversion."""

    spec: keys.KeySpec
    name: str
    type_name: str
    convert: Callable[[Any, VesselParams], convert.Msg]
    doc: str


TOPICS: tuple[Topic, ...] = (
    Topic(keys.NAV_STATE, "odom", rt.ODOMETRY.name, lambda s, _v: convert.odometry(s),
          "estimated state: pose in map (ENU), twist in base_link (FLU), covariances"),
    Topic(keys.GNSS, "gnss/fix", rt.NAV_SAT_FIX.name, lambda g, _v: convert.nav_sat_fix(g),
          "GNSS fix in degrees, horizontal covariance when known"),
    Topic(keys.MISSION_ACCEPTED, "mission/path", rt.PATH.name,
          lambda a, _v: convert.mission_path(a), "the accepted mission's waypoints P_0..P_N in map"),
    Topic(keys.SOLVE, "mpc/predicted_path", rt.PATH.name, lambda s, _v: convert.predicted_path(s),
          "the MPC's predicted trajectory at each solve, in map"),
    Topic(keys.THRUST, "thrust/wrench", rt.WRENCH_STAMPED.name, convert.thrust_wrench,
          "commanded thrust as surge force and yaw moment in base_link (FLU)"),
    Topic(keys.VEHICLE_BATTERY, "battery", rt.BATTERY_STATE.name,
          lambda b, _v: convert.battery_state(b), "the propulsion battery"),
)
WRITES_FLAG = "--ros2-writes"
"""``seaway-ros2``'s switch for what ROS 2 may send (``seaway.ros2.writes``); the launcher passes
it and makes the stack's access rules let the face ask (``seaway.contract.access.ROS2_REQUESTS``)."""
DIAGNOSTICS_TOPIC = "/diagnostics"
"""Health: each service's liveliness and the vehicle's status (``convert.diagnostics``)."""
BY_SUFFIX: dict[str, Topic] = {t.spec.suffix: t for t in TOPICS}


def ros_message(topic: Topic, msg: m.Message, vessel: VesselParams) -> convert.Msg:
    """``msg`` (of ``topic.spec``) as the topic's ROS 2 message."""
    type_name, value = topic.convert(msg, vessel)
    assert type_name == topic.type_name, (type_name, topic.type_name)
    return type_name, value


class Health:
    """Which services' health tokens live, and the newest vehicle status: the diagnostics' input."""

    def __init__(self) -> None:
        self.services: dict[str, bool] = {}
        self.vehicle: m.VehicleStatus | None = None

    def on_token(self, service: str, alive: bool) -> None:
        self.services[service] = alive

    def on_status(self, status: m.VehicleStatus) -> None:
        self.vehicle = status

    def message(self, stamp_ns: int, vessel: str) -> convert.Msg:
        return convert.diagnostics(stamp_ns, vessel, dict(self.services), self.vehicle)


def topic_types() -> Mapping[str, str]:
    """Every topic of the face (relative names, and ``/diagnostics``) with its ROS 2 type."""
    return {**{t.name: t.type_name for t in TOPICS}, DIAGNOSTICS_TOPIC: rt.DIAGNOSTIC_ARRAY.name}
