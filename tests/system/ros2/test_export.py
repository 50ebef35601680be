"""``seaway export ros2`` through the real command, read back with ``rosbags``: its rosbag2 reader
(the ros2msg schemas, the CDR) message for message against the Seaway messages recorded, and the
full export's JSON channels kept as they were."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore
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
    _export(out, "--only-ros2")
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


def test_the_full_export_keeps_the_recording_and_adds_ros2_channels(tmp_path) -> None:
    out = tmp_path / "full.mcap"
    _export(out)
    store = get_typestore(Stores.EMPTY)
    counts: dict[str, int] = {}
    with open(out, "rb") as fh:
        r = make_reader(fh)
        assert r.get_header().profile == "ros2"
        for schema, channel, msg in r.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.message_encoding == "cdr":
                assert schema.encoding == "ros2msg" and "offered_qos_profiles" in channel.metadata
                if schema.name not in store.fielddefs:
                    from rosbags.typesys import get_types_from_msg

                    for part in schema.data.decode().split("=" * 80 + "\n"):
                        head, _, body = part.partition("\n")
                        store.register(get_types_from_msg(body, head[5:].replace("/", "/msg/"))
                                       if head.startswith("MSG: ") else
                                       get_types_from_msg(part, schema.name))
                store.deserialize_cdr(msg.data, schema.name)
        atts = {a.name for a in r.iter_attachments()}
    info = reader.read_info([RECORDING])
    assert {t: counts[t] for t in info.topics} == info.topics  # every JSON message kept
    assert set(info.attachments) <= atts
    assert counts["/replay1/odom"] == info.topics["seaway/replay1/nav/state"]
