"""The controller as a real-time process on Zenoh says which mission it accepted on
``mission/accepted``, and says it again every second, so that a session that joins after the
acceptance (a recorder or ground station started late) still learns the path flown."""

from __future__ import annotations

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, MissionRequest, Waypoint
from seaway.runtime.bus import Bus

from tests.conftest import BIN, wait_for

pytestmark = pytest.mark.system
VESSEL = "acceptlive"
WAYPOINTS = [(0.0, 0.0), (0.0, -6.0), (6.0, -6.0)]


def test_the_accepted_mission_reaches_a_session_that_joins_later(zenoh_env, procs) -> None:
    proc = procs.start([str(BIN / "seaway-controller"), "--vessel", VESSEL, "--solver", "ipopt"],
                       zenoh_env, name="controller")
    req = MissionRequest.make(stamp_ns=0, mission_id="late-join", coa_radius_m=1.0, task_power_w=5.0,
                              controller="eo-empc",
                              waypoints=[Waypoint(x_m=x, y_m=y) for x, y in WAYPOINTS])
    with Bus.open(VESSEL) as bus:
        wait_for(lambda: "controller" in bus.alive_services(timeout_s=0.5) or proc.poll() is not None,
                 timeout_s=120, what="the controller's health token")
        assert proc.poll() is None, procs.log(proc)
        reply = bus.request(keys.MISSION_SET, req, timeout_s=60.0)
        assert reply.accepted, reply.reason
    # A new session, opened after the acceptance: it hears the mission all the same.
    with Bus.open(VESSEL) as late:
        heard = late.subscribe(keys.MISSION_ACCEPTED, mode="fifo")
        got: list[MissionAccepted] = []

        def two() -> bool:
            got.extend(heard.drain())
            return len(got) >= 2

        wait_for(two, 60, interval_s=0.1, what="two mission/accepted messages on the late session")
    first, second = got[0], got[1]
    assert first.mission_id == "late-join" and first.waypoints_m() == WAYPOINTS
    assert (first.coa_radius_m, first.task_power_w, first.controller) == (1.0, 5.0, "eo-empc")
    assert first.controller_settings["horizon_steps"] == 10 and first.controller_settings["dt_s"] == 0.1
    # The same acceptance re-published every second of the controller's wall clock (no sooner; a
    # busy machine may make it later).
    assert second.accepted_ns == first.accepted_ns <= first.stamp_ns
    assert second.model_copy(update={"stamp_ns": first.stamp_ns}) == first
    assert 1.0e9 <= second.stamp_ns - first.stamp_ns <= 2.5e9
