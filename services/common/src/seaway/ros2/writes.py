"""What a ROS 2 node may send Seaway, as the requests an operator sends (pure: bytes in, requests out).

Off unless ``seaway-ros2 --ros2-writes`` (``seaway launch --ros2 --ros2-writes``). Two topics, under
the face's namespace (``/<vessel>/...``), each with a standard type:

* ``mission/command`` (``std_msgs/msg/String``): ``pause``, ``resume`` or ``abort`` becomes the
  ``MissionCommand`` an operator sends on ``mission/command``;
* ``mission/set_path`` (``nav_msgs/msg/Path``, frame ``map``): its positions, ENU -> NED
  (``seaway.ros2.convert.path_waypoints_ned``), become the waypoints of a ``MissionRequest`` on
  ``mission/set``, flown with the settings of the mission the controller accepted last (circle of
  acceptance, task power, controller, policies; ``mission/accepted``): a Path carries waypoints
  only. Before any mission was accepted there are no settings to take, and the path is dropped.

The requests go to Seaway under the bridge's own identity (``ros2``); Zenoh's access control lets
it ask exactly these two (``seaway.contract.access.ROS2_REQUESTS``, in a stack made with
``ros2_writes``) and the controller decides as for any operator: it refuses too many waypoints, a
path out of range or the operating area, a resume while a failsafe is latched, ...

A sample that is not a whole message of the topic's type (malformed CDR), a path in another frame
or with a coordinate not finite, an unknown command word: dropped and counted here (``WriteStats``,
which the bridge publishes in ``/diagnostics`` and logs at a limited rate), never sent.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, get_args

from seaway.contract import keys
from seaway.contract import messages as m
from seaway.ros2 import cdr, convert
from seaway.ros2 import types as rt


@dataclass(frozen=True)
class Inbound:
    """One topic ROS 2 may write: its name (relative to the namespace), type and the Seaway
    request it becomes."""

    name: str
    type_name: str
    spec: keys.KeySpec
    doc: str


# The command's topic is named after the key it feeds (``mission/command`` on both sides).
COMMAND = Inbound(keys.MISSION_COMMAND.suffix, rt.STRING.name, keys.MISSION_COMMAND,
                  "'pause', 'resume' or 'abort' the mission")
SET_PATH = Inbound("mission/set_path", rt.PATH.name, keys.MISSION_SET,
                   "a new mission through the path's positions (frame map), with the settings of "
                   "the mission accepted last")
INBOUND: tuple[Inbound, ...] = (COMMAND, SET_PATH)
BY_NAME: dict[str, Inbound] = {i.name: i for i in INBOUND}
COMMAND_WORDS: tuple[str, ...] = get_args(m.MissionCommand.model_fields["command"].annotation)


class DroppedError(ValueError):
    """A sample not sent to Seaway; ``kind`` is the counter it goes to."""

    def __init__(self, kind: str, reason: str) -> None:
        super().__init__(reason)
        self.kind = kind


MALFORMED, NOT_CONVERTIBLE, INVALID, NO_SETTINGS = ("malformed", "not_convertible", "invalid",
                                                    "no_settings")
"""Why a sample was dropped: bytes that are not a message of the type; a frame or value the
conversion does not take; a request Seaway's own validation refuses to build; a path before any
mission was accepted."""


@dataclass
class WriteStats:
    """Counts since the bridge started: samples received, requests sent, their answers, drops."""

    received: int = 0
    sent: int = 0
    accepted: int = 0
    refused: int = 0
    dropped: dict[str, int] = field(default_factory=dict)

    def values(self) -> dict[str, str]:
        """As ``diagnostic_msgs/KeyValue`` pairs."""
        out = {"received": self.received, "sent": self.sent, "accepted": self.accepted,
               "refused": self.refused, "dropped": sum(self.dropped.values())}
        out.update({f"dropped_{k}": v for k, v in sorted(self.dropped.items())})
        return {k: str(v) for k, v in out.items()}


class Writes:
    """ROS 2 samples in, Seaway requests out; the newest accepted mission for a path's settings."""

    def __init__(self) -> None:
        self.stats = WriteStats()
        self.mission: m.MissionAccepted | None = None
        self._paths = 0

    def on_accepted(self, accepted: m.MissionAccepted) -> None:
        self.mission = accepted

    def request(self, topic: str, payload: bytes, now_ns: int) -> tuple[keys.KeySpec, m.Request]:
        """The request a sample on ``topic`` asks for; ``DroppedError`` (counted) if none."""
        self.stats.received += 1
        inbound = BY_NAME[topic]
        try:
            try:
                value = cdr.decode(inbound.type_name, payload)
            except cdr.CdrError as err:
                raise DroppedError(MALFORMED, f"malformed CDR: {err}") from None
            return inbound.spec, _BUILD[inbound.name](self, value, now_ns)
        except DroppedError as drop:
            self.stats.dropped[drop.kind] = self.stats.dropped.get(drop.kind, 0) + 1
            raise

    def on_reply(self, reply: m.Reply) -> None:
        self.stats.sent += 1
        if reply.accepted:
            self.stats.accepted += 1
        else:
            self.stats.refused += 1

    def _command(self, value: dict[str, Any], now_ns: int) -> m.Request:
        word = value["data"].strip().lower()
        if word not in COMMAND_WORDS:
            raise DroppedError(INVALID, f"{COMMAND.name}: {value['data']!r} is no command; "
                                   f"send one of {', '.join(COMMAND_WORDS)}")
        return m.MissionCommand.make(stamp_ns=now_ns, command=word)

    def _path(self, value: dict[str, Any], now_ns: int) -> m.Request:
        try:
            points = convert.path_waypoints_ned(value)
        except convert.NotConvertibleError as err:
            raise DroppedError(NOT_CONVERTIBLE, f"{SET_PATH.name}: {err}") from None
        a = self.mission
        if a is None:
            raise DroppedError(NO_SETTINGS, f"{SET_PATH.name}: no mission accepted yet, so no circle of "
                                       "acceptance, task power or controller to fly it with; send "
                                       "the first mission through Seaway")
        self._paths += 1
        try:
            return m.MissionRequest.make(
                stamp_ns=now_ns, mission_id=f"ros2-path-{self._paths}",
                waypoints=[{"x_m": n, "y_m": e} for n, e in points],
                coa_radius_m=a.coa_radius_m, task_power_w=a.task_power_w, controller=a.controller,
                predict_disturbance=a.predict_disturbance, speed_hint_mps=a.speed_hint_mps,
                on_low_energy=a.on_low_energy, at_rest=a.at_rest, on_area_breach=a.on_area_breach)
        except m.MessageError as err:
            raise DroppedError(INVALID, f"{SET_PATH.name}: {err}") from None


_BUILD: dict[str, Callable[[Writes, dict[str, Any], int], m.Request]] = {
    COMMAND.name: Writes._command, SET_PATH.name: Writes._path}
