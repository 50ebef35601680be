"""Issue 14, item 14: a normal run is quiet. Every stop printed a ``thrust_stale`` WARNING, every
lockstep start a recorder WARNING ("still lacking ..., no answer yet from ...") and every lockstep
stop a sim WARNING per member ("... is gone; holding until it is back"): expected events, now INFO.
A WARNING is left for what a user should act on, so a normal run has none."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

from tests.conftest import solver_built, wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system
LOUD = re.compile(r" (WARNING|ERROR|CRITICAL) |Traceback")


def loud_lines(run: Path, launcher_out: str) -> list[str]:
    lines = [f"{log.name}: {line}" for log in sorted((run / "logs").glob("*.log"))
             for line in log.read_text(errors="replace").splitlines() if LOUD.search(line)]
    return lines + [f"launcher: {line}" for line in launcher_out.splitlines() if LOUD.search(line)]


@pytest.mark.timeout(600)
def test_a_normal_lockstep_run_logs_no_warning(procs, zenoh_env, tmp_path) -> None:
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch", "--scenario",
                      "paper-c1", "--controller", "nmpc", "--run-dir", str(run)], zenoh_env, "launcher")
    la.wait(540)
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    assert loud_lines(run, out) == []


@pytest.mark.slow  # a whole real-time mission: about 45 s
@pytest.mark.timeout(600)
def test_a_normal_real_time_run_logs_no_warning(procs, zenoh_env, tmp_path) -> None:
    # A normal run, not a machine's first: there line-of-sight guidance and then the reference
    # IPOPT fly while the solver is compiled, and that fallback is worth its WARNING. (The compile
    # runs niced, so it does not starve the stack: seaway.vessel.native.compile_shared.)
    solver_built("cc-empc", "paper-boat")
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim", "--scenario",
                      str(short_lake(tmp_path, "quiet")), "--run-dir", str(run)], zenoh_env, "launcher")
    wait_for(lambda: la.poll() is not None, 540, interval_s=0.5, what="the run to end")
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    assert loud_lines(run, out) == []  # (the stop's watchdog trip, if any, is INFO: a zero command)
    assert "built cc-empc solver" not in (run / "logs" / "controller.log").read_text(), \
        "the stack compiled its solver: solver_built made another one than the controller uses"
