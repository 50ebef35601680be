"""What ROS 2 may send (seaway.ros2.writes): samples serialised by rosbags (code no one here wrote)
become the requests an operator sends, ENU -> NED; what is not a request is dropped and counted."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from seaway.contract import keys
from seaway.contract import messages as m
from seaway.ros2 import convert, writes

TS = get_typestore(Stores.ROS2_JAZZY)
T = TS.types
ACCEPTED = m.MissionAccepted.make(
    stamp_ns=1, accepted_ns=1, waypoints=[{"x_m": 0, "y_m": 0}, {"x_m": 10, "y_m": 0}],
    coa_radius_m=3.5, task_power_w=120.0, controller="cc-empc", predict_disturbance=True,
    at_rest="drift", on_area_breach="return")


def _header(frame: str):
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=1, nanosec=2),
                                    frame_id=frame)


def path_cdr(points_enu, frame="map", pose_frame="") -> bytes:
    """A nav_msgs/Path through (x east, y north) points, serialised by rosbags."""
    q = T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    poses = [T["geometry_msgs/msg/PoseStamped"](
        header=_header(pose_frame),
        pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                          orientation=q)) for x, y in points_enu]
    msg = T["nav_msgs/msg/Path"](header=_header(frame), poses=poses)
    return bytes(TS.serialize_cdr(msg, "nav_msgs/msg/Path"))


def string_cdr(text: str) -> bytes:
    return bytes(TS.serialize_cdr(T["std_msgs/msg/String"](data=text), "std_msgs/msg/String"))


def test_a_path_in_map_becomes_a_mission_in_ned_with_the_accepted_settings():
    w = writes.Writes()
    w.on_accepted(ACCEPTED)
    # 20 m east then 30 m north of it: (x east, y north) in ENU.
    spec, req = w.request("mission/set_path", path_cdr([(0.0, 0.0), (20.0, 0.0), (20.0, 30.0)]), 5)
    assert spec is keys.MISSION_SET and isinstance(req, m.MissionRequest)
    assert [(p.x_m, p.y_m) for p in req.waypoints] == [(0.0, 0.0), (0.0, 20.0), (30.0, 20.0)]
    assert (req.coa_radius_m, req.task_power_w, req.controller, req.predict_disturbance,
            req.at_rest, req.on_area_breach) == (3.5, 120.0, "cc-empc", True, "drift", "return")
    assert req.stamp_ns == 5 and req.mission_id == "ros2-path-1"
    assert w.stats.received == 1 and not w.stats.dropped


def test_enu_to_ned_inverts_what_the_face_publishes():
    for n, e in [(10.0, -4.0), (-3.5, 7.25)]:
        assert convert.enu_to_ned(*convert.ned_to_enu(n, e)) == (n, e)


def test_a_command_word_becomes_the_operators_mission_command():
    w = writes.Writes()
    for word in ("pause", "resume", "abort"):
        spec, req = w.request("mission/command", string_cdr(word), 7)
        assert spec is keys.MISSION_COMMAND
        assert req == m.MissionCommand.make(stamp_ns=7, command=word)


@pytest.mark.parametrize(("topic", "payload", "kind"), [
    ("mission/command", b"\x00\x01\x00\x00\xff\xff\xff\x7f", writes.MALFORMED),  # length 2^31
    ("mission/command", b"\x00\x01", writes.MALFORMED),
    ("mission/command", string_cdr("dance"), writes.INVALID),
    ("mission/set_path", path_cdr([(0.0, 0.0), (1.0, 1.0)])[:-9], writes.MALFORMED),
    ("mission/set_path", path_cdr([(0.0, 0.0), (5.0, 5.0)], frame="odom"), writes.NOT_CONVERTIBLE),
    ("mission/set_path", path_cdr([(0.0, 0.0), (5.0, 5.0)], pose_frame="base_link"),
     writes.NOT_CONVERTIBLE),
    ("mission/set_path", path_cdr([(0.0, 0.0), (math.nan, 5.0)]), writes.NOT_CONVERTIBLE),
    ("mission/set_path", path_cdr([(0.0, 0.0), (1e309, 5.0)]), writes.NOT_CONVERTIBLE),  # inf
], ids=["huge-length", "truncated-header", "unknown-word", "truncated-path", "frame-odom",
        "pose-frame", "nan", "inf"])
def test_what_is_not_a_request_is_dropped_and_counted(topic, payload, kind):
    w = writes.Writes()
    w.on_accepted(ACCEPTED)
    with pytest.raises(writes.DroppedError) as err:
        w.request(topic, payload, 1)
    assert err.value.kind == kind
    assert w.stats.dropped == {kind: 1} and w.stats.received == 1 and w.stats.sent == 0
    assert w.stats.values()["dropped"] == "1"


def test_a_path_before_any_mission_has_no_settings_to_fly_with():
    w = writes.Writes()
    with pytest.raises(writes.DroppedError, match="no mission accepted yet"):
        w.request("mission/set_path", path_cdr([(0.0, 0.0), (5.0, 5.0)]), 1)
    assert w.stats.dropped == {writes.NO_SETTINGS: 1}


def test_replies_are_counted():
    w = writes.Writes()
    w.on_reply(m.Reply.accept(1))
    w.on_reply(m.Reply.refuse(2, "no"))
    assert (w.stats.sent, w.stats.accepted, w.stats.refused) == (2, 1, 1)


def test_rosbags_agrees_on_the_path_it_serialised():
    """The path is decoded by seaway.ros2.cdr exactly as rosbags wrote it (not ours both ways)."""
    data = path_cdr([(1.5, -2.0), (3.0, 4.0)])
    theirs = TS.deserialize_cdr(data, "nav_msgs/msg/Path")
    got = [(p.pose.position.x, p.pose.position.y) for p in theirs.poses]
    assert np.allclose(got, [(1.5, -2.0), (3.0, 4.0)])
