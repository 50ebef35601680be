"""seaway.ros2's wire pieces against code no one here wrote (rosbags) and published values: type
hashes, CDR both ways, rmw_zenoh's key expressions, tokens and attachment, and the frames."""

from __future__ import annotations

import dataclasses
import math
import struct

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from seaway.contract import messages as m
from seaway.ros2 import cdr, convert, face, rmw
from seaway.ros2 import types as rt
from seaway.vessel.model import load_vessel

TS = get_typestore(Stores.ROS2_JAZZY)
VESSEL = load_vessel("paper-boat")

# Published in rmw_zenoh's documentation (docs/design.md, the chatter example) and by others'
# tests of rmw_zenoh keys (an Odometry topic): computed here, they must come out the same.
PUBLISHED = {
    "std_msgs/msg/String": "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18",
    "nav_msgs/msg/Odometry": "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
}


@pytest.mark.parametrize("name", sorted(PUBLISHED))
def test_type_hashes_equal_the_published_ones(name):
    assert rt.type_hash(name) == PUBLISHED[name]


@pytest.mark.parametrize("name", sorted(rt.TYPES))
def test_type_hashes_equal_rosbags(name):
    assert rt.type_hash(name) == TS.hash_rihs01(name)


@pytest.mark.parametrize("name", sorted(rt.TYPES))
def test_msg_definitions_parse_to_the_same_fields_as_rosbags(name):
    """The ros2msg schema text rosbags reads (as from an MCAP) defines the types it knows."""
    text = rt.msg_definition(name)
    own = {}
    for i, part in enumerate(text.split(rt.SEPARATOR + "\n")):
        head, _, body = part.partition("\n")
        tname = name if i == 0 else head.removeprefix("MSG: ").replace("/", "/msg/")
        own.update(get_types_from_msg(part if i == 0 else body, tname))
    for tname, (_consts, fields) in own.items():
        assert fields == TS.fielddefs[tname][1], tname


def _state(**over) -> m.StateEstimate:
    base = dict(stamp_ns=12_345_678_901, u_mps=1.2, v_mps=0.3, r_radps=0.05, x_m=10.0, y_m=-4.0,
                psi_rad=0.4, covariance=[float(i % 9 + 1) / 100 for i in range(81)])
    return m.StateEstimate.make(**{**base, **over})


SAMPLES = {
    "odom": _state(),
    "gnss/fix": m.GnssFix.make(stamp_ns=5, lat_rad=0.9, lon_rad=0.2, alt_m=12.0, fix_type=6,
                                horizontal_std_m=0.5),
    "mission/path": m.MissionAccepted.make(
        stamp_ns=7, accepted_ns=7, waypoints=[{"x_m": 0, "y_m": 0}, {"x_m": 20, "y_m": 5},
                                              {"x_m": 20, "y_m": 30}],
        coa_radius_m=2, task_power_w=100, controller="cc-empc", predict_disturbance=False),
    "mpc/predicted_path": m.SolveRecord.make(
        stamp_ns=9, controller="cc-empc", status="ok", success=True, iterations=3, solve_time_s=0.01,
        predicted_x_m=[0.0, 1.0, 2.0], predicted_y_m=[0.0, 0.5, 1.0], predicted_psi_rad=[0.0, 0.1, 0.2]),
    "thrust/wrench": m.ThrustCommand.make(stamp_ns=11, thrust_port_n=30.0, thrust_starboard_n=10.0),
    "battery": m.BatteryState.make(stamp_ns=13, source="sim", voltage_v=24.5, current_a=12.0,
                                   remaining_frac=0.8),
}


def _plain(v):
    """A rosbags message as dicts and lists, to compare with ours."""
    if hasattr(v, "__msgtype__"):
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)
                if f.name != "__msgtype__" and not f.name.isupper()}  # constants: not on the wire
    if isinstance(v, np.ndarray | list):
        return [_plain(x) for x in v]
    return v


def _same(a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, list):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    elif isinstance(a, float) and math.isnan(a):
        assert math.isnan(b)
    else:
        assert a == pytest.approx(b, rel=1e-6) if isinstance(a, float) else a == b


@pytest.mark.parametrize("topic", [t.name for t in face.TOPICS])
def test_cdr_round_trips_through_rosbags(topic):
    """Our bytes decode in rosbags to our values; rosbags' bytes of them decode here the same."""
    t = face.BY_SUFFIX[next(s for s, x in face.BY_SUFFIX.items() if x.name == topic)]
    type_name, value = face.ros_message(t, SAMPLES[topic], VESSEL)
    data = cdr.encode(type_name, value)
    assert data[:4] == b"\x00\x01\x00\x00"
    theirs = TS.deserialize_cdr(data, type_name)
    _same(value, _plain(theirs))
    back = cdr.decode(type_name, TS.serialize_cdr(theirs, type_name))
    _same(value, back)


def test_diagnostics_round_trip_through_rosbags():
    status = m.VehicleStatus.make(stamp_ns=1, autopilot="px4", link_ok=True, armed=True,
                                  mode="MANUAL", failsafe="thrust_stale")
    type_name, value = convert.diagnostics(3, "vessel1", {"estimator": True, "sim": False}, status)
    got = _plain(TS.deserialize_cdr(cdr.encode(type_name, value), type_name))
    _same(value, got)
    assert [s["level"] for s in got["status"]] == [convert.OK, convert.ERROR, convert.WARN]


