"""The sim as a real process in real time, driven over MAVLink on UDP loopback like vehicle_io does.

Scenario paper-c1: no disturbance and no sensor noise, so what the sim reports can be compared with
an in-test integration of ``seaway.vessel.model`` for the same thrust (see the tolerance note below).
"""

from __future__ import annotations

import math
import signal
import socket
import time
from collections import defaultdict
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as ml
from seaway.contract import keys
from seaway.contract.messages import ScenarioRequest
from seaway.runtime.bus import Bus
from seaway.simkit.scenario import load_scenario
from seaway.simkit.sensors import origin_of
from seaway.vessel import model
from seaway.vessel.model import load_vessel

from tests.conftest import BIN, free_port, wait_for

pytestmark = pytest.mark.system

# -- a minimal MAVLink 2 ground-side client over a real UDP socket (vehicle_io's part) ----------

SIM_SYSID = 1


class MavClient:
    """Sends as a GCS (255/190); files every message it receives by type, with arrival time."""

    def __init__(self, port: int) -> None:
        self.addr = ("127.0.0.1", port)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.tx = ml.MAVLink(None, 255, 190)
        self.got: dict[str, list[tuple[float, Any]]] = defaultdict(list)

    def send(self, msg: Any) -> None:
        self.sock.sendto(msg.pack(self.tx), self.addr)

    def send_raw(self, data: bytes) -> None:
        self.sock.sendto(data, self.addr)

    def pump(self, seconds: float) -> None:
        """Receive for ``seconds``, filing every message by type."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            self.sock.settimeout(left)
            try:
                data, _ = self.sock.recvfrom(65535)
            except TimeoutError:
                return
            for m in ml.MAVLink(None).parse_buffer(data) or []:
                self.got[m.get_type()].append((time.time(), m))

    def wait(self, kind: str, timeout_s: float = 5.0, where=lambda m: True,
             keep_streaming: Any = None) -> Any:
        """The first new ``kind`` message matching ``where``; ``keep_streaming`` is sent meanwhile."""
        seen = len(self.got[kind])
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            if keep_streaming is not None:
                self.send(keep_streaming)
            self.pump(0.05)
            for _, m in self.got[kind][seen:]:
                if where(m):
                    return m
            seen = len(self.got[kind])
        raise AssertionError(f"no {kind} within {timeout_s} s")

    def command(self, cmd: int, *params: float, keep_streaming: Any = None) -> int:
        p = list(params) + [0.0] * (7 - len(params))
        self.send(ml.MAVLink_command_long_message(SIM_SYSID, 1, cmd, 0, *p))
        ack = self.wait("COMMAND_ACK", where=lambda m: m.command == cmd,
                        keep_streaming=keep_streaming)
        return ack.result

    def messages(self, kind: str) -> list[Any]:
        return [m for _, m in self.got[kind]]

    def close(self) -> None:
        self.sock.close()


def manual_control(y: int, z: int, x: int = 0, r: int = 0) -> Any:
    return ml.MAVLink_manual_control_message(SIM_SYSID, x, y, z, r, 0)


STEP_S = 0.01  # the sim's real-time tick and the plant's internal RK4 step
PAPER = load_vessel("paper-sim")


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_sim(procs, env, *args: str):
    port = free_udp_port()
    p = procs.start([str(BIN / "seaway-sim"), "--mavlink", f"udpin:127.0.0.1:{port}", *args], env,
                    "sim")
    wait_for(lambda: "real time: MAVLink on" in procs.log(p), 20, what="sim up")
    return p, port


def model_table(thrust: tuple[float, float], seconds: float) -> list[list[float]]:
    """States from rest every 10 ms under constant thrust: the same RK4 and step as the plant."""
    x = [0.0] * 6
    out = [x]
    for _ in range(round(seconds / STEP_S)):
        x = model.rk4_step(x, thrust, STEP_S, PAPER, math)
        out.append(x)
    return out


def test_constant_thrust_moves_the_vessel_as_the_model_predicts_then_failsafe(procs, zenoh_env):
    sim, port = start_sim(procs, zenoh_env, "--scenario", "paper-c1")
    with Bus.open("vessel1") as bus:
        truth = bus.subscribe(keys.SIM_TRUTH, mode="fifo")
        mav = MavClient(port)
        mav.send(ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3))
        hb = mav.wait("HEARTBEAT")
        assert (hb.type, hb.autopilot, hb.custom_mode) == (10, ml.MAV_AUTOPILOT_PX4, 0x03040000)

        # PX4 boots in Hold; Manual is taken disarmed without a stream, but arming in it is not.
        assert mav.command(ml.MAV_CMD_DO_SET_MODE, 1, 1, 0) == ml.MAV_RESULT_ACCEPTED
        assert mav.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ml.MAV_RESULT_TEMPORARILY_REJECTED

        # y = 200, z = 900: throttle 0.8, diff 0.2 -> L 1.0, R 0.6 -> T1 10 N, T2 6 N (paper-sim).
        stick = manual_control(200, 900)
        assert mav.command(ml.MAV_CMD_DO_SET_MODE, 1, 1, 0, keep_streaming=stick) == 0
        assert mav.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1, keep_streaming=stick) == 0
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            # The last stick leaves between these two clock readings: this process may be
            # descheduled on either side of the send (0.24 s was seen under load).
            sent_from = time.time()
            mav.send(stick)
            sent_by = time.time()
            mav.pump(0.05)
        mav.pump(1.2)  # silence: the failsafe must act

        # -- motion against the model ------------------------------------------------------
        table = model_table((10.0, 6.0), 10.0)
        local = {m.time_boot_ms: m for m in mav.messages("LOCAL_POSITION_NED")}
        yaw = {m.time_boot_ms: m.yaw for m in mav.messages("ATTITUDE")}
        moving = sorted(t for t, m in local.items() if m.vx != 0.0)
        assert len(moving) >= 10, "expected >= 10 position samples under way"
        # Fixes are 200 ms apart, thrust starts on a 10 ms tick: find that tick from the first
        # samples under way (the only unknown), then every sample must agree with the model.
        usable = [t for t in moving if t <= moving[0] + 2400]
        best = min(range(moving[0] - 200, moving[0], 10),
                   key=lambda t0: sum((local[t].x - table[(t - t0) // 10][3]) ** 2 for t in usable))
        # Tolerance: the sim and this test take the same RK4 steps from the same start, so the
        # residue is float32 rounding in LOCAL_POSITION_NED (~1e-7 relative) and ATTITUDE: 1 mm,
        # 1 mm/s and 1 mrad leave room for that and catch any wrong thrust, mapping or timing
        # (one tick of offset alone moves x by ~6 mm at 0.6 m/s).
        for t in usable:
            want = table[(t - best) // 10]
            m = local[t]
            assert (m.x, m.y) == pytest.approx((want[3], want[4]), abs=1e-3), t
            vn = want[0] * math.cos(want[5]) - want[1] * math.sin(want[5])
            ve = want[0] * math.sin(want[5]) + want[1] * math.cos(want[5])
            assert (m.vx, m.vy) == pytest.approx((vn, ve), abs=1e-3), t
            assert yaw[t] == pytest.approx(want[5], abs=1e-3), t
        # Port pushes harder: the vessel turns clockwise (to starboard, y east grows).
        assert table[(usable[-1] - best) // 10][5] > 0.05 and local[usable[-1]].y > 0.0
        # GLOBAL_POSITION_INT carries the same fixes in WGS84 (degE7: ~1 cm steps) at 5 Hz.
        origin = origin_of(load_scenario("paper-c1").origin)
        gpi = {m.time_boot_ms: m for m in mav.messages("GLOBAL_POSITION_INT")}
        for t in usable:
            n, e, _ = origin.to_ned(math.radians(gpi[t].lat / 1e7), math.radians(gpi[t].lon / 1e7))
            assert (n, e) == pytest.approx((local[t].x, local[t].y), abs=0.02), t
            assert gpi[t].hdg == round(math.degrees(yaw[t]) * 100) % 36000
        assert mav.messages("BATTERY_STATUS")

        # -- loss failsafe: thrust to zero within COM_RC_LOSS_T (0.5 s) + one period -----------
        samples = [(s.stamp_ns / 1e9, s.thrust_port_n, s.thrust_starboard_n) for s in truth.drain()]
        assert any(p == pytest.approx(10.0) and s == pytest.approx(6.0) for _, p, s in samples)
        zero_t = next(t for t, p, s in samples if t > sent_from and p == 0.0 and s == 0.0)
        # Truth is published every 0.1 s, and its stamps and this clock agree to a few ms. The
        # delay from the last stick to zero thrust lies in [zero_t - sent_by, zero_t - sent_from]:
        # it must meet COM_RC_LOSS_T within a period and a margin, so a thrust cut at once fails.
        assert zero_t - sent_by <= 0.5 + 0.1 + 0.05, (zero_t - sent_by, sent_by - sent_from)
        assert zero_t - sent_from >= 0.5 - 0.1 - 0.05, (zero_t - sent_from, sent_by - sent_from)
        assert all(p > 0 for t, p, _ in samples if sent_from < t < sent_from + 0.5 - 0.1 - 0.05)
        hb = mav.messages("HEARTBEAT")[-1]
        assert hb.system_status == ml.MAV_STATE_CRITICAL and hb.custom_mode == 0x03040000
        assert hb.base_mode & ml.MAV_MODE_FLAG_SAFETY_ARMED
        status = mav.messages("SYS_STATUS")[-1]
        assert not status.onboard_control_sensors_health & ml.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
        mav.close()
    assert procs.stop(sim, signal.SIGTERM) < 2.0
    assert sim.returncode == 0
    assert "manual control lost" in procs.log(sim)


def test_garbage_and_bad_requests_are_dropped_and_the_sim_keeps_serving(procs, zenoh_env):
    sim, port = start_sim(procs, zenoh_env, "--scenario", "paper-c1")
    mav = MavClient(port)
    mav.send(ml.MAVLink_heartbeat_message(ml.MAV_TYPE_GCS, ml.MAV_AUTOPILOT_INVALID, 0, 0, 4, 3))
    mav.wait("HEARTBEAT")
    assert mav.command(ml.MAV_CMD_DO_SET_MODE, 1, 1, 0) == ml.MAV_RESULT_ACCEPTED  # boots in Hold
    good = manual_control(0, 500).pack(ml.MAVLink(None, 255, 190))
    corrupted = bytearray(good)
    corrupted[-1] ^= 0xFF
    mav.send_raw(b"\x00\x01\x02 not mavlink at all \xfd\xfe")   # garbage
    mav.send_raw(bytes(corrupted))                               # bad CRC
    mav.send_raw(good[:9])                                      # truncated frame
    mav.send(manual_control(0, 500, x=5000))                     # out-of-range axis
    mav.send(ml.MAVLink_command_long_message(1, 1, ml.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                             math.nan, 0, 0, 0, 0, 0, 0))  # NaN param
    # Still answering, and reporting the garbage in SYS_STATUS.errors_comm.
    mav.send(ml.MAVLink_param_request_read_message(1, 1, b"COM_RC_LOSS_T", -1))
    pv = mav.wait("PARAM_VALUE")
    assert (pv.param_id, pv.param_value) == ("COM_RC_LOSS_T", 0.5)
    status = mav.wait("SYS_STATUS", timeout_s=3, where=lambda m: m.errors_comm >= 3)
    assert status.errors_comm == 3  # one per datagram that held garbage
    # The out-of-range stick did not count as a manual control stream: arming is still refused.
    assert mav.command(ml.MAV_CMD_COMPONENT_ARM_DISARM, 1) == ml.MAV_RESULT_TEMPORARILY_REJECTED
    log = procs.log(sim)
    assert "MANUAL_CONTROL with axes outside [-1000, 1000]: {'x': 5000}" in log
    assert "non-finite params" in log and "garbage from" in log

    with Bus.open("vessel1") as bus:
        bad_doc = {"name": "broken", "seed": -1, "vessel": "paper-sim", "sensors": {"gnss_std_m": -2}}
        reply = bus.request(keys.SIM_SCENARIO,
                            ScenarioRequest(stamp_ns=0, action="load", scenario=bad_doc), 5.0)
        assert not reply.accepted
        assert "seed" in reply.reason and "sensors.gnss_std_m" in reply.reason
        no_vessel = {"name": "x", "seed": 1, "vessel": "no-such-boat"}
        reply = bus.request(keys.SIM_SCENARIO,
                            ScenarioRequest(stamp_ns=0, action="load", scenario=no_vessel), 5.0)
        assert not reply.accepted and "no-such-boat" in reply.reason
        good_doc = {"name": "push", "seed": 2, "vessel": "paper-sim",
                    "disturbances": [{"kind": "world_constant", "north_n": 0.5}]}
        reply = bus.request(keys.SIM_SCENARIO,
                            ScenarioRequest(stamp_ns=0, action="load", scenario=good_doc), 5.0)
        assert reply.accepted and reply.detail["name"] == "push"
        dist = bus.subscribe(keys.SIM_DISTURBANCE)
        d = wait_for(lambda: dist.latest(), 5, what="a disturbance sample")
        assert d.surge_n == pytest.approx(0.5, abs=1e-9)  # heading north: the push is surge
        reply = bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="restart"), 5.0)
        assert reply.accepted and "restarted" in reply.reason
    mav.wait("HEARTBEAT")  # MAVLink still served after all of it
    mav.close()
    assert sim.poll() is None
    assert procs.stop(sim, signal.SIGTERM) < 2.0


def test_bad_arguments_exit_with_a_message(procs, zenoh_env):
    p = procs.start([str(BIN / "seaway-sim"), "--scenario", "no-such-scenario"], zenoh_env, "bad")
    assert p.wait(20) == 2
    assert "no-such-scenario" in procs.log(p)
    p = procs.start([str(BIN / "seaway-sim"), "--mavlink", f"tcp:127.0.0.1:{free_port()}"],
                    zenoh_env, "bad2")
    assert p.wait(20) == 2
    assert "expected udpin:HOST:PORT" in procs.log(p)
