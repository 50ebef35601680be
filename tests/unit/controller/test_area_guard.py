"""The operating area the controller enforces (area_guard.py): a route leaving it refused, naming
the run; in flight, a committed course leaving it stops the mission (hold station, or return to
the nearest clear one of home and the rally points); the area announced on ``area/active``."""

from __future__ import annotations

import math

import pytest
from seaway.area.model import OperatingArea
from seaway.contract.messages import ActiveArea, StateEstimate, Waypoint
from seaway_controller.area_guard import AreaGuard, coast_m

from tests.unit.controller.test_core import DT_NS, VP, ScriptedSolver, make_core, mission

BOX = [(-5.0, -5.0), (9.5, -5.0), (9.5, 12.0), (-5.0, 12.0)]


def area(**kw) -> OperatingArea:
    return OperatingArea.make(keep_in={"name": "box", "vertices_m": BOX}, **kw)


def at(k: int, x: float, y: float, u: float = 0.0, psi: float = 0.0) -> StateEstimate:
    return StateEstimate.make(stamp_ns=k * DT_NS + 7, u_mps=u, v_mps=0.0, r_radps=0.0, x_m=x,
                              y_m=y, psi_rad=psi)


def core_with(a: OperatingArea):
    core = make_core(ScriptedSolver())
    core.area.set_area(a, "test box", 0)
    return core


def test_a_route_leaving_the_keep_in_is_refused_naming_the_leg() -> None:
    core = core_with(area())
    out = mission().model_copy(update={"waypoints": [Waypoint(x_m=0, y_m=0), Waypoint(x_m=8, y_m=0),
                                                     Waypoint(x_m=12, y_m=6)]})
    reply = core.handle_mission(0, out)
    assert not reply.accepted
    assert "leg 1->2 leaves the keep-in area" in reply.reason and "test box" in reply.reason
    assert core.missions.state == "idle"
    assert core.handle_mission(0, mission()).accepted  # inside: flown


def test_the_way_from_the_vessel_to_p0_is_checked_too() -> None:
    core = core_with(area(keep_out_circles=[{"name": "buoy", "center_m": (-2.0, 0.0),
                                             "radius_m": 1.0}]))
    core.step(DT_NS, at(1, -4.0, 0.0))  # idle, seen west of the buoy
    reply = core.handle_mission(0, mission(join_first_leg=False))
    assert not reply.accepted
    assert "the way from the vessel to P_0 enters keep-out area keep_out_circles[0] 'buoy'" in reply.reason
    # Joining the first leg instead still crosses it (to P_1).
    reply = core.handle_mission(0, mission(join_first_leg=True))
    assert not reply.accepted and "the way from the vessel to P_1" in reply.reason


def test_a_course_that_would_leave_holds_station_inside_and_says_why() -> None:
    core = core_with(area())
    assert core.handle_mission(0, mission()).accepted
    # Heading straight at the east edge (x = 9.5) at 1 m/s, 0.1 m from it: its coast alone
    # (0.38 m on this hull) crosses it.
    assert coast_m(VP, 1.0) == pytest.approx(12.84 / 33.57)
    cmd, record, st = core.step(DT_NS, at(1, 9.4, 0.0, u=1.0))
    assert record is not None  # the solve of this period is still recorded
    assert st.state == "paused" and "operating area's edge" in st.reason
    assert "leaves the keep-in area" in st.reason and "test box" in st.reason
    # Held where it stopped, moved in from the edge by HOLD_MARGIN_M (hold_point): 2 m inside.
    assert st.hold_x_m == pytest.approx(7.5, abs=0.15) and abs(st.hold_y_m) < 0.3
    assert cmd.source == "hold"
    # Well inside, the same speed goes on.
    core = core_with(area())
    assert core.handle_mission(0, mission()).accepted
    _, _, st = core.step(DT_NS, at(1, 4.0, 0.0, u=1.0))
    assert st.state == "active"


