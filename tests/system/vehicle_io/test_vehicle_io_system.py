"""vehicle_io as a real process: real UDP MAVLink bytes, real Zenoh, real peers.

Two kinds of autopilot on the other end of the UDP link:

* ``seaway-sim`` (the project's simulator, PX4-like, real time): the end-to-end criteria. Its
  ``sim/truth`` says what thrust the plant actually got, so thrust is checked in newtons at the
  vessel, not only as MAVLink numbers. Skipped, saying why, if ``seaway-sim`` is not installed.
* ``seaway_lab.fake_autopilot.FakeAutopilot`` (a scripted MAVLink peer, in this process or as its own
  process): it records each MANUAL_CONTROL's arrival time, so the watchdog is measured at the
  MAVLink side, and it can send garbage and out-of-range fields.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    ArmRequest,
    Attitude,
    GnssFix,
    LocalPosition,
    ModeRequest,
    SimTruth,
    ThrustCommand,
)
from seaway.runtime.bus import Bus
from seaway_lab.fake_autopilot import ARDUPILOT_DEFAULT_PARAMS, FakeAutopilot
from seaway_vehicle_io.config import SOURCE_SYSTEM
from seaway_vehicle_io.mav import mavlink

from tests.conftest import BIN, PYTHON, Procs, wait_for

pytestmark = pytest.mark.system

VIO = BIN / "seaway-vehicle-io"
SIM = BIN / "seaway-sim"
needs_sim = pytest.mark.skipif(not SIM.exists(), reason=f"{SIM} is not installed (services/sim)")

PERIOD_S = 0.05  # vehicle_io's MANUAL_CONTROL period at the default 20 Hz
TIMEOUT_S = 0.3  # the watchdog's default
HEARTBEAT_TIMEOUT_S = 1.5  # shortened (from 3 s) to keep the fault tests quick
REQUEST_TIMEOUT_S = 5.0  # longer than 3 COMMAND_LONG attempts of 1 s


def udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_vio(procs: Procs, env: dict[str, str], tmp: Path, url: str, **cfg: object):
    lines = [f'mavlink = "{url}"', f"heartbeat_timeout_s = {HEARTBEAT_TIMEOUT_S}"]
    lines += [f"{k} = {json.dumps(v)}" for k, v in cfg.items()]
    path = tmp / f"vio-{len(procs.procs)}.toml"
    path.write_text("\n".join(lines) + "\n")
    # The same run as the simulator's default (the lake scenario: paper-boat's 75 N thrusters), so the
    # two processes agree on the run (seaway.runtime.run) and the thrust mapping is the boat's.
    return procs.start([str(VIO), "--config", str(path), "--scenario", "lake"], env,
                       name=f"vio-{len(procs.procs)}")


def start_sim(procs: Procs, env: dict[str, str], port: int, name: str = "sim"):
    return procs.start([str(SIM), "--mavlink", f"udpin:127.0.0.1:{port}"], env, name=name)


def thrust(t1: float, t2: float) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=time.time_ns(), thrust_port_n=t1, thrust_starboard_n=t2,
                              source="test")


class Watch:
    """Messages of one key, in arrival order, and a wait for the first one that satisfies a
    condition.

    ``wait`` looks only at messages that arrive after it is called, unless ``keep=True``: then it
    also looks at everything since the last ``clear()`` (for a message that may already be in).
    """

    def __init__(self, bus: Bus, spec: keys.KeySpec) -> None:
        self.sub = bus.subscribe(spec, mode="fifo")
        self.seen: list = []

    def wait(self, pred, timeout_s: float, what: str, keep: bool = False):
        if not keep:
            self.clear()

        def check():
            self.seen.extend(self.sub.drain())
            return next((m for m in self.seen if pred(m)), None)
        return wait_for(check, timeout_s, what=what)

    def clear(self) -> None:
        self.sub.drain()
        self.seen.clear()


def arm(bus: Bus, on: bool = True):
    return bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=on),
                       timeout_s=REQUEST_TIMEOUT_S)


def mode(bus: Bus, name: str):
    return bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(), mode=name),
                       timeout_s=REQUEST_TIMEOUT_S)


def alive(p: subprocess.Popen, procs: Procs) -> None:
    assert p.poll() is None, f"vehicle_io exited ({p.returncode}):\n{procs.log(p)[-3000:]}"


# =============================================================================================
# Against the simulator (seaway-sim, PX4-like, real time)
# =============================================================================================


@needs_sim
def test_sim_arm_mode_thrust_out_and_telemetry_in(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    start_sim(procs, zenoh_env, port)
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    truth = Watch(bus, keys.SIM_TRUTH)
    gnss, att, lpos = (Watch(bus, k) for k in (keys.GNSS, keys.ATTITUDE, keys.LOCAL_POSITION))
    status.wait(lambda s: s.link_ok and s.autopilot == "px4" and s.mode == "HOLD", 15,
                "vehicle_io to see the sim's PX4 heartbeat (PX4 boots in Hold)")

    # telemetry in: the sim's sensors reach the bus only through vehicle_io, in SI units
    fix: GnssFix = gnss.wait(lambda m: True, 5, "a GnssFix")
    assert math.isclose(math.degrees(fix.lat_rad), 28.18, abs_tol=0.01)  # lake.toml origin
    assert math.isclose(math.degrees(fix.lon_rad), 112.94, abs_tol=0.01)
    assert abs(fix.stamp_ns - time.time_ns()) < 2e9
    a: Attitude = att.wait(lambda m: True, 5, "an Attitude")
    assert -math.pi <= a.yaw_rad <= math.pi
    assert isinstance(lpos.wait(lambda m: True, 5, "a LocalPosition"), LocalPosition)

    # arming only on request; thrust is withheld while disarmed
    pub = bus.publisher(keys.THRUST)
    for _ in range(6):
        pub.put(thrust(30.0, -20.0))
        time.sleep(PERIOD_S)
    t = truth.wait(lambda m: True, 3, "sim truth")
    assert (t.thrust_port_n, t.thrust_starboard_n) == (0.0, 0.0)
    assert mode(bus, "MANUAL").accepted  # from Hold, where the thrusters would be withheld
    reply = arm(bus)
    assert reply.accepted, reply.reason
    assert reply.detail["result"] == "ACCEPTED"
    status.wait(lambda s: s.armed, 3, "armed status")

    # thrust out: newtons at the vessel equal the command (within the wire's resolution)
    truth.clear()
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        pub.put(thrust(30.0, -20.0))
        time.sleep(PERIOD_S)
    t = truth.wait(lambda m: abs(m.thrust_port_n - 30.0) < 0.3, 3, "port thrust 30 N at the plant",
                   keep=True)
    assert t.thrust_starboard_n == pytest.approx(-20.0, abs=0.3)

    # mode changes only on request, answered from the COMMAND_ACK
    reply = mode(bus, "HOLD")
    assert reply.accepted, reply.reason
    status.wait(lambda s: s.mode == "HOLD", 3, "HOLD in status")
    reply = mode(bus, "OFFBOARD")  # the sim refuses modes it does not implement
    assert not reply.accepted and "TEMPORARILY_REJECTED" in reply.reason
    reply = mode(bus, "WARP")  # not a PX4 mode: refused without bothering the autopilot
    assert not reply.accepted and "no mode" in reply.reason
    assert mode(bus, "MANUAL").accepted
    assert arm(bus, False).accepted
    status.wait(lambda s: not s.armed, 3, "disarmed status")
    alive(vio, procs)


@needs_sim
def test_sim_watchdog_stops_the_thrusters_and_commands_resume(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    start_sim(procs, zenoh_env, port)
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    truth = Watch(bus, keys.SIM_TRUTH)
    status.wait(lambda s: s.link_ok, 15, "link")
    assert mode(bus, "MANUAL").accepted  # the sim, like PX4, boots in Hold
    assert arm(bus).accepted
    pub = bus.publisher(keys.THRUST)
    truth.clear()
    status.clear()
    for _ in range(20):
        pub.put(thrust(25.0, 25.0))
        time.sleep(PERIOD_S)
    truth.wait(lambda m: m.thrust_port_n > 24.0, 3, "thrust applied", keep=True)
    status.wait(lambda s: s.failsafe is None, 2, "no failsafe while commands flow", keep=True)
    t_stop = time.time_ns()
    truth.clear()
    stopped: SimTruth = truth.wait(lambda m: m.thrust_port_n == 0.0 and m.thrust_starboard_n == 0.0,
                                   3, "zero thrust at the plant", keep=True)
    # sim truth is published every 0.1 s: allow that on top of timeout + one period
    assert (stopped.stamp_ns - t_stop) / 1e9 <= TIMEOUT_S + PERIOD_S + 0.1 + 0.05
    s = status.wait(lambda s: s.failsafe == "thrust_stale", 2, "failsafe thrust_stale")
    # vehicle_io's neutral stream keeps the autopilot's own loss failsafe from firing
    time.sleep(1.0)
    s = status.wait(lambda s: s.failsafe == "thrust_stale", 2, "status")
    assert s.armed and s.mode == "MANUAL"
    # commands return: thrust resumes, failsafe cleared
    truth.clear()
    status.clear()
    for _ in range(10):
        pub.put(thrust(25.0, 25.0))
        time.sleep(PERIOD_S)
    truth.wait(lambda m: m.thrust_port_n > 24.0, 3, "thrust resumed", keep=True)
    status.wait(lambda s: s.failsafe is None, 2, "failsafe cleared", keep=True)
    alive(vio, procs)


@needs_sim
def test_sim_killed_and_restarted_vehicle_io_reconnects(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    sim = start_sim(procs, zenoh_env, port)
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpout:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    status.wait(lambda s: s.link_ok, 15, "link")
    os.killpg(sim.pid, signal.SIGKILL)
    sim.wait(5)
    t_kill = time.monotonic()
    status.clear()
    status.wait(lambda s: not s.link_ok, HEARTBEAT_TIMEOUT_S + 2.5, "link_ok False")
    assert time.monotonic() - t_kill >= HEARTBEAT_TIMEOUT_S - 1.0  # not before the timeout
    status.clear()
    start_sim(procs, zenoh_env, port, name="sim-restarted")
    status.wait(lambda s: s.link_ok and s.autopilot == "px4", 15, "link relearnt")
    assert arm(bus).accepted  # the new autopilot is commanded, no restart of vehicle_io
    alive(vio, procs)


# =============================================================================================
# Against the scripted peer (real UDP; arrival times measured at the MAVLink side)
# =============================================================================================


def test_peer_arm_mode_thrust_and_telemetry(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    gnss = Watch(bus, keys.GNSS)
    with FakeAutopilot(("127.0.0.1", port)) as peer:
        s = status.wait(lambda s: s.link_ok and s.battery_voltage_v is not None, 15, "link")
        assert (s.autopilot, s.mode, s.armed) == ("px4", "MANUAL", False)
        assert s.battery_voltage_v == pytest.approx(16.2)
        assert s.battery_remaining_frac == pytest.approx(0.87)
        fix = gnss.wait(lambda m: m.fix_type == 3, 5, "a GnssFix qualified by GPS_RAW_INT")
        assert math.degrees(fix.lat_rad) == pytest.approx(47.397742, abs=1e-9)
        assert math.degrees(fix.lon_rad) == pytest.approx(8.545594, abs=1e-9)
        assert (fix.alt_m, fix.vel_n_mps, fix.vel_e_mps) == pytest.approx((488.0, 1.5, -0.5))
        assert (fix.horizontal_std_m, fix.satellites) == (pytest.approx(1.2), 12)

        peer.refuse_arm_result = 1
        reply = arm(bus)
        assert not reply.accepted and reply.detail["result"] == "TEMPORARILY_REJECTED"
        peer.refuse_arm_result = None
        assert arm(bus).accepted and peer.armed
        assert mode(bus, "HOLD").accepted and peer.mode == "HOLD"
        assert mode(bus, "MANUAL").accepted and peer.mode == "MANUAL"
        sent_commands = len(peer.commands)
        assert not mode(bus, "WARP").accepted
        assert len(peer.commands) == sent_commands  # nothing sent for a refused name
        # no command that acts on the vehicle was ever sent that the test did not ask for; of its
        # own accord vehicle_io only asks for telemetry rates (511) and the events metadata (512)
        own = {511: 6, 512: 1}
        assert [c for c, _ in peer.commands if c not in own] == [400, 400, 176, 176]
        assert {c: n for c in own if (n := sum(x == c for x, _ in peer.commands))} == own

        pub = bus.publisher(keys.THRUST)
        t0 = time.monotonic_ns()
        pub.put(thrust(30.0, -20.0))
        rec = wait_for(lambda: next((r for r in peer.manual_controls_since(t0)
                                     if (r.y, r.z) == (333, 533)), None), 2, what="MANUAL_CONTROL")
        assert (rec.target, rec.x, rec.r, rec.src_system) == (1, 0, 0, SOURCE_SYSTEM)
    alive(vio, procs)


def test_peer_watchdog_zero_thrust_within_timeout_plus_one_period(zenoh_env, procs, bus,
                                                                   tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    with FakeAutopilot(("127.0.0.1", port), armed=True) as peer:
        status.wait(lambda s: s.link_ok and s.armed, 15, "link")
        pub = bus.publisher(keys.THRUST)
        commanded = (0, 700)  # 30 N each side of a 75 N thruster: L = R = 0.4
        neutral = (0, 500)
        t_last = 0
        for _ in range(20):
            pub.put(thrust(30.0, 30.0))
            t_last = time.monotonic_ns()  # same clock as the peer's arrival stamps
            time.sleep(PERIOD_S)
        wait_for(lambda: any((r.y, r.z) == neutral for r in peer.manual_controls_since(t_last)),
                 2, what="neutral MANUAL_CONTROL")
        recs = peer.manual_controls_since(t_last)
        first_neutral = next(r for r in recs if (r.y, r.z) == neutral)
        before = [r for r in recs if r.arrival_mono_ns < first_neutral.arrival_mono_ns]
        assert before and all((r.y, r.z) == commanded for r in before)  # held until the timeout
        latency_s = (first_neutral.arrival_mono_ns - t_last) / 1e9
        print(f"watchdog: first neutral MANUAL_CONTROL {latency_s * 1e3:.1f} ms after the last put")
        assert TIMEOUT_S <= latency_s <= TIMEOUT_S + PERIOD_S, latency_s
        s = status.wait(lambda s: s.failsafe == "thrust_stale", 2, "failsafe thrust_stale")
        assert s.armed
        # the stream goes on, neutral, so the autopilot's loss failsafe is not tripped
        time.sleep(0.5)
        later = peer.manual_controls_since(first_neutral.arrival_mono_ns + 100_000_000)
        assert len(later) >= 5 and all((r.y, r.z) == neutral for r in later)
        # commands resume: thrust resumes at once
        status.clear()
        t_resume = time.monotonic_ns()
        pub.put(thrust(30.0, 30.0))
        rec = wait_for(lambda: next((r for r in peer.manual_controls_since(t_resume)
                                     if (r.y, r.z) == commanded), None), 1, what="resumed thrust")
        # At the latest with the next tick (one period); a second one is the margin for a busy
        # machine, where this process's own threads (the put, the peer's receive) wait their turn.
        assert (rec.arrival_mono_ns - t_resume) / 1e9 < 2 * PERIOD_S
        status.wait(lambda s: s.failsafe is None, 2, "failsafe cleared", keep=True)
    alive(vio, procs)


def test_peer_process_killed_and_restarted(zenoh_env, procs, bus, tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)

    def start_peer(sysid: int, record: Path):
        return procs.start([PYTHON, "-m", "seaway_lab.fake_autopilot", "--to", f"127.0.0.1:{port}",
                            "--sysid", str(sysid), "--record", str(record)], zenoh_env,
                           name=f"peer-{sysid}")

    def records(path: Path) -> list[dict]:
        return [json.loads(x) for x in path.read_text().splitlines()] if path.exists() else []

    peer = start_peer(1, tmp_path / "mc1.jsonl")
    status.wait(lambda s: s.link_ok, 15, "link to peer 1")
    wait_for(lambda: records(tmp_path / "mc1.jsonl"), 3, what="MANUAL_CONTROL at peer 1")
    os.killpg(peer.pid, signal.SIGKILL)
    peer.wait(5)
    status.clear()
    status.wait(lambda s: not s.link_ok and s.autopilot == "unknown", HEARTBEAT_TIMEOUT_S + 2.5,
                "link_ok False after the kill")
    # restarted, as another system id: relearnt without restarting vehicle_io
    start_peer(2, tmp_path / "mc2.jsonl")
    status.wait(lambda s: s.link_ok, 15, "link to peer 2")
    recs = wait_for(lambda: records(tmp_path / "mc2.jsonl"), 3, what="MANUAL_CONTROL at peer 2")
    assert {r["target"] for r in recs} == {2}
    alive(vio, procs)


def test_peer_garbage_and_out_of_range_fields_are_counted_and_dropped(zenoh_env, procs, bus,
                                                                       tmp_path):
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    att = Watch(bus, keys.ATTITUDE)
    with FakeAutopilot(("127.0.0.1", port), telemetry=False) as peer:
        status.wait(lambda s: s.link_ok, 15, "link")
        base = status.wait(lambda s: True, 2, "status").dropped_messages
        assert base == 0
        peer.send_raw(b"\xfd\x10not mavlink at all" * 4)
        peer.send_raw(bytes(range(256)))
        t = peer.time_boot_ms()
        peer.send(mavlink.MAVLink_attitude_message(t, 0.0, 0.0, float("nan"), 0.0, 0.0, 0.0))
        peer.send(mavlink.MAVLink_global_position_int_message(t, 950_000_000, 0, 0, 0, 0, 0, 0, 0))
        peer.send(mavlink.MAVLink_attitude_message(t, 0.0, 0.0, 0.0, 99.0, 0.0, 0.0))
        s = status.wait(lambda s: s.dropped_messages >= 4, 3, "dropped messages counted")
        assert s.link_ok
        # nothing from the bad messages was published; a good one still is
        att.clear()
        peer.send(mavlink.MAVLink_attitude_message(peer.time_boot_ms(), 0.0, 0.0, 1.25, 0, 0, 0))
        good = att.wait(lambda m: True, 3, "a good Attitude after the garbage", keep=True)
        assert good.yaw_rad == pytest.approx(1.25) and good.roll_rate_radps == 0.0
        assert all(m.yaw_rad == pytest.approx(1.25) for m in att.seen)
    alive(vio, procs)
    log = procs.log(vio)
    assert "dropped ATTITUDE (field yaw)" in log
    assert "dropped GLOBAL_POSITION_INT (field lat)" in log
    assert "dropped ATTITUDE (field rollspeed)" in log
    assert "dropped BAD_DATA" in log


class TcpAutopilot:
    """One accepted TCP connection playing a PX4: heartbeats out, MANUAL_CONTROL counted in."""

    def __init__(self, server: socket.socket, sysid: int = 1) -> None:
        server.settimeout(15.0)
        self.conn, _ = server.accept()
        self.conn.settimeout(0.1)
        self.mav = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=1)
        self.parser = mavlink.MAVLink(None)
        self.parser.robust_parsing = True
        self.manual_controls = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        next_hb = 0.0
        while not self._stop.is_set():
            if time.monotonic() >= next_hb:
                hb = mavlink.MAVLink_heartbeat_message(10, 12, 1, 1 << 16, 4, 3)
                try:
                    self.conn.sendall(hb.pack(self.mav))
                except OSError:
                    return
                next_hb = time.monotonic() + 0.5
            try:
                data = self.conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not data:
                return
            for m in self.parser.parse_buffer(data) or []:
                if m.get_type() == "MANUAL_CONTROL":
                    self.manual_controls += 1

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.conn.close()


def test_tcp_transport_reopened_after_the_autopilot_closes_it(zenoh_env, procs, bus, tmp_path):
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    port = server.getsockname()[1]
    vio = start_vio(procs, zenoh_env, tmp_path, f"tcp:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    try:
        first = TcpAutopilot(server)
        status.wait(lambda s: s.link_ok, 15, "link over TCP")
        wait_for(lambda: first.manual_controls > 0, 3, what="MANUAL_CONTROL over TCP")
        first.close()  # the autopilot end goes away (EOF for vehicle_io)
        second = TcpAutopilot(server)  # vehicle_io connects again by itself
        wait_for(lambda: second.manual_controls > 0, 5, what="MANUAL_CONTROL on the new connection")
        second.close()
    finally:
        server.close()
    alive(vio, procs)
    assert "MAVLink transport broke" in procs.log(vio)


def test_peer_ardupilot_mapping_and_a_blocking_parameter(zenoh_env, procs, bus, tmp_path):
    """ArduPilot over the wire: Two-Paddles axes; then an autopilot whose PILOT_STEER_TYPE would
    turn those axes into steering/throttle gets neutral only, and the status says why."""
    port = udp_port()
    vio = start_vio(procs, zenoh_env, tmp_path, f"udpin:127.0.0.1:{port}")
    status = Watch(bus, keys.VEHICLE_STATUS)
    pub = bus.publisher(keys.THRUST)
    with FakeAutopilot(("127.0.0.1", port), autopilot="ardupilot", armed=True) as peer:
        status.wait(lambda s: s.link_ok and s.autopilot == "ardupilot" and s.mode == "MANUAL", 15,
                    "link to ArduPilot")
        t0 = time.monotonic_ns()
        pub.put(thrust(30.0, -20.0))  # L = 0.4, R = -0.2667
        wait_for(lambda: any((r.y, r.z) == (400, -267) for r in peer.manual_controls_since(t0)),
                 2, what="y = 1000 L, z = 1000 R on the wire")
        assert mode(bus, "AUTO").accepted and peer.mode == "MISSION"  # AUTO is Seaway's MISSION
    status.clear()
    status.wait(lambda s: not s.link_ok, HEARTBEAT_TIMEOUT_S + 2.5, "link lost")
    bad = {**ARDUPILOT_DEFAULT_PARAMS, "PILOT_STEER_TYPE": (0, 2)}
    with FakeAutopilot(("127.0.0.1", port), autopilot="ardupilot", sysid=2, armed=True,
                       params=bad) as peer:
        status.wait(lambda s: s.link_ok and s.failsafe == "autopilot_config", 15,
                    "failsafe autopilot_config")
        t0 = time.monotonic_ns()
        for _ in range(6):
            pub.put(thrust(30.0, -20.0))
            time.sleep(PERIOD_S)
        recs = peer.manual_controls_since(t0)
        assert recs and all((r.y, r.z) == (0, 0) for r in recs)
    alive(vio, procs)
    assert "PILOT_STEER_TYPE=0" in procs.log(vio)
