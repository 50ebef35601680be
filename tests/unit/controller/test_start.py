"""Issue #57 item 4, the start: a mission goes to its first waypoint first (as QGroundControl and
ArduPilot do), then flies its legs; joining the first leg from where the vessel is stays an explicit
option (``MissionRequest.join_first_leg``). A vessel that starts inside P_0's circle (the paper's
runs) flies exactly the run it flew before."""

from __future__ import annotations

import math

from seaway.simkit.scenario import load_scenario
from seaway_controller.mission import MissionManager
from seaway_lab.closed_loop import run_closed_loop

from tests.unit.controller.test_core import ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_mission import request

FAR = (4.0, -4.0)  # off the first leg's start: joining P_0 -> P_1 from here never comes near P_0


def test_the_manager_goes_to_p0_first_then_flies_the_legs() -> None:
    mm = MissionManager()
    mm.start(request([(0, 0), (8, 0), (5.13, 8.57)]), None)
    assert mm.update(*FAR) is None
    assert mm.active == 0 and mm.leg() == (FAR, (0, 0))  # from where it was first seen, to P_0
    assert mm.update(2.0, -2.0) is None and mm.leg() == (FAR, (0, 0))
    assert mm.update(0.5, -0.5) == "switched"  # into P_0's circle: its first leg
    assert mm.active == 1 and mm.leg() == ((0, 0), (8, 0)) and mm.switches == 1


def test_joining_the_first_leg_is_an_explicit_option() -> None:
    mm = MissionManager()
    mm.start(request([(0, 0), (8, 0)], join_first_leg=True), None)
    assert mm.update(*FAR) is None and mm.active == 1 and mm.leg() == ((0, 0), (8, 0))


def test_the_mpc_is_given_the_way_to_p0() -> None:
    core = make_core(ScriptedSolver())
    reply = core.handle_mission(0, mission(join_first_leg=False))
    assert reply.accepted
    _, record, status = core.step(7, state(0, *FAR))
    assert status.state == "active" and status.active_leg == 0 and record is not None
    assert status.distance_to_waypoint_m == math.dist(FAR, (0, 0))


def test_a_vessel_away_from_p0_visits_it_first() -> None:
    sc = load_scenario("paper-c1")
    sc = sc.model_copy(update={"start": sc.start.model_copy(update={"x_m": FAR[0], "y_m": FAR[1]})})
    goes = run_closed_loop(sc, "cc-empc")
    assert goes.reached and goes.unconverged == 0
    p0 = sc.mission.waypoints_m[0]
    closest = min(math.dist((t.x_m, t.y_m), p0) for t in goes.truth)
    assert closest <= sc.mission.coa_radius_m
    # Joined from where it is (the former behaviour, now on request), P_0 is never visited.
    joins = run_closed_loop(sc, "cc-empc", join_first_leg=True)
    assert joins.reached
    assert min(math.dist((t.x_m, t.y_m), p0) for t in joins.truth) > 2 * sc.mission.coa_radius_m


def test_a_vessel_starting_at_p0_flies_the_run_it_flew_before() -> None:
    # The paper's scenarios start at P_0: going there first changes nothing, bit for bit.
    first = run_closed_loop("paper-c1", "cc-empc")
    joined = run_closed_loop("paper-c1", "cc-empc", join_first_leg=True)
    assert first.trajectory == joined.trajectory and first.energy_j == joined.energy_j


def test_a_restart_on_the_way_to_p0_resumes_it() -> None:
    # The checkpoint keeps leg 0 (and a waiting mission), which it refused before.
    from seaway_controller.checkpoint import MissionCheckpoint

    req = mission(join_first_leg=False)
    for leg, st in ((0, "active"), (0, "waiting")):
        cp = MissionCheckpoint(request=req.model_dump(mode="json"), active_leg=leg, state=st,
                               energy_used_j=1.0, saved_unix_ns=1)
        core = make_core(ScriptedSolver())
        reply = core.restore(0, cp.mission_request(), cp.active_leg, cp.state, cp.energy_used_j)
        assert reply.accepted, reply.reason
        assert core.missions.active == 0 and core.missions.state == st
        if st == "waiting":
            assert "waiting for the vehicle" in core.missions.reason


def test_the_accepted_mission_says_how_it_starts_and_ends() -> None:
    core = make_core(ScriptedSolver())
    core.handle_mission(0, mission(join_first_leg=False).model_copy(update={"at_rest": "drift"}))
    acc = core.take_accepted(1)
    assert acc is not None and acc.join_first_leg is False and acc.at_rest == "drift"
    core.handle_mission(2, mission())
    acc = core.take_accepted(3)
    assert acc is not None and acc.join_first_leg is True and acc.at_rest == "hold"