def test_the_return_policy_goes_to_the_nearest_clear_rally_point() -> None:
    a = area(rally_points=[{"name": "jetty", "position_m": (8.0, 10.0)},
                           {"name": "far", "position_m": (-4.0, 11.0)}])
    core = core_with(a)
    req = mission().model_copy(update={"on_area_breach": "return"})
    assert core.handle_mission(0, req).accepted
    _, _, st = core.step(DT_NS, at(1, 9.4, 8.0, u=1.0))
    assert st.state == "active" and st.mission_id == "m1/return"
    assert "returning" in st.reason and "leaves the keep-in area" in st.reason
    assert core.missions.mission.waypoints_m[-1] == (8.0, 10.0)  # the jetty, nearer than home
    assert core.mission_request.on_area_breach == "hold"  # the return itself only holds


def test_the_area_is_announced_when_in_force_then_once_a_second() -> None:
    guard = AreaGuard(VP, area(), "test box")
    first = guard.message(5 * DT_NS)
    assert isinstance(first, ActiveArea) and first.since_ns == 5 * DT_NS
    assert first.to_area() == area() and first.source == "test box"
    assert guard.message(6 * DT_NS) is None
    again = guard.message(15 * DT_NS)
    assert again is not None and again.since_ns == 5 * DT_NS
    assert AreaGuard(VP).message(0) is None  # no area: nothing to say


def test_a_return_may_start_outside_the_keep_in_but_not_cross_a_keep_out() -> None:
    guard = AreaGuard(VP, area(keep_out_circles=[{"center_m": (4.0, 4.0), "radius_m": 1.0}]), "box")
    outside = (10.0, 0.0)
    assert "the way from the vessel to P_1 leaves the keep-in area" in guard.refusal(
        [outside, (0.0, 0.0)], outside, True)
    assert guard.refusal([outside, (0.0, 0.0)], outside, True, returning=True) is None
    assert "enters keep-out area" in guard.refusal([outside, (0.0, 8.0)], outside, True,
                                                   returning=True)
    assert guard.return_target((8.0, 8.0), (0.0, 0.0)) is None  # the way home crosses the circle


def test_home_is_where_the_vessel_was_at_the_first_mission_or_at_arming() -> None:
    from tests.unit.controller.test_vehicle_pause import status as vehicle_status

    core = core_with(area())
    core.step(DT_NS, at(1, 1.0, 2.0))
    assert core.handle_mission(0, mission()).accepted
    assert core.missions.mission.home == (1.0, 2.0) and core.home == (1.0, 2.0)
    assert (core.accepted.home_x_m, core.accepted.home_y_m) == (1.0, 2.0)
    # A later mission keeps it; the operator's own home wins.
    core.step(2 * DT_NS, at(2, 3.0, 3.0))
    assert core.handle_mission(0, mission()).accepted and core.missions.mission.home == (1.0, 2.0)
    own = mission().model_copy(update={"home": Waypoint(x_m=0.0, y_m=5.0)})
    assert core.handle_mission(0, own).accepted and core.missions.mission.home == (0.0, 5.0)
    # A home outside the area is refused, naming it.
    out = mission().model_copy(update={"home": Waypoint(x_m=30.0, y_m=0.0)})
    reply = core.handle_mission(0, out)
    assert not reply.accepted and "home at north 30.0 m" in reply.reason
    # Arming moves home to where the vessel is.
    core.on_vehicle_status(vehicle_status(3 * DT_NS, "disarmed"))
    core.step(4 * DT_NS, at(4, 4.0, 4.0))
    core.on_vehicle_status(vehicle_status(5 * DT_NS, None))
    assert core.home == (4.0, 4.0)


