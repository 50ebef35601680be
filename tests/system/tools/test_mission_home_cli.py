"""``seaway mission home`` against a running stack (#57 item 2: home "set by the operator"): the
real CLI, the real controller in a lockstep ``seaway launch sim-batch`` of the lake (its operating
area), over Zenoh with the stack's operator credentials."""

from __future__ import annotations

import signal
import subprocess

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted
from seaway.runtime.bus import Bus

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system


def home(env: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "seaway"), "mission", "home", *args, "--timeout", "60"],
                          env=env, capture_output=True, text=True, timeout=120, check=False)


def test_the_operator_sets_home_and_the_next_mission_returns_there(procs, zenoh_env, tmp_path):
    run = tmp_path / "run"
    launcher = procs.launch_ready(zenoh_env, "sim-batch", "--scenario", "lake", "--run-dir",
                                  str(run), "--no-mission", "--stay")
    # Outside the lake's keep-in area (45 m north at most): refused, naming it; exit 1.
    out = home(zenoh_env, "60,0")
    assert out.returncode == 1 and "home at north 60.0 m" in out.stdout + out.stderr, out
    # A bad command line: exit 2, naming what is allowed; nothing sent.
    bad = home(zenoh_env, "nan,1")
    assert bad.returncode == 2 and "'nan,1'" in bad.stderr and "x_m" in bad.stderr, bad
    word = home(zenoh_env, "north")
    assert word.returncode == 2 and "NORTH_M,EAST_M" in word.stderr, word
    ok = home(zenoh_env, "3,4")
    assert ok.returncode == 0 and "home set at north 3.0 m, east 4.0 m" in ok.stdout, ok
    accepted: list[MissionAccepted] = []
    with Bus.open("vessel1") as bus:
        bus.subscribe(keys.MISSION_ACCEPTED, mode="fifo", callback=lambda _k, m: accepted.append(m))
        sent = subprocess.run([str(BIN / "seaway"), "mission", "lake", "--timeout", "120"],
                              env=zenoh_env, capture_output=True, text=True, timeout=300)
        assert sent.returncode == 0, sent.stdout + sent.stderr
        first = wait_for(lambda: next(iter(accepted), None), 60, what="the lake mission accepted")
        assert (first.home_x_m, first.home_y_m) == (3.0, 4.0)  # the operator's home, not P_0
        # 'here': where the estimator has the vessel now.
        here = home(zenoh_env, "here")
        assert here.returncode == 0 and "home set at north" in here.stdout, here
    assert procs.stop(launcher, signal.SIGINT, timeout_s=120) < 120
