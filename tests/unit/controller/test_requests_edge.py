"""Requests valid by type but absurd or badly timed, from an authorised sender: the controller
refuses them with a reply naming what is wrong, changes nothing it did not say it changed, never
moves the boat on its own account and never plans to leave its operating area.

Each test drives the real core (``ControllerCore``) with the scripted solver of ``test_core``."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
from seaway.contract.messages import (
    BatteryState,
    HomeRequest,
    MissionCommand,
    MissionRequest,
    Waypoint,
)
from seaway_controller.budget import SUDDEN_DECIDE_S
from seaway_controller.checkpointing import Checkpoints

from tests.unit.controller.test_area_guard import area, at, core_with
from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_hold import LAST, completed
from tests.unit.controller.test_hold import at as hold_at
from tests.unit.controller.test_vehicle_pause import status as vehicle_status

SUDDEN_STEPS = round(SUDDEN_DECIDE_S * 1e9 / DT_NS)  # periods an unforeseen shortfall must last


def command(c: str) -> MissionCommand:
    return MissionCommand.make(stamp_ns=0, command=c)  # type: ignore[arg-type]


def home_at(x_m: float, y_m: float) -> HomeRequest:
    return HomeRequest.make(stamp_ns=0, home=Waypoint(x_m=x_m, y_m=y_m))


# -- home ------------------------------------------------------------------------------------------


def test_a_refused_mission_does_not_make_where_the_vessel_is_its_home() -> None:
    """A mission refused while the vessel was outside its area used to leave home there (where
    the vessel was), and every later mission without a home of its own was refused for it, the
    vessel back inside."""
    core = core_with(area())
    core.step(DT_NS, at(1, 15.0, 0.0))  # outside the keep-in (x <= 9.5)
    refused = core.handle_mission(DT_NS, mission())
    assert not refused.accepted and "leaves the keep-in area" in refused.reason
    assert core.home is None and core.missions.state == "idle"
    core.step(2 * DT_NS, at(2, 2.0, 0.5))  # back inside
    reply = core.handle_mission(2 * DT_NS, mission())
    assert reply.accepted, reply.reason
    assert core.home == (2.0, 0.5) and core.missions.mission.home == (2.0, 0.5)


def test_a_home_set_while_holding_at_the_end_is_where_the_budget_returns() -> None:
    """A complete mission holding station keeps its budget priced; a home the operator sets then
    is where its policy flies ("home set"), not the home it had."""
    core = completed()
    reply = core.handle_home(2 * DT_NS, home_at(8.0, 8.0))
    assert reply.accepted, reply.reason
    assert core.missions.mission.home == (8.0, 8.0) and core.budget.home == (8.0, 8.0)
    assert core.accepted is not None and (core.accepted.home_x_m, core.accepted.home_y_m) == (8.0, 8.0)
    # Enough above the reserve to hold a while, not to stay: the budget's return goes there.
    core.on_battery(BatteryState.make(stamp_ns=2 * DT_NS, source="sim", remaining_j=1_100.0,
                                      reserve_j=1_000.0))
    for k in range(3, 40 + SUDDEN_STEPS):
        _, _, st = core.step(k * DT_NS, hold_at(k, *LAST, tau=(0.5, 0.0, 0.0)))  # held: drains
        if st.state == "active":
            break
    assert st.mission_id == "m1/return" and core.missions.mission.waypoints_m[-1] == (8.0, 8.0)


def flying_on_a_small_battery():
    """A mission under way with 2000 J above the reserve (its way home: tens of J)."""
    core = make_core(ScriptedSolver())
    core.on_battery(BatteryState.make(stamp_ns=0, source="sim", remaining_j=3_000.0,
                                      reserve_j=1_000.0))
    assert core.handle_mission(0, mission()).accepted
    for k in range(1, 5):
        _, _, st = core.step(k * DT_NS, state(k))
    assert st.state == "active" and core.budget.decision == "none"
    return core


def test_a_home_the_battery_cannot_reach_is_refused_and_the_mission_flies_on() -> None:
    """A home 4 km off with 2000 J left used to be taken: five seconds later the budget turned
    the mission into a return that no battery here reaches. Refused now, naming the energy."""
    core = flying_on_a_small_battery()
    reply = core.handle_home(5 * DT_NS, home_at(4_000.0, 0.0))
    assert not reply.accepted
    assert "J" in reply.reason and "'return'" in reply.reason and "abort" in reply.reason
    assert core.home is None and core.budget.home == (0.0, 0.0)  # nothing changed
    assert core.missions.mission.home == (0.0, 0.0) and core.mission_request.home is None
    for k in range(5, 20 + SUDDEN_STEPS):
        _, _, st = core.step(k * DT_NS, state(k))
    assert st.state == "active" and st.mission_id == "m1" and not core.budget.returning
    # A home within reach is taken; so is any home once no mission is under way.
    assert core.handle_home(20 * DT_NS, home_at(1.0, 1.0)).accepted
    assert core.budget.home == (1.0, 1.0)
    assert core.handle_command(21 * DT_NS, command("abort")).accepted
    assert core.handle_home(21 * DT_NS, home_at(4_000.0, 0.0)).accepted


def test_a_nearer_home_is_taken_even_when_the_battery_is_short_of_both() -> None:
    core = flying_on_a_small_battery()
    core.on_battery(BatteryState.make(stamp_ns=4 * DT_NS, source="sim", remaining_j=1_010.0,
                                      reserve_j=1_000.0))  # short of every home but here
    core.budget.home = (9.0, 9.0)  # farther than the one asked for
    assert core.handle_home(5 * DT_NS, home_at(2.0, 1.0)).accepted


# -- a checkpoint that cannot be resumed -----------------------------------------------------------


def test_a_checkpoint_leg_that_is_no_leg_leaves_the_controller_idle_and_checkpointable(
        tmp_path: Path) -> None:
    """A refused restore used to leave the mission set with the state 'idle', which no checkpoint
    holds: every save raised (in real time out of the control step: a restart loop)."""
    core = make_core(ScriptedSolver())
    reply = core.restore(0, mission(), active_leg=7, state="active", energy_used_j=1.0)
    assert not reply.accepted and "7" in reply.reason
    assert core.missions.mission is None and core.mission_request is None and core.budget is None
    assert core.progress() is None
    Checkpoints(tmp_path / "cp.json").save(core, threading.Lock(), DT_NS, force=True)
    _, _, st = core.step(DT_NS, state(1))
    assert st.state == "idle"
    assert core.handle_mission(2 * DT_NS, mission()).accepted  # it takes a mission as before


# -- a mission accepted before any state estimate --------------------------------------------------

BUOY = {"name": "buoy", "center_m": (-2.0, 0.0), "radius_m": 1.0}


def test_a_mission_taken_before_any_state_does_not_fly_a_way_through_a_keep_out() -> None:
    """Accepted with no position known, the way from the vessel to P_0 was never checked: seen
    west of a buoy, the vessel flew at it (the guard would stop it at the buoy's edge)."""
    core = core_with(area(keep_out_circles=[BUOY]))
    assert core.handle_mission(0, mission(join_first_leg=False)).accepted
    cmd, record, st = core.step(DT_NS, at(1, -4.0, 0.0))
    assert record is None and cmd.source == "hold" and st.state == "paused"
    assert "first seen" in st.reason and "buoy" in st.reason
    # Its own policy 'return' goes home (P_0 here) only on a way that stays in the area: none.
    core = core_with(area(keep_out_circles=[BUOY]))
    req = mission(join_first_leg=False).model_copy(update={"on_area_breach": "return"})
    assert core.handle_mission(0, req).accepted
    _, _, st = core.step(DT_NS, at(1, -4.0, 0.0))
    assert st.state == "paused" and "buoy" in st.reason


def test_a_mission_taken_before_any_state_with_a_clear_way_flies() -> None:
    core = core_with(area(keep_out_circles=[BUOY]))
    assert core.handle_mission(0, mission(join_first_leg=False)).accepted
    _, record, st = core.step(DT_NS, at(1, 2.0, 3.0))
    assert st.state == "active" and record is not None and st.reason == ""


def test_a_waiting_mission_whose_way_leaves_the_area_does_not_start_by_itself() -> None:
    core = core_with(area(keep_out_circles=[BUOY]))
    core.on_vehicle_status(vehicle_status(0, "disarmed"))
    reply = core.handle_mission(0, mission(join_first_leg=False))
    assert reply.accepted and core.missions.state == "waiting"
    _, _, st = core.step(DT_NS, at(1, -4.0, 0.0))
    assert st.state == "paused" and "buoy" in st.reason
    core.on_vehicle_status(vehicle_status(2 * DT_NS, None))  # armed: it must not start
    cmd, record, st = core.step(3 * DT_NS, at(3, -4.0, 0.0))
    assert st.state == "paused" and record is None and cmd.source in ("hold", "paused")


# -- already handled (kept so) ---------------------------------------------------------------------


def test_force_skips_neither_the_area_nor_the_circle_bounds() -> None:
    core = core_with(area())
    core.step(DT_NS, at(1, 2.0, 0.5))
    out = mission().model_copy(update={"force": True, "waypoints": [
        Waypoint(x_m=0, y_m=0), Waypoint(x_m=8, y_m=0), Waypoint(x_m=30, y_m=0)]})
    reply = core.handle_mission(DT_NS, out)
    assert not reply.accepted and "leaves the keep-in area" in reply.reason
    wide = mission().model_copy(update={"force": True, "coa_radius_m": 5_000.0})
    reply = core.handle_mission(DT_NS, wide)
    assert not reply.accepted and "coa_radius_m" in reply.reason
    assert core.missions.state == "idle" and core.accepted is None


@pytest.mark.parametrize("sequence, last_state", [
    (["resume", "pause", "abort"], "idle"),  # no mission: each refused
    (["pause"] * 3 + ["resume"] * 3, "active"),
    (["abort", "abort", "resume", "pause"], "aborted"),
])
def test_commands_in_odd_orders_are_refused_naming_the_state(sequence, last_state) -> None:
    core = make_core(ScriptedSolver())
    if last_state != "idle":
        assert core.handle_mission(0, mission()).accepted
        core.step(DT_NS, state(1))
    replies = [core.handle_command(DT_NS, command(c)) for c in sequence]
    assert core.missions.state == last_state
    for c, r in zip(sequence, replies, strict=True):
        if not r.accepted:
            assert c in r.reason and (last_state in r.reason or "no mission" in r.reason)


def test_a_thousand_pauses_and_resumes_leave_one_mission_flying() -> None:
    core = make_core(ScriptedSolver())
    assert core.handle_mission(0, mission()).accepted
    core.step(DT_NS, state(1))
    for _ in range(1000):
        assert core.handle_command(DT_NS, command("pause")).accepted
        assert core.handle_command(DT_NS, command("resume")).accepted
    _, record, st = core.step(2 * DT_NS, state(2))
    assert st.state == "active" and record is not None and st.hold_x_m is None


@pytest.mark.parametrize("points, named", [
    ([(1.0, 1.0)] * 5, "leg 0->1"),
    ([(0.0, 0.0), (5.0, 0.0), (5.0, 0.0), (9.0, 0.0)], "leg 1->2"),
    ([(0.0, 0.0), (0.001, 0.0)], "leg 0->1"),
])
def test_degenerate_routes_are_refused_naming_the_leg(points, named) -> None:
    core = make_core(ScriptedSolver())
    req = MissionRequest.make(stamp_ns=0, mission_id="d", coa_radius_m=0.001, task_power_w=0.49,
                              waypoints=[Waypoint(x_m=x, y_m=y) for x, y in points])
    reply = core.handle_mission(0, req)
    assert not reply.accepted and named in reply.reason and core.missions.state == "idle"


# -- resume after the energy budget held the mission -----------------------------------------------


def held_by_the_budget():
    """A mission (policy 'hold', forced past the check) the budget held: 30 J above the reserve,
    about 43 J to get home."""
    core = make_core(ScriptedSolver())
    core.on_battery(BatteryState.make(stamp_ns=0, source="sim", remaining_j=1_030.0,
                                      reserve_j=1_000.0))
    req = mission().model_copy(update={"on_low_energy": "hold", "force": True})
    assert core.handle_mission(0, req).accepted
    for k in range(1, 40 + SUDDEN_STEPS):
        _, _, st = core.step(k * DT_NS, state(k))
        if st.state != "active":
            break
    assert st.state == "paused" and core.budget.decision == "hold"
    return core, k


def test_a_resume_of_a_mission_the_budget_held_is_refused_while_the_battery_is_short() -> None:
    """Resumed, it used to fly on with its decision taken: the budget never acted again, the
    margin falling past 0 to the empty battery."""
    core, k = held_by_the_budget()
    reply = core.handle_command(k * DT_NS, command("resume"))
    assert not reply.accepted and "energy budget" in reply.reason and "force" in reply.reason
    cmd, record, st = core.step((k + 1) * DT_NS, state(k + 1))
    assert st.state == "paused" and record is None
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)
    assert core.handle_command(k * DT_NS, command("abort")).accepted  # still the operator's


def test_a_resume_once_the_battery_reaches_home_again_rearms_the_budget() -> None:
    core, k = held_by_the_budget()
    t = (k + 1) * DT_NS
    core.on_battery(BatteryState.make(stamp_ns=t, source="sim", remaining_j=5_000.0,
                                      reserve_j=1_000.0))  # a fresh battery
    reply = core.handle_command(t, command("resume"))
    assert reply.accepted, reply.reason
    assert core.budget.decision == "none" and core.missions.state == "active"
    # Short again later: its policy acts again.
    core.on_battery(BatteryState.make(stamp_ns=t + DT_NS, source="sim", remaining_j=1_020.0,
                                      reserve_j=1_000.0))
    for j in range(k + 2, k + 40 + SUDDEN_STEPS):
        _, _, st = core.step(j * DT_NS, state(j))
        if st.state != "active":
            break
    assert st.state == "paused" and core.budget.decision == "hold"
