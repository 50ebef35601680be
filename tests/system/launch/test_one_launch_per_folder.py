"""Two launchers into one ``--run-dir`` at once (two stacks on two rendezvous ports): the check for
an earlier launch's recording passed for both (no recorder had written yet) and both ran into the
folder, their files mixed. Now the second is refused at once (exit 2) naming the folder and the
first's pid, and the first runs on and stops cleanly (``seaway.tools.launch.run_lock``)."""

from __future__ import annotations

import signal
import sys

import pytest

from tests.conftest import free_port, wait_for
from tests.system.launch.test_launcher import proc, write_profile

pytestmark = pytest.mark.system


def test_a_second_launcher_into_the_same_run_folder_is_refused(procs, zenoh_env, tmp_path) -> None:
    profile = write_profile(tmp_path, proc("sim", "sim") + proc("est", "estimator", after='["sim"]'))
    run_dir = tmp_path / "run"
    argv = [sys.executable, "-m", "seaway.tools.cli", "launch", str(profile), "--run-dir",
            str(run_dir)]
    first = procs.start(argv, zenoh_env, "first")
    wait_for(lambda: "all ready" in procs.log(first), 30, what="the first launch ready")
    other_port = {**zenoh_env, "SEAWAY_ZENOH_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}"}
    second = procs.start(argv, other_port, "second")
    try:
        second.wait(60)
    except Exception:
        pytest.fail(f"the second launcher runs into the first's folder:\n{procs.log(second)}")
    out = procs.log(second)
    assert second.returncode == 2, out
    assert str(run_dir) in out and f"pid {first.pid}" in out, out
    assert "all ready" not in out
    assert first.poll() is None, procs.log(first)
    procs.stop(first, signal.SIGINT, timeout_s=15)
    assert first.returncode == 0, procs.log(first)
    # Only the first's processes started: one start of each in its logs.
    assert (run_dir / "logs" / "est.log").read_text().count("--- start") == 1
