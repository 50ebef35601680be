"""Issue 56, item 18, through real processes: a "complete" published with the controller's own
certificate (the one identity the access rules let publish ``mission/status``), stamped an hour
ahead, an hour behind or now, stopped the stack at t = 7-10 s of a 334 s mission. Now the launcher
takes a status as the end of a mission only when its stamp is within bounds and the navigation
state puts the vessel at the last waypoint (``seaway.tools.launch.mission_end``): the forged ones
are refused and said, and the real completion still ends the run.

The real ``sim`` profile runs a short lake mission (one 25 m leg, about 25 s) with the credentials
the launcher makes for the run; the forger opens a session with the stack's controller certificate.
"""

from __future__ import annotations

import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionStatus
from seaway.runtime import credentials
from seaway.runtime.bus import Bus

from tests.conftest import stack_credentials, wait_for
from tests.system.hardening.stack import short_lake

pytestmark = pytest.mark.system
S = 1_000_000_000
HOUR = 3600 * S


@pytest.mark.timeout(300)
def test_a_forged_complete_from_the_controllers_identity_stops_nothing(
    procs, zenoh_env, tmp_path, monkeypatch
) -> None:
    env = dict(zenoh_env)
    for name in (credentials.ENV_CREDENTIALS, credentials.ENV_IDENTITY):  # the launcher's own
        env.pop(name, None)
        monkeypatch.delenv(name, raising=False)
    run = tmp_path / "run"
    la = procs.launch(env, "sim", "--scenario", str(short_lake(tmp_path, "forged")), "--run-dir", str(run))
    stack = stack_credentials()
    with Bus.open("vessel1", identity="controller", credentials=stack) as forger:
        heard: list[MissionStatus] = []
        forger.subscribe(keys.MISSION_STATUS, callback=lambda _k, m: heard.append(m))
        wait_for(lambda: heard and heard[-1].state == "active", 180, what="the mission under way")
        mission_id = heard[-1].mission_id
        put = forger.publisher(keys.MISSION_STATUS)
        # 3 s of forged "complete"s at 60 Hz, the three stamps in turn: the launcher looks at the
        # newest status five times a second, and most looks find a forged one.
        deadline, k = time.monotonic() + 3.0, 0
        while time.monotonic() < deadline:
            stamp = time.time_ns() + (HOUR, -HOUR, 0)[k % 3]
            put.put(
                MissionStatus.make(
                    stamp_ns=stamp, state="complete", mission_id=mission_id, active_leg=1, waypoint_count=2
                )
            )
            k += 1
            time.sleep(1 / 60)
        time.sleep(1.0)  # a look after the last forged status
        assert la.poll() is None, procs.log(la)[-3000:]  # the forged "complete"s stopped nothing
        assert heard[-1].state == "active"  # the real controller's, a second after the forger's
    la.wait(180)
    out = procs.log(la)
    assert la.returncode == 0 and "mission complete" in out, out[-3000:]
    # The launcher said what it did not take: out-of-bounds stamps, and a vessel far from the end.
    assert "dropped a message on mission/status" in out, out[-3000:]
    assert "not taken" in out, out[-3000:]