def test_the_operator_sets_home_and_the_mission_under_way_takes_it() -> None:
    """``mission/home`` (#57 item 2, "set by the operator"): 'here' or a point; outside the area,
    with degrees before the origin is known, or before any state for 'here': refused, naming why.
    The mission under way takes the new home: its budget prices the way there, and the accepted
    mission is published again with it."""
    from seaway.contract.messages import HomeRequest

    core = core_with(area())
    here = HomeRequest.make(stamp_ns=0, home="here")
    refused = core.handle_home(0, here)
    assert not refused.accepted and "no state estimate" in refused.reason and core.home is None
    core.step(DT_NS, at(1, 1.0, 2.0))
    assert core.handle_mission(0, mission()).accepted
    assert core.budget is not None and core.budget.home == (1.0, 2.0)
    reply = core.handle_home(2 * DT_NS, HomeRequest.make(stamp_ns=0, home=Waypoint(x_m=0.0,
                                                                                  y_m=8.0)))
    assert reply.accepted, reply.reason
    assert reply.detail == {"home_x_m": 0.0, "home_y_m": 8.0}
    assert core.home == (0.0, 8.0) and core.missions.mission.home == (0.0, 8.0)
    assert core.budget.home == (0.0, 8.0)
    assert core.mission_request.home == Waypoint(x_m=0.0, y_m=8.0)  # what a checkpoint keeps
    assert (core.accepted.home_x_m, core.accepted.home_y_m) == (0.0, 8.0)
    # 'here' at a position past the mission limits (the same bound as a home given as a point).
    far = core_with(area())
    far.step(DT_NS, at(1, 1.0, 2.0))
    far._last_state = far._last_state.model_copy(update={"x_m": 50_000.0})
    refused = far.handle_home(DT_NS, here)
    assert not refused.accepted and "max" in refused.reason and far.home != (50_000.0, 2.0)
    # Outside the keep-in area: refused, home unchanged.
    out = core.handle_home(3 * DT_NS, HomeRequest.make(stamp_ns=0, home=Waypoint(x_m=30.0, y_m=0.0)))
    assert not out.accepted and "home at north 30.0 m" in out.reason and core.home == (0.0, 8.0)
    # Degrees need the origin.
    deg = core.handle_home(3 * DT_NS, HomeRequest.make(stamp_ns=0, home=Waypoint(lat_deg=28.18,
                                                                                lon_deg=112.94)))
    assert not deg.accepted and "origin" in deg.reason
    # 'here' takes the latest estimate; the next mission without a home of its own takes it.
    core.step(4 * DT_NS, at(4, 3.0, 3.0))
    assert core.handle_home(4 * DT_NS, here).accepted and core.home == (3.0, 3.0)
    assert core.handle_mission(0, mission()).accepted and core.missions.mission.home == (3.0, 3.0)


def test_a_home_request_is_validated_at_the_edge() -> None:
    """NaN, a string other than 'here', a waypoint with no position: refused by the message."""
    from seaway.contract.messages import HomeRequest, MessageError

    for bad in ({"home": "there"}, {"home": {"x_m": float("nan"), "y_m": 0.0}}, {}):
        with pytest.raises(MessageError):
            HomeRequest.make(stamp_ns=0, **bad)


def test_a_hold_point_near_the_edge_is_moved_in_and_one_inside_is_kept() -> None:
    """Station keeping wanders about its point (p95 within 2 m) while the guard does not act: a
    last waypoint 0.5 m inside the edge is held ``HOLD_MARGIN_M`` inside instead, at the nearest
    such point; one well inside is held where it is."""
    from seaway.area.model import margin_m
    from seaway_controller.area_guard import HOLD_MARGIN_M

    guard = AreaGuard(VP, area(), "test box", 0)
    near = (9.0, 3.0)  # 0.5 m from the north edge (9.5)
    moved = guard.hold_point(near)
    assert margin_m(guard.area, moved) >= HOLD_MARGIN_M
    assert math.dist(near, moved) <= 1.5 + 0.3  # straight in, to within the search's steps
    assert moved[0] < near[0]
    assert guard.hold_point((2.0, 3.0)) == (2.0, 3.0)
    assert AreaGuard(VP).hold_point(near) == near  # no area: held where asked


def test_the_controller_holds_inside_at_the_end_of_a_mission_ending_near_the_edge() -> None:
    from seaway.area.model import margin_m
    from seaway_controller.area_guard import HOLD_MARGIN_M

    core = core_with(area())
    core.step(DT_NS, at(1, 0.0, 3.0))
    end = mission().model_copy(update={"waypoints": [Waypoint(x_m=0.0, y_m=3.0),
                                                     Waypoint(x_m=9.0, y_m=3.0)]})
    assert core.handle_mission(0, end).accepted
    _, _, st = core.step(2 * DT_NS, at(2, 9.0, 3.0))  # at the last waypoint: complete
    assert st.state == "complete", st
    _, _, st = core.step(3 * DT_NS, at(3, 9.0, 3.0))
    held = (st.hold_x_m, st.hold_y_m)
    assert margin_m(core.area.area, held) >= HOLD_MARGIN_M and held[0] < 9.0
