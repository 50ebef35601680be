"""What ROS 2 may send, live: ``seaway launch sim --ros2 --ros2-writes`` and a ROS 2 publisher written
here from rmw_zenoh's documented format alone (no ``seaway.ros2`` code): a plain Zenoh peer with
its node and publisher liveliness tokens, samples in CDR serialised by ``rosbags`` with rmw_zenoh's
attachment (sequence number, timestamp, the GID as XXH3-128 of the publisher's token).

With writes on, the face's subscription is discovered through its token, a malformed payload is
counted (the face's ``/diagnostics``, read with ``rosbags``) and ignored, and ``pause`` pauses the
mission (``mission/status``). With writes off, the same pause does nothing.
"""

from __future__ import annotations

import struct
import threading
import time

import pytest
import xxhash
import zenoh
from rosbags.typesys import Stores, get_typestore
from seaway.contract import keys
from seaway.runtime import credentials
from seaway.runtime.bus import Bus

from tests.conftest import free_port, wait_for
from tests.system.ros2.independent import dds_name, ros_peer

pytestmark = [pytest.mark.system, pytest.mark.slow]
TS = get_typestore(Stores.ROS2_JAZZY)
DOMAIN = 9
STRING, DIAG, PATH = ("std_msgs/msg/String", "diagnostic_msgs/msg/DiagnosticArray",
                      "nav_msgs/msg/Path")
QOS = "::,:,:,:,,"  # rmw_zenoh's QoS chunk of the default profile



class RosPeer:
    """A ROS 2 node ``/tester`` on its own Zenoh peer (the face connects to it, as to rmw_zenohd):
    liveliness tokens heard, ``/diagnostics`` received, publishers on ``/vessel1/mission/command``
    and ``/vessel1/mission/set_path``."""

    def __init__(self, port: int) -> None:
        self.session = ros_peer(port)
        self.zid = str(self.session.info.zid())
        self.tokens: set[str] = set()
        self.diagnostics: list[bytes] = []
        self.lock = threading.Lock()
        self.keep = [self.session.liveliness().declare_subscriber(
            f"@ros2_lv/{DOMAIN}/**", self._on_token, history=True)]
        diag = f"{DOMAIN}/diagnostics/{dds_name(DIAG)}/{TS.hash_rihs01(DIAG)}"
        self.keep.append(self.session.declare_subscriber(diag, self._on_diag))
        # rmw_zenoh's layout: @ros2_lv/<domain>/<zid>/<nid>/<id>/NN|MP/<enclave>/<ns>/<node>[/...].
        self.keep.append(self.session.liveliness().declare_token(
            f"@ros2_lv/{DOMAIN}/{self.zid}/0/0/NN/%/%/tester"))
        self.pubs = {ros_type: self._publisher(i + 1, topic, ros_type) for i, (topic, ros_type) in
                     enumerate([("vessel1/mission/command", STRING),
                                ("vessel1/mission/set_path", PATH)])}
        self.seq = 0

    def _publisher(self, entity: int, topic: str, ros_type: str):
        token = (f"@ros2_lv/{DOMAIN}/{self.zid}/0/{entity}/MP/%/%/tester/%{topic.replace('/', '%')}/"
                 f"{dds_name(ros_type)}/{TS.hash_rihs01(ros_type)}/{QOS}")
        gid = xxhash.xxh3_128_intdigest(token.encode()).to_bytes(16, "little")
        self.keep.append(self.session.liveliness().declare_token(token))
        pub = self.session.declare_publisher(
            f"{DOMAIN}/{topic}/{dds_name(ros_type)}/{TS.hash_rihs01(ros_type)}")
        return pub, gid

    def _on_token(self, sample: zenoh.Sample) -> None:
        with self.lock:
            if sample.kind == zenoh.SampleKind.PUT:
                self.tokens.add(str(sample.key_expr))
            else:
                self.tokens.discard(str(sample.key_expr))

    def _on_diag(self, sample: zenoh.Sample) -> None:
        with self.lock:
            self.diagnostics.append(sample.payload.to_bytes())

    def subscription(self, fq_topic: str, ros_type: str) -> str | None:
        with self.lock:
            for t in self.tokens:
                c = t.split("/")
                if (len(c) == 13 and c[5] == "MS" and c[9] == fq_topic.replace("/", "%")
                        and c[10] == dds_name(ros_type) and c[11] == TS.hash_rihs01(ros_type)):
                    return t
        return None

    def send(self, payload: bytes, ros_type: str = STRING) -> None:
        pub, gid = self.pubs[ros_type]
        self.seq += 1
        pub.put(payload, attachment=struct.pack("<qqB", self.seq, time.time_ns(), 16) + gid)

    def send_word(self, word: str) -> None:
        self.send(bytes(TS.serialize_cdr(TS.types[STRING](data=word), STRING)))

    def send_path(self, points_enu: list[tuple[float, float]]) -> None:
        t = TS.types
        stamp = t["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
        q = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
        poses = [t["geometry_msgs/msg/PoseStamped"](
            header=t["std_msgs/msg/Header"](stamp=stamp, frame_id="map"),
            pose=t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
                                              orientation=q)) for x, y in points_enu]
        msg = t[PATH](header=t["std_msgs/msg/Header"](stamp=stamp, frame_id="map"), poses=poses)
        self.send(bytes(TS.serialize_cdr(msg, PATH)), PATH)

    def writes_counts(self) -> dict[str, str] | None:
        """The newest ``seaway ros2 writes`` status of ``/diagnostics``, as key -> value."""
        with self.lock:
            raw = list(self.diagnostics)
        for payload in reversed(raw):
            for st in TS.deserialize_cdr(payload, DIAG).status:
                if st.name == "seaway ros2 writes":
                    return {kv.key: kv.value for kv in st.values}
        return None

    def close(self) -> None:
        self.session.close()