def test_a_malformed_payload_is_refused_naming_the_field():
    type_name, value = convert.odometry(_state())
    data = cdr.encode(type_name, value)
    with pytest.raises(cdr.CdrError, match=r"Odometry\.twist"):
        cdr.decode(type_name, data[:-60])
    with pytest.raises(cdr.CdrError, match="encapsulation"):
        cdr.decode(type_name, b"\x00\x00\x00\x00" + data[4:])
    bad = bytearray(data)
    struct.pack_into("<I", bad, 4 + 8, 1 << 30)  # the frame_id's length: a gigabyte
    with pytest.raises(cdr.CdrError, match="frame_id"):
        cdr.decode(type_name, bytes(bad))


def test_frames_ned_frd_become_enu_flu():
    s = _state(x_m=10.0, y_m=-4.0, psi_rad=0.0, u_mps=1.0, v_mps=0.5, r_radps=0.1)
    _, o = convert.odometry(s)
    p, q = o["pose"]["pose"]["position"], o["pose"]["pose"]["orientation"]
    assert (p["x"], p["y"]) == (-4.0, 10.0)  # east, north
    assert 2 * math.atan2(q["z"], q["w"]) == pytest.approx(math.pi / 2)  # north is +90 deg from east
    tw = o["twist"]["twist"]
    assert (tw["linear"]["x"], tw["linear"]["y"], tw["angular"]["z"]) == (1.0, -0.5, -0.1)
    # East (psi = +90 deg clockwise) is yaw 0; the pose covariance's xx is NED's yy.
    assert convert.heading_to_yaw(math.pi / 2) == pytest.approx(0.0)
    assert o["pose"]["covariance"][0] == s.covariance[9 * 4 + 4]
    # More thrust on port turns the boat clockwise (NED +N): in FLU that is a negative moment.
    _, w = convert.thrust_wrench(SAMPLES["thrust/wrench"], VESSEL)
    assert w["wrench"]["force"]["x"] == 40.0
    assert w["wrench"]["torque"]["z"] == pytest.approx(-(30.0 - 10.0) * VESSEL.arm_m)


def test_key_expressions_and_tokens_follow_rmw_zenoh():
    """rmw_zenoh's documented chatter example: the key and the publisher's token."""
    assert rmw.topic_key(0, "/chatter", "std_msgs/msg/String") == (
        "0/chatter/std_msgs::msg::dds_::String_/" + PUBLISHED["std_msgs/msg/String"])
    node = rmw.Node(0, "8b20917502ee955ac4476e0266340d5c", 0, "/", "talker")
    assert node.publisher_token(10, "/chatter", "std_msgs/msg/String", qos="::,7:,:,:,,") == (
        "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
        "std_msgs::msg::dds_::String_/" + PUBLISHED["std_msgs/msg/String"] + "/::,7:,:,:,,")
    assert node.token() == "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/0/NN/%/%/talker"
    with pytest.raises(rmw.RosNameError, match="namespace"):
        rmw.Node(0, "z", 0, "/vessel-1", "n")
    assert rmw.ros_name("boat-2.a") == "boat_2_a" and rmw.ros_name("2b") == "v2b"


def test_the_attachment_is_zenoh_ext_serialised():
    gid = bytes(range(16))
    att = rmw.attachment(7, 1_700_000_000_123_456_789, gid)
    assert att == struct.pack("<qq", 7, 1_700_000_000_123_456_789) + b"\x10" + gid
    assert rmw.parse_attachment(att) == (7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(ValueError):
        rmw.parse_attachment(att[:-1])


# XXH3-128 of the empty input (seed 0) is xxHash's documented sanity value
# 0x99AA06D3014798D8_6001C324468D497F (high64_low64, tests/sanity_test_vectors.h); rmw_zenoh stores
# low64 then high64, each little endian. The two tokens' GIDs were computed by compiling rmw_zenoh's
# own simplified_xxhash3.cpp (rolling) with Entity::Entity's two memcpy calls, not with this code.
RMW_ZENOH_GIDS = {
    "": "7f498d4624c30160d8984701d306aa99",
    "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/0/NN/%/%/talker":
        "82f480988f49d464f0f2c507f2f1a8c6",
    "@ros2_lv/0/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
    "std_msgs::msg::dds_::String_/" + PUBLISHED["std_msgs/msg/String"] + "/::,7:,:,:,,":
        "eb85fa883b7846dc448a4501890ad062",
}


@pytest.mark.parametrize("token", sorted(RMW_ZENOH_GIDS))
def test_the_gid_is_rmw_zenohs_xxh3_128_of_the_token(token):
    assert rmw.gid(token).hex() == RMW_ZENOH_GIDS[token]


def test_the_gid_of_the_documented_talker_is_that_of_its_token():
    node = rmw.Node(0, "8b20917502ee955ac4476e0266340d5c", 0, "/", "talker")
    token = node.publisher_token(10, "/chatter", "std_msgs/msg/String", qos="::,7:,:,:,,")
    assert rmw.gid(token).hex() == "eb85fa883b7846dc448a4501890ad062"
