"""``mission/accepted``: the controller says which mission it accepted, in local NED, so that a
recording holds the path actually flown (issue 14, item 5).

The core's part (what the message holds, when it is due) with an injected solver; the lockstep
loop's part (it is one of the messages of the answering period, listed in the answer) on the
in-memory bus, as in test_service_loop.
"""

from __future__ import annotations

import math

import pytest
from seaway.contract import keys
from seaway.contract.messages import MissionAccepted, MissionRequest, Waypoint
from seaway.runtime.lockstep import Period
from seaway.vessel.frames import GeoOrigin
from seaway_controller.core_requests import ACCEPTED_REPUBLISH_NS

from tests.conftest import wait_for
from tests.unit.controller.test_core import ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_service_loop import VESSEL, World, running_controller

ORIGIN = GeoOrigin.from_degrees(47.0, 8.0, 0.0)


def test_the_accepted_mission_is_in_local_metres_with_its_controller_settings() -> None:
    core = make_core(ScriptedSolver(), predict_disturbance=True)
    core.set_origin(ORIGIN)
    # One waypoint in degrees, ~11 m north and ~7.6 m east of the origin: accepted in metres.
    lat, lon = 47.0 + 1e-4, 8.0 + 1e-4
    req = MissionRequest.make(stamp_ns=0, mission_id="geo", coa_radius_m=1.5, task_power_w=2.0,
                              controller="nmpc", speed_hint_mps=0.7,
                              waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(lat_deg=lat, lon_deg=lon)])
    assert core.handle_mission(123, req).accepted
    got = core.take_accepted(500)
    assert got is not None and isinstance(got, MissionAccepted)
    north, east, _ = ORIGIN.to_ned(math.radians(lat), math.radians(lon), 0.0)
    assert got.waypoints_m() == [(0.0, 0.0), pytest.approx((north, east), abs=1e-9)]
    assert 10.0 < north < 12.0 and 7.0 < east < 8.5
    assert (got.stamp_ns, got.accepted_ns, got.mission_id) == (500, 500, "geo")
    # (lockstep: accepted_ns is the period that carries it)
    assert (got.coa_radius_m, got.task_power_w, got.controller, got.speed_hint_mps) == \
        (1.5, 2.0, "nmpc", 0.7)
    assert got.predict_disturbance  # the process flag applies to every mission
    spec = core.controller("nmpc").spec
    assert got.controller_settings["horizon_steps"] == spec.horizon
    assert got.controller_settings["dt_s"] == spec.dt_s
    assert got.controller_settings["q_heading"] == spec.nmpc.q_heading
    assert "t_d_min_s" not in got.controller_settings  # the NMPC has no decision time t_d
    assert core.handle_mission(124, mission("cc-empc")).accepted
    empc = core.take_accepted(600)
    assert empc is not None and empc.controller_settings["t_d_min_s"] == spec.t_d_min_s
    assert "q_heading" not in empc.controller_settings
    # The wire form round-trips (and its schema is the registry's).
    assert MissionAccepted.decode(got.encode()) == got
    assert keys.MISSION_ACCEPTED.message is MissionAccepted


def test_taken_once_in_lockstep_and_resent_every_second_in_real_time() -> None:
    core = make_core(ScriptedSolver())
    assert core.take_accepted(0) is None and core.accepted_due(0) is None  # nothing accepted yet
    assert core.handle_mission(10, mission()).accepted
    assert core.take_accepted(10) is not None
    assert core.take_accepted(20) is None  # once

    t0 = 5 * 10**9
    first = core.accepted_due(t0)  # real time: sent at first, then once a second
    assert first is not None and first.stamp_ns == t0 and first.accepted_ns == 10
    assert core.accepted_due(t0 + ACCEPTED_REPUBLISH_NS - 1) is None
    again = core.accepted_due(t0 + ACCEPTED_REPUBLISH_NS)
    assert again is not None and again.stamp_ns == t0 + ACCEPTED_REPUBLISH_NS
    assert again.model_copy(update={"stamp_ns": t0}) == first  # the same acceptance

    # A new mission is sent at once, whatever the second; a refused one changes nothing.
    other = mission("eo-empc").model_copy(update={"mission_id": "m2"})
    assert core.handle_mission(t0 + ACCEPTED_REPUBLISH_NS + 1, other).accepted
    new = core.accepted_due(t0 + ACCEPTED_REPUBLISH_NS + 2)
    assert new is not None and (new.mission_id, new.controller) == ("m2", "eo-empc")
    bad = mission().model_copy(update={"waypoints": [Waypoint(x_m=0, y_m=0)]})
    assert not core.handle_mission(t0 + 3 * ACCEPTED_REPUBLISH_NS, bad).accepted
    assert core.accepted is not None and core.accepted.mission_id == "m2"


def test_a_checkpoint_that_cannot_be_resumed_announces_nothing() -> None:
    core = make_core(ScriptedSolver())
    assert not core.restore(0, mission(), active_leg=7, state="active", energy_used_j=1.0).accepted
    assert core.take_accepted(0) is None and core.accepted_due(0) is None


def test_lockstep_answer_lists_the_accepted_mission_once_and_again_in_a_new_episode() -> None:
    with running_controller() as controller:
        world = World(controller.hub)
        accepted = controller.hub.bus(VESSEL).subscribe(keys.MISSION_ACCEPTED, mode="fifo")
        operator = controller.hub.bus(VESSEL)
        assert world.period(0, state(0)).hold
        assert operator.request(keys.MISSION_SET, mission(), timeout_s=2.0).accepted
        again = world.next_answer(Period(0, 0))
        assert again.published[keys.MISSION_ACCEPTED.suffix] == [0]
        msg = wait_for(lambda: accepted.get(0.05), 5, what="mission/accepted")
        assert (msg.stamp_ns, msg.accepted_ns, msg.mission_id) == (0, 0, "m1")
        assert msg.waypoints_m() == [(0.0, 0.0), (8.0, 0.0), (5.13, 8.57)]
        for k in range(1, 4):  # only in the period that answered the acceptance
            assert keys.MISSION_ACCEPTED.suffix not in world.period(k, state(k)).published
        assert accepted.drain() == []
        # The world restarts: the controller restarts the mission, and says so for that episode.
        restarted = world.period(0, state(0), episode=1)
        assert restarted.published[keys.MISSION_ACCEPTED.suffix] == [0]
        assert wait_for(lambda: accepted.get(0.05), 5, what="mission/accepted again").mission_id == "m1"
