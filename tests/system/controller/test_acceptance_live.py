"""A mission the vessel cannot fly is refused before it starts, through the real stack (issue #56,
item 24): ``seaway mission paper-c1`` sent to the lake stack in real time turned at once into a
return home whose energy was infinite. Paper condition #1's 0.49 W on the lake boat cruises at
0.045 m/s on 0.75 N a side, inside the boat's 10 N thruster dead zone (and the lake's wind and
current, about 1.5 N, leave such a cruise no way on some courses): the controller now refuses it,
saying why, and flies nothing. Unit tests of the judgement: tests/unit/controller/test_acceptance.py."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.runtime.bus import Bus

from tests.conftest import wait_for

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent


@pytest.mark.timeout(600)
def test_paper_c1_sent_to_the_lake_stack_is_refused_with_its_reason(procs, zenoh_env,
                                                                     tmp_path) -> None:
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--no-mission",
                      "--run-dir", str(run), "--no-report"], zenoh_env, "launcher")
    bus = Bus.open("vessel1")
    try:
        status = bus.subscribe(keys.MISSION_STATUS, mode="latest")
        sent = subprocess.run([str(BIN / "seaway"), "mission", "paper-c1", "--vessel", "vessel1",
                               "--timeout", "120"],
                              capture_output=True, text=True, timeout=180, env=zenoh_env,
                              check=False)
        out = sent.stdout + sent.stderr
        assert sent.returncode == 1, out
        assert "cannot be flown" in out and "m/s" in out and "dead zone" in out, out
        last = wait_for(status.latest, 10, what="a mission status")
        assert last.state == "idle"  # nothing started, nothing returning
    finally:
        bus.close()
    la.send_signal(signal.SIGINT)
    wait_for(lambda: la.poll() is not None, 60, interval_s=0.2, what="the launcher to stop")
    controller = (run / "logs" / "controller.log").read_text()
    assert "energy budget" not in controller and "cannot be flown" in controller
