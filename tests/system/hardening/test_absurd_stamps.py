"""Issue 14, item 1, through real processes: a valid ``ThrustCommand`` stamped in the future hung
the estimator. Stamped +10 s it moved the filter 10 s ahead, so every later sample was "too old"
and ``nav/state`` stopped; stamped 10^4000 ns it integrated for ever inside the loop's lock, so
``nav/reset`` timed out and SIGINT was ignored. Now such a stamp is dropped before the core,
counted and logged once, and the estimator goes on.

The estimator runs in real time on its own, fed a still vessel's GNSS and heading by this test at
the wall clock, as vehicle_io would (``test_future_stamps_on_a_real_time_stack`` does the same to
the whole ``sim`` profile, in the slow set)."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import Attitude, GnssFix, NavResetRequest, ThrustCommand
from seaway.runtime.bus import Bus

from tests.conftest import BIN, wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system
S = 1_000_000_000
LAT, LON = math.radians(47.0), math.radians(8.0)


class Sensors(threading.Thread):
    """A still vessel's GNSS (5 Hz) and heading (20 Hz), stamped with the wall clock."""

    def __init__(self, bus: Bus) -> None:
        super().__init__(daemon=True)
        self.gnss, self.att = bus.publisher(keys.GNSS), bus.publisher(keys.ATTITUDE)
        self.stop = threading.Event()

    def run(self) -> None:
        k = 0
        while not self.stop.wait(0.05):
            t = time.time_ns()
            self.att.put(Attitude(stamp_ns=t, roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.3,
                                  roll_rate_radps=0.0, pitch_rate_radps=0.0, yaw_rate_radps=0.0))
            if k % 4 == 0:
                self.gnss.put(GnssFix(stamp_ns=t, lat_rad=LAT, lon_rad=LON, alt_m=0.0, fix_type=3,
                                      vel_n_mps=0.0, vel_e_mps=0.0, horizontal_std_m=0.3))
            k += 1


def states_keep_coming(sub, seconds: float) -> list:
    """Every nav/state over ``seconds``; each must be stamped within 0.5 s of the wall clock."""
    got, deadline = [], time.monotonic() + seconds
    while time.monotonic() < deadline:
        msg = sub.get(0.5)
        assert msg is not None, f"nav/state stopped after {len(got)} states"
        assert abs(msg.stamp_ns - time.time_ns()) < S // 2, "nav/state stamped off the clock"
        got.append(msg)
    return got


@pytest.mark.timeout(120)
def test_future_stamped_thrust_commands_do_not_stop_the_estimator(procs, zenoh_env) -> None:
    est = procs.start([str(BIN / "seaway-estimator")], zenoh_env, "estimator")
    with Bus.open("vessel1") as bus:
        wait_for(lambda: "estimator" in bus.alive_services(), 30, what="the estimator ready")
        sensors = Sensors(bus)
        sensors.start()
        try:
            states = bus.subscribe(keys.NAV_STATE, mode="fifo")
            wait_for(lambda: states.get(0.2), 20, what="a first nav/state")
            thrust = bus.publisher(keys.THRUST)
            now = time.time_ns()
            thrust.put(ThrustCommand(stamp_ns=now + 10 * S, thrust_port_n=10.0,
                                     thrust_starboard_n=10.0, source="attacker"))
            thrust.put(ThrustCommand(stamp_ns=2**62, thrust_port_n=10.0, thrust_starboard_n=10.0,
                                     source="attacker"))
            states.drain()
            got = states_keep_coming(states, 3.0)
            assert len(got) >= 20  # 20 Hz, on a busy machine
            # The still vessel stays still: neither command was taken.
            assert max(abs(s.u_mps) for s in got) < 0.05
            t0 = time.monotonic()
            reply = bus.request(keys.NAV_RESET, NavResetRequest.make(
                stamp_ns=time.time_ns(), keep_origin=True, reason="test"), 5.0)
            assert reply.accepted, reply.reason
            assert time.monotonic() - t0 < 3.0
        finally:
            sensors.stop.set()
    assert procs.stop(est, signal.SIGINT, timeout_s=10) < 5.0
    log = procs.log(est)
    assert "Traceback" not in log
    drops = [line for line in log.splitlines() if "dropped a message on seaway" in line
             or "dropped a message on ctrl/thrust" in line]
    assert len(drops) == 1, drops  # counted, logged once
    assert "stamps dropped: ctrl/thrust ahead 2" in log  # the final stats line counts both


@pytest.mark.slow  # a whole real-time mission: about 45 s
@pytest.mark.timeout(600)
def test_future_stamps_on_a_real_time_stack(procs, zenoh_env, tmp_path) -> None:
    """The issue's own reproduction on the ``sim`` profile: future-stamped thrust commands put on
    the bus mid-mission. ``nav/state`` goes on, the controller never sees a stale state, the
    mission completes."""
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--scenario",
                      str(short_lake(tmp_path, "stamps")), "--run-dir", str(run)], zenoh_env,
                     "launcher")
    with Bus.open("vessel1") as bus:
        states = bus.subscribe(keys.NAV_STATE, mode="fifo")
        status = bus.subscribe(keys.MISSION_STATUS)
        wait_for(lambda: (s := status.latest()) is not None and s.state == "active", 300,
                 what="the mission under way")
        thrust = bus.publisher(keys.THRUST)
        for stamp in (time.time_ns() + 10 * S, 2**62):
            thrust.put(ThrustCommand(stamp_ns=stamp, thrust_port_n=0.0, thrust_starboard_n=0.0,
                                     source="attacker"))
        states.drain()
        states_keep_coming(states, 3.0)
        la.wait(180)
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    assert "nav/state older than" not in (run / "logs" / "controller.log").read_text()
    assert "stamps dropped: ctrl/thrust ahead 2" in (run / "logs" / "estimator.log").read_text()
