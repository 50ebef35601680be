"""A service that exits with code 0 while the launcher did not ask it to stop (a ``kill`` from
outside, a service that returned from its loop): a service runs until the launcher stops it, so
this is no finish. Before, the launcher wrote ``exited (code 0)`` and ran on for ever without it
(in lockstep the whole stack waiting on it); now it is restarted as a failed one is, and with
``restart = "never"`` a required one ends the run (exit 1) with the stop in order, the recording
finished and the summary printed (``seaway.tools.launch.exits``)."""

from __future__ import annotations

import signal

import pytest

from tests.conftest import wait_for
from tests.system.launch.test_launcher import launch, proc, write_profile

pytestmark = pytest.mark.system


def test_a_service_exiting_0_unasked_is_restarted(procs, zenoh_env, tmp_path) -> None:
    marker = tmp_path / "pids"
    m = f', "--marker", "{marker}"'
    profile = write_profile(tmp_path, proc("sim", "sim", m)
                            + proc("est", "estimator", m + ', "--exit-after", "1.0", "--code", "0"',
                                   after='["sim"]'))
    la = launch(procs, zenoh_env, profile, tmp_path)
    wait_for(lambda: "all ready" in procs.log(la), 30, what="all ready")
    # est exits 0 a second after each start; each exit is followed by a new start.
    wait_for(lambda: (tmp_path / "run" / "logs" / "est.log").read_text().count("--- start") >= 2,
             30, what="est restarted after its exit with code 0")
    assert la.poll() is None, procs.log(la)
    procs.stop(la, signal.SIGINT, timeout_s=15)
    assert la.returncode == 0, procs.log(la)


def test_a_required_service_exiting_0_unasked_without_restarts_ends_the_run(procs, zenoh_env,
                                                                            tmp_path) -> None:
    profile = write_profile(tmp_path, proc("rec", "recorder")
                            + proc("est", "estimator", ', "--exit-after", "1.0", "--code", "0"',
                                   after='["rec"]', restart='"never"'))
    la = launch(procs, zenoh_env, profile, tmp_path)
    la.wait(60)
    out = procs.log(la)
    assert la.returncode == 1, out
    assert "required process(es) failed: est" in out
    assert "stopped in" in out  # the stop in order ran, with its summary table
    events = (tmp_path / "run" / "events.jsonl").read_text()
    assert '"rec"' in events.splitlines()[-1] and '"stopped"' in events.splitlines()[-1]
