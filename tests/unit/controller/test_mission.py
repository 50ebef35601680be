"""Mission manager: validation refusals, lat/lon conversion, switching, completion, commands."""

from __future__ import annotations

import math

import pytest
from seaway.contract.messages import MessageError, MissionCommand, MissionRequest, Waypoint
from seaway.vessel.frames import GeoOrigin
from seaway_controller.mission import MissionError, MissionLimits, MissionManager, validate_mission

ORIGIN = GeoOrigin(math.radians(47.0), math.radians(8.0), 0.0)


def request(points, coa=1.0, **kw) -> MissionRequest:
    wps = [p if isinstance(p, Waypoint) else Waypoint(x_m=p[0], y_m=p[1]) for p in points]
    return MissionRequest.make(stamp_ns=0, waypoints=wps, coa_radius_m=coa, task_power_w=0.49, **kw)


def cmd(c: str) -> MissionCommand:
    return MissionCommand.make(stamp_ns=0, command=c)


@pytest.mark.parametrize(("points", "coa", "needle"), [
    ([(0, 0)], 1.0, "at least 2 waypoints"),
    ([(0, 0), (5, 0), (5, 0)], 1.0, "leg 1->2 has zero length"),
    ([(0, 0), (6000, 0)], 1.0, "waypoint 1 at (6000.0, 0.0) m is 6000 m from the origin"),
    ([(0, 0), Waypoint(x_m=3.0)], 1.0, "waypoint 1: needs both x_m and y_m"),
    ([(0, 0), Waypoint()], 1.0, "waypoint 1: has no position"),
    ([(0, 0), Waypoint(x_m=1, y_m=1, lat_deg=47, lon_deg=8)], 1.0, "not both"),
    ([(0, 0), Waypoint(lat_deg=47.0)], 1.0, "needs both lat_deg and lon_deg"),
])
def test_refusals_name_the_problem(points, coa, needle):
    with pytest.raises(MissionError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        validate_mission(request(points, coa), ORIGIN)


@pytest.mark.parametrize("coa", [0.0, -2.0])
def test_a_radius_not_above_zero_is_refused_naming_it(coa):
    """Refused by the request itself (the bus contract), and by the controller's check for a
    request that was built without validation."""
    with pytest.raises(MessageError, match="coa_radius_m"):
        request([(0, 0), (5, 0)], coa)
    unchecked = request([(0, 0), (5, 0)]).model_copy(update={"coa_radius_m": coa})
    with pytest.raises(MissionError, match="coa_radius_m"):
        validate_mission(unchecked, ORIGIN)


def test_non_finite_waypoints_cannot_even_be_built():
    with pytest.raises(ValueError, match="x_m"):
        Waypoint(x_m=math.nan, y_m=0.0)


def test_lat_lon_needs_an_origin_and_is_converted_through_it():
    north_1000 = Waypoint(lat_deg=47.0 + 1000 / 111_200, lon_deg=8.0)
    req = request([(0, 0), north_1000])
    with pytest.raises(MissionError, match="no navigation origin"):
        validate_mission(req, None)
    m = validate_mission(req, ORIGIN)
    x, y = m.waypoints_m[1]
    assert x == pytest.approx(1000.0, rel=5e-3)
    assert abs(y) < 0.01


def test_operating_area_is_configurable():
    req = request([(0, 0), (300, 0)])
    validate_mission(req, None)
    with pytest.raises(MissionError, match="outside the operating area"):
        validate_mission(req, None, MissionLimits(max_range_m=200.0))


def test_switches_on_entering_the_circle_and_completes_on_the_last():
    mm = MissionManager()
    mm.start(request([(0, 0), (8, 0), (5.13, 8.57)], coa=1.0), None)
    assert mm.update(0.0, 0.0) is None  # inside P_0's circle from the start: its first leg
    assert mm.state == "active" and mm.leg() == ((0, 0), (8, 0)) and mm.switches == 0
    assert mm.update(6.9, 0.0) is None  # 1.1 m short of P_1
    assert mm.update(7.05, 0.2) == "switched"
    assert mm.active == 2 and mm.leg() == ((8, 0), (5.13, 8.57))
    assert mm.inside_any_circle(7.5, 0.0) and not mm.inside_any_circle(6.5, 4.0)
    assert mm.update(6.0, 6.0) is None
    assert mm.update(5.5, 7.8) == "complete"
    assert mm.state == "complete"
    assert mm.update(0.0, 0.0) is None


def test_passing_several_circles_at_once():
    mm = MissionManager()
    mm.start(request([(0, 0), (2, 0), (2.5, 0), (10, 0)], coa=1.0, join_first_leg=True), None)
    assert mm.update(2.2, 0.0) == "switched"
    assert mm.active == 3


def test_pause_resume_abort():
    mm = MissionManager()
    with pytest.raises(MissionError, match="no mission"):
        mm.command(cmd("pause"))
    mm.start(request([(0, 0), (8, 0)]), None)
    with pytest.raises(MissionError, match="not paused"):
        mm.command(cmd("resume"))
    assert mm.command(cmd("pause")) == "paused"
    assert mm.update(8.0, 0.0) is None  # no switching while paused
    with pytest.raises(MissionError, match="cannot pause: the mission is paused"):
        mm.command(cmd("pause"))
    assert mm.command(cmd("resume")) == "active"
    assert mm.command(cmd("abort")) == "aborted"
    with pytest.raises(MissionError, match="already aborted"):
        mm.command(cmd("abort"))
    mm.start(request([(0, 0), (8, 0)]), None)  # a new mission replaces an aborted one
    assert mm.state == "active" and mm.active == 0  # on its way to P_0 first
