"""A real-time run whose recorder fails for good (a boat's card gone read-only, a recorder that dies
at every start) goes on flying: the recorder is not required in a real-time profile, as an
autopilot's logger is not. Before, the launcher ended the run once the recorder's restarts were used
up, and with it the control loop, leaving the vessel to the autopilot's failsafe mid-mission.

The ``sim`` profile, real processes on real Zenoh and MAVLink, with one restart allowed: the
recorder SIGKILLed twice fails for good. Checked: thrust keeps reaching the vessel, the launcher is
still running, its status line says NOT RECORDING, and after a clean stop it exits with
``EXIT_WENT_WITHOUT``.
"""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.runtime.bus import Bus
from seaway.tools.launch.stack import EXIT_WENT_WITHOUT

from tests.conftest import REPO, wait_for
from tests.system.launch.test_hangs_and_stops import of

pytestmark = pytest.mark.system

FLYING_ON_S = 5.0  # watched after the recorder failed for good


def one_restart_profile(tmp: Path) -> Path:
    """The ``sim`` profile with one restart per process, soon."""
    profile = tmp / "sim-one-restart.toml"
    profile.write_text((REPO / "deploy" / "profiles" / "sim.toml").read_text()
                       + "\n[backoff]\ninitial_s = 0.2\nmax_restarts = 1\n")
    return profile


def recorder_pids(run: Path) -> list[int]:
    return [e["pid"] for e in of(run, "recorder", "start")]


def test_a_real_time_run_flies_on_when_its_recorder_fails_for_good(procs, zenoh_env, tmp_path):
    run = tmp_path / "run"
    la = procs.launch_ready(zenoh_env, str(one_restart_profile(tmp_path)), "--run-dir", str(run),
                            "--stay", "--no-report", timeout_s=120)
    lock = threading.Lock()
    thrust_at_vessel: list[float] = []  # receive times of sim/truth with thrust on

    def on_truth(_key: str, m) -> None:
        if m.thrust_port_n or m.thrust_starboard_n:
            with lock:
                thrust_at_vessel.append(time.monotonic())

    with Bus.open("vessel1") as bus:
        bus.subscribe(keys.SIM_TRUTH, callback=on_truth)
        wait_for(lambda: len(thrust_at_vessel) > 20, 90, what="the mission flying")
        os.kill(recorder_pids(run)[0], signal.SIGKILL)
        second = wait_for(lambda: recorder_pids(run)[1:], 30, what="the recorder restarted")[0]
        os.kill(second, signal.SIGKILL)
        wait_for(lambda: "recorder failed" in procs.log(la), 30, interval_s=0.2,
                 what="the launcher giving the recorder up")
        failed_at = time.monotonic()
        time.sleep(FLYING_ON_S)
        with lock:
            after = [t for t in thrust_at_vessel if t > failed_at]
    assert la.poll() is None, procs.log(la)[-3000:]
    # The sim publishes truth at 10 Hz: thrust reached the vessel through nearly all of it.
    assert len(after) >= 0.5 * 10 * FLYING_ON_S, len(after)
    assert len(recorder_pids(run)) == 2  # given up: no third start
    # The status line says so (printed every few seconds when not on a terminal).
    wait_for(lambda: any(line.startswith("vessel1 |") and "NOT RECORDING" in line
                         for line in procs.log(la).splitlines()), 15, interval_s=0.5,
             what="the status line saying the run is not recorded")
    procs.stop(la, signal.SIGINT, timeout_s=60)
    assert la.returncode == EXIT_WENT_WITHOUT, procs.log(la)[-3000:]
