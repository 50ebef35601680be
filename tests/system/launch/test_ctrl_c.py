"""Ctrl-C of ``seaway launch`` at the moments a user hits it: while the services are still starting
(each was stopped with SIGINT and printed a KeyboardInterrupt traceback from the middle of its
imports), and during the report after a mission completed (the first Ctrl-C was taken as the stop
of a run that had already stopped, so the report went on, and a second one skipped it saying
"stopping faster" with nothing left to stop)."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest

from tests.conftest import solver_built, wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system


def tracebacks(run: Path, launcher_out: str) -> list[str]:
    logs = {log.name: log.read_text(errors="replace") for log in sorted((run / "logs").glob("*.log"))}
    logs["launcher"] = launcher_out
    return [name for name, text in logs.items() if "Traceback" in text or "KeyboardInterrupt" in text]


@pytest.mark.timeout(300)
def test_ctrl_c_while_the_services_start_stops_them_without_a_traceback(procs, zenoh_env,
                                                                          tmp_path) -> None:
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch", "--run-dir",
                      str(run), "--no-report"], zenoh_env, "launcher")
    # The sim starts once the recorder is ready; its log appears as it is spawned, a few tenths of
    # a second before its imports are done and its stop handler is in place.
    wait_for(lambda: (run / "logs" / "sim.log").exists() or la.poll() is not None, 120,
             interval_s=0.005, what="the sim to be spawned")
    assert la.poll() is None, procs.log(la)[-3000:]
    la.send_signal(signal.SIGINT)
    wait_for(lambda: la.poll() is not None, 120, interval_s=0.1, what="the launcher to stop")
    out = procs.log(la)
    assert la.returncode == 0, out[-3000:]
    assert "stopping..." in out and "all ready" not in out, out[-3000:]  # stopped while starting
    assert tracebacks(run, out) == [], out[-3000:]


@pytest.mark.timeout(600)
def test_one_ctrl_c_during_the_report_of_a_completed_mission_skips_the_report(procs, zenoh_env,
                                                                                tmp_path) -> None:
    solver_built("cc-empc", "paper-boat")
    run = tmp_path / "run"
    la = procs.start([sys.executable, "-m", "seaway.tools.cli", "launch", "sim-batch", "--scenario",
                      str(short_lake(tmp_path, "report-skipped")), "--run-dir", str(run)],
                     zenoh_env, "launcher")
    wait_for(lambda: "making the report" in procs.log(la) or la.poll() is not None, 400,
             interval_s=0.02, what="the launcher to make the report")
    assert la.poll() is None, procs.log(la)[-3000:]
    la.send_signal(signal.SIGINT)
    wait_for(lambda: la.poll() is not None, 60, interval_s=0.1, what="the launcher to end")
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    assert "(report skipped: Ctrl-C; make it with: " in out, out[-3000:]
    assert "stopping faster" not in out, out[-3000:]  # nothing was left to stop
    assert not (run / "report").exists() or not any((run / "report").iterdir()), \
        sorted((run / "report").iterdir())
