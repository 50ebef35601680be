"""The ROS 2 face, live: ``seaway launch sim --ros2`` and a ROS 2 subscriber written here, from
rmw_zenoh's documented format alone (no ``seaway.ros2`` code), with ``rosbags``' type store for the
type hashes and its CDR deserialiser for the payloads.

The subscriber is a plain Zenoh peer listening on a loopback port of its own, where the face
connects as it would to ``rmw_zenohd``. It finds the node and its publishers through their
liveliness tokens under ``@ros2_lv/<domain>/``, subscribes to the key expression each publisher's
token names (``<domain>/<topic>/<pkg>::msg::dds_::<Name>_/<RIHS01 hash>``), and checks Odometry
against ``nav/state`` and the mission's Path against ``mission/accepted``, heard on Seaway's bus.
"""

from __future__ import annotations

import math
import struct
import threading

import pytest
import zenoh
from rosbags.typesys import Stores, get_typestore
from seaway.contract import keys
from seaway.runtime.bus import Bus

from tests.conftest import free_port, wait_for
from tests.system.ros2.independent import dds_name, ros_peer

pytestmark = [pytest.mark.system, pytest.mark.slow]
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
DOMAIN = 7
ODOM, PATH = "nav_msgs/msg/Odometry", "nav_msgs/msg/Path"



class RosListener:
    """Liveliness tokens and samples heard on ROS 2's side, by key."""

    def __init__(self, port: int) -> None:
        self.session = ros_peer(port)
        self.tokens: set[str] = set()
        self.samples: dict[str, list[tuple[bytes, bytes | None]]] = {}
        self.lock = threading.Lock()
        self._subs = [self.session.liveliness().declare_subscriber(
            f"@ros2_lv/{DOMAIN}/**", self._on_token, history=True)]

    def _on_token(self, sample: zenoh.Sample) -> None:
        with self.lock:
            if sample.kind == zenoh.SampleKind.PUT:
                self.tokens.add(str(sample.key_expr))
            else:
                self.tokens.discard(str(sample.key_expr))

    def publisher(self, fq_topic: str, ros_type: str) -> list[str] | None:
        """The chunks of the publisher token of ``fq_topic``, per the documented layout:
        @ros2_lv/<domain>/<zid>/<nid>/<id>/MP/<enclave>/<ns>/<node>/<topic>/<type>/<hash>/<qos>."""
        with self.lock:
            for t in self.tokens:
                c = t.split("/")
                if (len(c) == 13 and c[5] == "MP" and c[9] == fq_topic.replace("/", "%")
                        and c[10] == dds_name(ros_type)):
                    return c
        return None

    def subscribe(self, key: str) -> None:
        self.samples[key] = []

        def on(sample: zenoh.Sample) -> None:
            att = sample.attachment
            with self.lock:
                self.samples[key].append((sample.payload.to_bytes(),
                                          None if att is None else att.to_bytes()))

        self._subs.append(self.session.declare_subscriber(key, on))

    def close(self) -> None:
        self.session.close()


def test_ros2_subscriber_discovers_and_receives_odometry_and_the_mission_path(
        tmp_path, zenoh_env, procs) -> None:
    port = free_port()
    ros = RosListener(port)
    try:
        launcher = procs.launch_ready(zenoh_env, "sim", "--ros2", "--ros2-connect",
                                      f"tcp/127.0.0.1:{port}", "--ros2-domain", str(DOMAIN),
                                      "--stay", "--no-report", "--run-dir", str(tmp_path / "run"))
        # Discovery through liveliness: the node, then a publisher per topic with its type hash.
        node = wait_for(lambda: next((t for t in list(ros.tokens) if t.split("/")[5:6] == ["NN"]
                                      and t.endswith("/%vessel1/seaway_bridge")), None),
                        30, what="the node's liveliness token")
        assert node.startswith(f"@ros2_lv/{DOMAIN}/")
        chunks = {}
        for topic, ros_type in (("/vessel1/odom", ODOM), ("/vessel1/mission/path", PATH)):
            c = wait_for(lambda t=topic, r=ros_type: ros.publisher(t, r), 30, what=f"{topic}'s token")
            assert c[11] == TYPESTORE.hash_rihs01(ros_type), (topic, c[11])
            assert c[2] == node.split("/")[2]  # the same session (zid) as the node
            key = f"{DOMAIN}/{topic.strip('/')}/{c[10]}/{c[11]}"
            ros.subscribe(key)
            chunks[ros_type] = key

        with Bus.open("vessel1") as bus:
            states = bus.subscribe(keys.NAV_STATE, mode="fifo")
            accepted = bus.subscribe(keys.MISSION_ACCEPTED, mode="fifo")
            heard: dict[int, object] = {}

            def matched() -> int:
                for s in states.drain():
                    heard[s.stamp_ns] = s
                with ros.lock:
                    odoms = list(ros.samples[chunks[ODOM]])
                return sum(1 for p, _ in odoms
                           if _stamp(TYPESTORE.deserialize_cdr(p, ODOM).header) in heard)

            wait_for(lambda: matched() >= 20, 60, interval_s=0.2, what="20 odometry samples matched")
            mission = wait_for(lambda: accepted.latest(), 30, what="mission/accepted")
            wait_for(lambda: ros.samples[chunks[PATH]], 30, what="a mission path sample")

        # Odometry == nav/state, converted NED/FRD -> ENU/FLU.
        with ros.lock:
            odoms = list(ros.samples[chunks[ODOM]])
        checked = 0
        seqs = []
        for payload, att in odoms:
            msg = TYPESTORE.deserialize_cdr(payload, ODOM)
            s = heard.get(_stamp(msg.header))
            assert att is not None and len(att) == 33 and att[16] == 16, att
            seqs.append(struct.unpack_from("<q", att)[0])
            if s is None:
                continue
            p, q, tw = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
            assert (msg.header.frame_id, msg.child_frame_id) == ("map", "base_link")
            assert p.x == pytest.approx(s.y_m, abs=1e-9) and p.y == pytest.approx(s.x_m, abs=1e-9)
            yaw = 2 * math.atan2(q.z, q.w)
            assert math.remainder(yaw - (math.pi / 2 - s.psi_rad), 2 * math.pi) == pytest.approx(0, abs=1e-9)
            assert tw.linear.x == pytest.approx(s.u_mps, abs=1e-9)
            assert tw.linear.y == pytest.approx(-s.v_mps, abs=1e-9)
            assert tw.angular.z == pytest.approx(-s.r_radps, abs=1e-9)
            checked += 1
        assert checked >= 20
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)

        # The mission's path == mission/accepted's waypoints, (north, east) -> (x east, y north).
        with ros.lock:
            payload, _ = ros.samples[chunks[PATH]][-1]
        path = TYPESTORE.deserialize_cdr(payload, PATH)
        assert path.header.frame_id == "map"
        got = [c for ps in path.poses for c in (ps.pose.position.x, ps.pose.position.y)]
        want = [c for n, e in mission.waypoints_m() for c in (e, n)]
        assert got == pytest.approx(want, abs=1e-9)
        procs.stop(launcher, timeout_s=30)
    finally:
        ros.close()


def _stamp(header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
