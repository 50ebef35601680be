"""``seaway mission`` against real processes: it waits for the controller instead of racing the mesh.

A new session needs a moment to learn where the controller's queryable is; a request sent before
that reaches nobody and used to be reported as "no reply within 5 s" after about a second (issue 14,
item 6). Here the request is sent before the controller even exists: it must wait for it (up to
``--timeout``) and be accepted, and without a controller it must say that none was seen.
"""

from __future__ import annotations

import subprocess
import time

import pytest

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
VESSEL = "missioncli"


def mission(*args: str, env: dict[str, str], timeout_s: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "seaway"), "mission", *args, "--vessel", VESSEL], env=env,
                          capture_output=True, text=True, timeout=timeout_s, check=False)


def test_a_mission_sent_before_the_controller_is_up_waits_for_it(zenoh_env, procs) -> None:
    early = procs.start([str(BIN / "seaway"), "mission", "paper-c1", "--vessel", VESSEL,
                         "--timeout", "90"], zenoh_env, "mission-early")
    time.sleep(2.0)  # the request is due well before anybody serves it
    assert early.poll() is None, procs.log(early)
    ctl = procs.start([str(BIN / "seaway-controller"), "--vessel", VESSEL], zenoh_env, "controller")
    wait_for(lambda: early.poll() is not None, 120, what="seaway mission to finish")
    assert early.returncode == 0, procs.log(early) + procs.log(ctl)
    assert "mission paper-c1 (3 waypoints): accepted" in procs.log(early)

    # Fresh sessions against the ready controller: every one gets its reply.
    for _ in range(3):
        out = mission("paper-c1", env=zenoh_env)
        assert out.returncode == 0 and "accepted" in out.stdout, out.stderr


def test_without_a_controller_it_says_none_was_seen(zenoh_env) -> None:
    t0 = time.monotonic()
    out = mission("pause", "--timeout", "2", env=zenoh_env, timeout_s=60)
    assert out.returncode == 1
    assert "not delivered: no controller on vessel missioncli: its health token did not appear " \
           "within 2 s" in out.stderr, out.stderr
    assert time.monotonic() - t0 < 30