class States:
    """``mission/status`` states heard, in order."""

    def __init__(self, bus: Bus) -> None:
        self.sub = bus.subscribe(keys.MISSION_STATUS, mode="fifo")
        self.seen: list[str] = []

    def now(self) -> str | None:
        self.seen += [s.state for s in self.sub.drain()]
        return self.seen[-1] if self.seen else None


def _launch(procs, env, tmp_path, port: int, *extra: str):
    return procs.launch_ready(env, "sim", "--ros2", "--ros2-connect", f"tcp/127.0.0.1:{port}",
                              "--ros2-domain", str(DOMAIN), *extra, "--stay", "--no-report",
                              "--run-dir", str(tmp_path / "run"))


def test_a_ros2_pause_pauses_the_mission_and_a_malformed_one_is_counted(
        tmp_path, zenoh_env, procs) -> None:
    # The stack's rules with the ROS 2 face's writes, as the launcher makes them per run.
    credentials.create(tmp_path / "credentials", harness=True, ros2_writes=True)
    port = free_port()
    ros = RosPeer(port)
    try:
        launcher = _launch(procs, zenoh_env, tmp_path, port, "--ros2-writes")
        wait_for(lambda: ros.subscription("/vessel1/mission/command", STRING), 30,
                 what="the face's subscription token for /vessel1/mission/command")
        with Bus.open("vessel1") as bus:
            status = States(bus)
            wait_for(lambda: status.now() == "active", 90, interval_s=0.2, what="the mission active")

            ros.send(b"\x00\x01\x00\x00\xff\xff\xff\x7f")  # a string claiming 2 GiB: malformed
            counts = wait_for(lambda: (c := ros.writes_counts()) and c.get("dropped_malformed") == "1"
                              and c, 20, interval_s=0.2, what="the malformed sample counted")
            assert counts["sent"] == "0"
            assert status.now() == "active"  # ignored

            ros.send_word("pause")
            wait_for(lambda: status.now() == "paused", 20, interval_s=0.1,
                     what="mission/status paused after ROS 2's pause")
            counts = wait_for(lambda: (c := ros.writes_counts()) and c["accepted"] == "1" and c, 20,
                              interval_s=0.2, what="the pause counted as accepted")
            assert counts["dropped"] == "1" and counts["received"] == "2"

            # Absurd missions: the controller's own checks refuse them, the face counts it.
            ros.send_path([(0.0, 0.0), (1e6, 0.0)])  # 1000 km east
            ros.send_path([(float(i % 2), float(i)) for i in range(2000)])  # 2000 waypoints
            counts = wait_for(lambda: (c := ros.writes_counts()) and c["refused"] == "2" and c, 30,
                              interval_s=0.2, what="both absurd paths refused")
            assert counts["sent"] == "3" and counts["accepted"] == "1"
            assert status.now() == "paused"  # the mission was not replaced
        assert launcher.poll() is None
        procs.stop(launcher, timeout_s=30)
    finally:
        ros.close()


def test_without_writes_the_same_pause_does_nothing(tmp_path, zenoh_env, procs) -> None:
    port = free_port()
    ros = RosPeer(port)
    try:
        launcher = _launch(procs, zenoh_env, tmp_path, port)
        wait_for(lambda: ros.writes_counts() is not None or any(
            t.endswith("/%vessel1/seaway_bridge") for t in list(ros.tokens)), 30,
            what="the face's node")
        with Bus.open("vessel1") as bus:
            status = States(bus)
            wait_for(lambda: status.now() == "active", 90, interval_s=0.2, what="the mission active")
            heard = len(status.seen)
            for _ in range(10):  # over several seconds, so a slow path would have had its chance
                ros.send_word("pause")
                time.sleep(0.5)
            n = len(ros.diagnostics)
            wait_for(lambda: len(ros.diagnostics) >= n + 2, 20, what="diagnostics after the pauses")
            status.now()
        assert len(status.seen) > heard + 2
        assert set(status.seen[heard - 1:]) == {"active"}, status.seen
        assert ros.subscription("/vessel1/mission/command", STRING) is None
        assert ros.writes_counts() is None
        procs.stop(launcher, timeout_s=30)
    finally:
        ros.close()
