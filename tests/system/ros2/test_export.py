"""``seaway export ros2`` through the real command, read back with ``rosbags``: its rosbag2 reader
(the ros2msg schemas, the CDR) message for message against the Seaway messages recorded; the bag
as rosbag2_storage_mcap reads it (one serialization format, a schema per channel, the ``rosbag2``
metadata record); and the rest of the recording kept as it was in the file beside it."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML
from seaway.contract import keys
from seaway.recording import reader

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent
RECORDING = Path(__file__).resolve().parents[2] / "replay" / "data" / "lake-30s.mcap"


def _export(out: Path, *extra: str) -> str:
    done = subprocess.run([str(BIN / "seaway"), "export", "ros2", str(RECORDING), str(out), *extra],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def _stamp(h) -> int:
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


def test_rosbags_reads_every_cdr_channel_message_for_message(tmp_path) -> None:
    out = tmp_path / "ros2.mcap"
    _export(out)  # the default export: rosbags reads it as it is
    dec = reader.decode_vessel([RECORDING], None, [keys.NAV_STATE.suffix, keys.GNSS.suffix,
                                                   keys.THRUST.suffix])
    states, fixes, thrusts = (dec.get(k.suffix) for k in (keys.NAV_STATE, keys.GNSS, keys.THRUST))
    got: dict[str, list] = {}
    with AnyReader([out]) as bag:
        assert {c.topic: c.msgtype for c in bag.connections} == {
            "/replay1/odom": "nav_msgs/msg/Odometry", "/replay1/gnss/fix": "sensor_msgs/msg/NavSatFix",
            "/replay1/thrust/wrench": "geometry_msgs/msg/WrenchStamped"}
        for con, _t, raw in bag.messages():
            got.setdefault(con.topic, []).append(bag.deserialize(raw, con.msgtype))
    assert len(got["/replay1/odom"]) == len(states) > 100
    for o, s in zip(got["/replay1/odom"], states, strict=True):
        assert _stamp(o.header) == s.stamp_ns
        p = o.pose.pose.position
        assert (p.x, p.y) == pytest.approx((s.y_m, s.x_m), abs=1e-9)
        assert 2 * math.atan2(o.pose.pose.orientation.z, o.pose.pose.orientation.w) == pytest.approx(
            math.atan2(math.cos(s.psi_rad), math.sin(s.psi_rad)), abs=1e-9)
        assert o.twist.twist.linear.x == pytest.approx(s.u_mps, abs=1e-9)
    assert len(got["/replay1/gnss/fix"]) == len(fixes) > 50
    for f, g in zip(got["/replay1/gnss/fix"], fixes, strict=True):
        assert (f.latitude, f.longitude) == pytest.approx(
            (math.degrees(g.lat_rad), math.degrees(g.lon_rad)), abs=1e-12)
    assert len(got["/replay1/thrust/wrench"]) == len(thrusts) > 100
    for w, t in zip(got["/replay1/thrust/wrench"], thrusts, strict=True):
        assert w.wrench.force.x == pytest.approx(t.thrust_port_n + t.thrust_starboard_n, abs=1e-9)


def test_the_bag_is_what_rosbag2_reads_and_the_rest_is_kept_beside_it(tmp_path) -> None:
    out = tmp_path / "full.mcap"
    said = _export(out)
    rest = tmp_path / "full.seaway.mcap"
    assert str(rest) in said
    store = get_typestore(Stores.EMPTY)
    counts: dict[str, int] = {}
    with open(out, "rb") as fh:
        r = make_reader(fh)
        assert r.get_header().profile == "ros2"
        summary = r.get_summary()
        assert summary is not None
        # rosbag2's SequentialReader::open: one serialization format; MCAPStorage::read_metadata:
        # every channel has a schema.
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        assert all(c.schema_id in summary.schemas for c in summary.channels.values())
        for schema, channel, msg in r.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            assert schema.encoding == "ros2msg" and "offered_qos_profiles" in channel.metadata
            if schema.name not in store.fielddefs:
                from rosbags.typesys import get_types_from_msg

                for part in schema.data.decode().split("=" * 80 + "\n"):
                    head, _, body = part.partition("\n")
                    store.register(get_types_from_msg(body, head[5:].replace("/", "/msg/"))
                                   if head.startswith("MSG: ") else
                                   get_types_from_msg(part, schema.name))
            store.deserialize_cdr(msg.data, schema.name)
        meta = {m.name: m.metadata for m in r.iter_metadata()}
        assert not list(r.iter_attachments())
    # The metadata record rosbag2 writes, its YAML read by a YAML parser, agreeing with the file.
    assert set(meta) == {"rosbag2"} and meta["rosbag2"]["ROS_DISTRO"] == "jazzy"
    bag = YAML(typ="safe").load(meta["rosbag2"]["serialized_metadata"])
    assert bag["storage_identifier"] == "mcap" and bag["ros_distro"] == "jazzy"
    assert bag["relative_file_paths"] == [out.name]
    assert bag["message_count"] == sum(counts.values())
    assert {t["topic_metadata"]["name"]: t["message_count"]
            for t in bag["topics_with_message_count"]} == counts
    for t in bag["topics_with_message_count"]:
        tm = t["topic_metadata"]
        assert tm["serialization_format"] == "cdr"
        assert tm["type_description_hash"] == get_typestore(Stores.ROS2_JAZZY).hash_rihs01(tm["type"])

    info = reader.read_info([RECORDING])
    kept: dict[str, int] = {}
    with open(rest, "rb") as fh:
        r = make_reader(fh)
        for _schema, channel, _msg in r.iter_messages():
            kept[channel.topic] = kept.get(channel.topic, 0) + 1
        atts = {a.name for a in r.iter_attachments()}
    assert kept == info.topics  # every recorded message kept, nothing else
    assert set(info.attachments) <= atts
    assert counts["/replay1/odom"] == info.topics["seaway/replay1/nav/state"]


def test_only_ros2_writes_no_companion(tmp_path) -> None:
    out = tmp_path / "bag.mcap"
    _export(out, "--only-ros2")
    assert out.exists() and not (tmp_path / "bag.seaway.mcap").exists()
