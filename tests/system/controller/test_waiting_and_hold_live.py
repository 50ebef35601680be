"""Issue #57 items 4 and 5 through the real ``sim`` profile (simulated PX4 over MAVLink, vehicle_io,
estimator, controller, recorder), on the real-time lake boat.

A mission sent while the vehicle is disarmed is accepted as ``waiting``, saying for what (never
"started"), and starts by itself once the operator arms; at its end the vessel holds station at the
last waypoint (``mission/status`` says where, ``ctrl/thrust`` comes from the hold) instead of
drifting."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, MissionRequest, ModeRequest, Waypoint
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system


class Latest:
    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.mission = self.state = self.vehicle = self.thrust = None
        self.missions: list = []
        bus.subscribe(keys.MISSION_STATUS, callback=self._on_mission)
        bus.subscribe(keys.NAV_STATE, callback=lambda _k, m: setattr(self, "state", m))
        bus.subscribe(keys.VEHICLE_STATUS, callback=lambda _k, m: setattr(self, "vehicle", m))
        bus.subscribe(keys.THRUST, callback=lambda _k, m: setattr(self, "thrust", m))

    def _on_mission(self, _key: str, msg) -> None:
        with self.lock:
            self.mission = msg
            self.missions.append(msg)


@pytest.mark.timeout(600)  # about 60 s; the first start on a machine also compiles the solvers
@pytest.mark.slow  # a real-time stack and two missions, about a minute
def test_a_mission_sent_disarmed_waits_then_flies_and_holds_station_at_its_end(procs, zenoh_env,
                                                                                tmp_path) -> None:
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--scenario",
                      str(short_lake(tmp_path, "waitlive")), "--run-dir", str(run)], zenoh_env,
                     "launcher")
    with Bus.open("vessel1") as bus:
        w = Latest(bus)
        wait_for(lambda: w.mission is not None and w.mission.state == "active"
                 and w.state is not None and w.state.u_mps > 0.5, 300, what="the mission under way")
        disarm = bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=False,
                                                                force=True), 10.0)
        assert disarm.accepted, disarm.reason
        wait_for(lambda: w.vehicle is not None and w.vehicle.thrust_withheld == "disarmed", 30,
                 what="vehicle_io reporting the vehicle disarmed")
        time.sleep(3.0)  # the boat comes to rest
        x, y = w.state.x_m, w.state.y_m
        target = (x, y + 12.0)
        req = MissionRequest.make(stamp_ns=time.time_ns(), mission_id="after-disarm",
                                  coa_radius_m=2.0, task_power_w=250.0, controller="cc-empc",
                                  waypoints=[Waypoint(x_m=x, y_m=y),
                                             Waypoint(x_m=target[0], y_m=target[1])])
        reply = bus.request(keys.MISSION_SET, req, 30.0)
        # Accepted as waiting, saying for what; never "started".
        assert reply.accepted and reply.detail["state"] == "waiting", reply
        assert "disarmed" in reply.reason and "started" not in reply.reason, reply.reason
        waiting = wait_for(lambda: w.mission if w.mission.mission_id == "after-disarm" else None,
                           10, what="the new mission's status")
        assert waiting.state == "waiting" and "disarmed" in waiting.reason, waiting
        time.sleep(1.0)
        assert w.mission.state == "waiting"
        # The operator arms (in MANUAL): it starts by itself.
        assert bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                               mode="MANUAL"), 10.0).accepted
        assert bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                           10.0).accepted
        wait_for(lambda: w.mission.mission_id == "after-disarm" and w.mission.state == "active", 15,
                 what="the waiting mission starting once armed")
        done = wait_for(lambda: w.mission if w.mission.state == "complete" else None, 120,
                        what="the mission complete")
        # At its end it holds station at the last waypoint, and says so.
        assert (done.hold_x_m, done.hold_y_m) == pytest.approx(target)
        time.sleep(10.0)
        assert w.mission.state == "complete" and w.mission.hold_energy_j > 0
        assert w.thrust.source == "hold"
        assert math.dist((w.state.x_m, w.state.y_m), target) <= 3.0, w.state
    procs.stop(la, signal.SIGINT, 30.0)
