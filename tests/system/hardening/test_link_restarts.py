"""Issue 56, item 19, through the real ``sim`` profile in real time: after a restart of vehicle_io
or of the sim, the mission stayed paused for good and the launcher never finished; and a restarted
sim put the vessel back at its start with a full battery.

* vehicle_io SIGKILLed mid-mission: the launcher restarts it, the controller pauses the mission (no
  thrust reached the thrusters), and the launcher, seeing the autopilot back and still armed, puts
  it in its mode and resumes the mission, which completes.
* the sim SIGKILLed mid-mission (an autopilot reboot): the restarted sim puts the vessel where it
  was, with the energy it had used; the autopilot comes back disarmed, which the launcher leaves to
  the operator; nobody re-arms it, so after ``--resume-wait`` the launcher ends the mission with
  the reason and exits 1.
"""

from __future__ import annotations

import math
import os
import signal

import pytest
from seaway.contract import keys
from seaway.runtime.bus import Bus

from tests.conftest import wait_for
from tests.system.hardening.stack import short_lake, starts

pytestmark = pytest.mark.system


class Heard:
    """The latest mission status, navigation state and sim truth, and every truth."""

    def __init__(self, bus: Bus) -> None:
        self.mission = self.state = None
        self.truths: list = []
        bus.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: setattr(self, "mission", m))
        bus.subscribe(keys.NAV_STATE, callback=lambda _k, m: setattr(self, "state", m))
        bus.subscribe(keys.SIM_TRUTH, callback=lambda _k, m: self.truths.append(m))


def _launch(procs, zenoh_env, tmp_path, name: str, *extra: str):
    run = tmp_path / "run"
    return run, procs.launch(
        zenoh_env, "sim", "--scenario", str(short_lake(tmp_path, name)), "--run-dir", str(run), *extra
    )


@pytest.mark.timeout(400)
def test_a_mission_paused_by_a_vehicle_io_restart_is_resumed_and_completes(
    procs, zenoh_env, tmp_path
) -> None:
    run, la = _launch(procs, zenoh_env, tmp_path, "vio-restart")
    with Bus.open("vessel1") as bus:
        w = Heard(bus)
        wait_for(
            lambda: (
                w.mission is not None
                and w.mission.state == "active"
                and w.state is not None
                and w.state.u_mps > 0.5
            ),
            300,
            what="the mission under way",
        )
        (vio,) = starts(run, "vehicle_io")
        os.kill(vio["pid"], signal.SIGKILL)
        wait_for(lambda: len(starts(run, "vehicle_io")) == 2, 30, what="vehicle_io restarted")
        wait_for(lambda: w.mission.state == "paused", 30, what="the mission paused")
        wait_for(lambda: w.mission.state == "active", 60, what="the launcher resuming it")
        la.wait(180)
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    assert "mission resumed after the link restart" in out


@pytest.mark.timeout(400)
def test_a_restarted_sim_keeps_the_vessel_and_the_unresumed_mission_ends_with_its_reason(
    procs, zenoh_env, tmp_path
) -> None:
    run, la = _launch(procs, zenoh_env, tmp_path, "sim-restart", "--resume-wait", "10")
    with Bus.open("vessel1") as bus:
        w = Heard(bus)
        wait_for(
            lambda: (
                w.mission is not None and w.mission.state == "active" and w.truths and w.truths[-1].x_m > 8.0
            ),
            300,
            what="the vessel 8 m along the leg",
        )
        (sim,) = starts(run, "sim")
        os.kill(sim["pid"], signal.SIGKILL)
        before = w.truths[-1]
        n = len(w.truths)
        wait_for(lambda: len(starts(run, "sim")) == 2, 30, what="the sim restarted")
        after = wait_for(
            lambda: next((t for t in w.truths[n:] if t.stamp_ns > before.stamp_ns), None),
            60,
            what="the restarted sim's truth",
        )
        # Where it was (kept every 0.5 s: at most a metre off at this speed), not back at the start.
        moved = math.hypot(after.x_m - before.x_m, after.y_m - before.y_m)
        assert moved < 3.0, (before, after)
        assert after.energy_j >= 0.9 * before.energy_j > 0, (before, after)  # not a fresh pack
        la.wait(120)
    out = procs.log(la)
    assert la.returncode == 1, out[-3000:]
    assert "mission complete" not in out
    line = next((ln for ln in out.splitlines() if "launcher ended it" in ln), "")
    assert "disarmed" in line, out[-3000:]
    assert "vessel put back where the sim before this one left it" in (run / "logs" / "sim.log").read_text()
