"""Issue 14, item 2, through the real ``sim`` profile (simulated PX4 over MAVLink, vehicle_io,
estimator, controller, recorder): SIGKILL the sim mid-mission, an autopilot reboot. It comes back
disarmed at its start pose. Before, the mission stayed ``active``, its energy kept rising and the
estimator dead-reckoned on the commanded thrust while the boat lay still. Now vehicle_io says the
thrust is withheld, the estimator predicts with zero thrust, the controller pauses the mission with
the reason in ``mission/status``, and the mission resumes only when asked, once the vehicle is armed
again; then it completes."""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, MissionCommand, ModeRequest
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.hardening.stack import short_lake, starts

pytestmark = pytest.mark.system


class Latest:
    """The latest message of a few keys, and every mission status."""

    def __init__(self, bus: Bus) -> None:
        self.lock = threading.Lock()
        self.mission = self.state = self.vehicle = None
        self.missions: list = []
        bus.subscribe(keys.MISSION_STATUS, callback=self._on_mission)
        bus.subscribe(keys.NAV_STATE, callback=lambda _k, m: setattr(self, "state", m))
        bus.subscribe(keys.VEHICLE_STATUS, callback=lambda _k, m: setattr(self, "vehicle", m))

    def _on_mission(self, _key: str, msg) -> None:
        with self.lock:
            self.mission = msg
            self.missions.append((time.monotonic(), msg))


@pytest.mark.timeout(600)  # about 45 s; the first start on a machine also compiles the solvers
@pytest.mark.slow  # a real-time mission, about 37 s
def test_an_autopilot_reboot_pauses_the_mission_until_resumed(procs, zenoh_env, tmp_path) -> None:
    run = tmp_path / "run"
    scenario = short_lake(tmp_path, "reboot")
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--scenario",
                      str(scenario), "--run-dir", str(run)], zenoh_env, "launcher")
    with Bus.open("vessel1") as bus:
        w = Latest(bus)
        wait_for(lambda: w.mission is not None and w.mission.state == "active"
                 and w.state is not None and w.state.u_mps > 0.5, 300, what="the mission under way")
        # The autopilot reboots.
        (sim,) = starts(run, "sim")
        os.kill(sim["pid"], signal.SIGKILL)
        wait_for(lambda: len(starts(run, "sim")) == 2, 30, what="the sim restarted")
        paused = wait_for(lambda: w.mission if w.mission.state == "paused" else None, 30,
                          what="the mission paused")
        assert "paused by the controller" in paused.reason
        assert "disarmed" in paused.reason or "no link" in paused.reason, paused.reason
        print(f"paused: {paused.reason}")
        # Paused means paused: no energy counted, zero thrust, the estimate at rest like the boat.
        energy = paused.energy_used_j
        time.sleep(3.0)
        assert w.mission.state == "paused" and w.mission.energy_used_j == pytest.approx(energy)
        assert abs(w.state.u_mps) < 0.2, w.state
        # The rebooted autopilot is heard again (a busy machine may take a while): disarmed.
        wait_for(lambda: w.vehicle is not None and w.vehicle.thrust_withheld == "disarmed", 60,
                 what="vehicle_io reporting the rebooted autopilot, disarmed")
        # Resuming while the vehicle is disarmed is refused, with the reason.
        refused = bus.request(keys.MISSION_COMMAND, MissionCommand.make(
            stamp_ns=time.time_ns(), command="resume"), 10.0)
        assert not refused.accepted and "disarmed" in refused.reason, refused.reason
        # The operator puts it in MANUAL (a rebooted PX4 comes up in Hold) and arms it again: the
        # mission stays paused until asked.
        manual = bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                                 mode="MANUAL"), 10.0)
        assert manual.accepted, manual.reason
        armed = bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True), 10.0)
        assert armed.accepted, armed.reason
        wait_for(lambda: w.vehicle is not None and w.vehicle.thrust_withheld is None, 10,
                 what="the vehicle applying thrust again")
        time.sleep(1.0)
        assert w.mission.state == "paused"
        resumed = bus.request(keys.MISSION_COMMAND, MissionCommand.make(
            stamp_ns=time.time_ns(), command="resume"), 10.0)
        assert resumed.accepted, resumed.reason
        la.wait(180)
    out = procs.log(la)
    assert la.returncode == 0, out[-3000:]
    assert "mission complete" in out
    est_log = (run / "logs" / "estimator.log").read_text()
    assert "withholds the thrust" in est_log and "predicting with zero thrust" in est_log
