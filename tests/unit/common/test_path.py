"""seaway.vessel.path: the cross-track sign convention, circles of acceptance, leg switching, LOS."""

from __future__ import annotations

import math

import casadi as ca
import pytest
from seaway.vessel.path import (
    advance_leg,
    cross_track_m,
    inside_any_circle,
    los_heading_rad,
    signed_cross_track_m,
)

NORTH = ((0.0, 0.0), (10.0, 0.0))  # a leg due north (NED: x north, y east)


def test_cross_track_is_positive_right_of_the_leg_in_ned():
    # Heading north, east (+y) is to the right; heading east, south (-x) is to the right.
    assert signed_cross_track_m(3.0, 2.0, *NORTH) == pytest.approx(2.0)
    assert signed_cross_track_m(3.0, -2.0, *NORTH) == pytest.approx(-2.0)
    east = ((0.0, 0.0), (0.0, 10.0))
    assert signed_cross_track_m(-1.5, 4.0, *east) == pytest.approx(1.5)
    # Reversing the leg flips the sign, not the distance.
    assert signed_cross_track_m(3.0, 2.0, NORTH[1], NORTH[0]) == pytest.approx(-2.0)


def test_cross_track_is_point_to_line_distance_on_a_diagonal_leg():
    # reproduction.md item 1: the printed numerator mixes x and y; the point-to-line distance does not.
    prev, act = (1.0, 1.0), (4.0, 5.0)
    assert abs(signed_cross_track_m(4.0, 1.0, prev, act)) == pytest.approx(2.4, rel=1e-12)
    assert signed_cross_track_m(2.5, 3.0, prev, act) == pytest.approx(0.0, abs=1e-12)
    printed = abs((prev[0] - act[1]) * 4.0 + (prev[1] - act[0]) * 1.0) / 5.0
    assert printed != pytest.approx(2.4)
    # Beyond the ends of the segment it is still the distance from the (infinite) line.
    assert cross_track_m(-2.0, -3.0, prev, act) == pytest.approx(0.0, abs=1e-12)


def test_cross_track_is_the_same_expression_for_casadi():
    x, y = ca.SX.sym("x"), ca.SX.sym("y")
    f = ca.Function("e", [x, y], [signed_cross_track_m(x, y, (1.0, 1.0), (4.0, 5.0), ca)])
    assert float(f(4.0, 1.0)) == signed_cross_track_m(4.0, 1.0, (1.0, 1.0), (4.0, 5.0))


def test_unsigned_cross_track_and_the_degenerate_leg():
    assert cross_track_m(3.0, -2.0, *NORTH) == pytest.approx(2.0)
    assert cross_track_m(4.0, -3.0, (0.0, 0.0), (3.0, 4.0)) == pytest.approx(5.0)
    assert cross_track_m(4.0, 5.0, (1.0, 1.0), (1.0, 1.0)) == pytest.approx(5.0)  # no line: the point


def test_on_the_circle_counts_as_inside():
    wps = [(0.0, 0.0), (10.0, 0.0)]
    assert inside_any_circle(9.0, 0.0, wps, 1.0)
    assert inside_any_circle(0.6, 0.8, wps, 1.0)  # exactly r from P_0
    assert not inside_any_circle(5.0, 0.0, wps, 1.0)
    assert not inside_any_circle(10.0, 1.0 + 1e-9, wps, 1.0)


def test_legs_advance_on_entering_circles_several_at_once_and_complete():
    wps = [(0.0, 0.0), (10.0, 0.0), (10.5, 0.0), (10.5, 10.0)]
    assert advance_leg(1, 5.0, 0.0, wps, 1.0) == 1  # outside P_1's circle: stays
    assert advance_leg(1, 9.2, 0.0, wps, 1.0) == 2  # in P_1's circle only (P_2 is 1.3 m away)
    assert advance_leg(1, 10.2, 0.0, wps, 1.0) == 3  # in P_1's and P_2's: both passed
    assert advance_leg(3, 10.5, 9.5, wps, 1.0) == 4  # the last circle: complete (len(wps))
    # Only the active waypoint's circle counts: being near P_3 early passes nothing.
    assert advance_leg(1, 10.5, 10.0, wps, 1.0) == 1


def test_los_heading_aims_at_the_look_ahead_point_on_the_leg():
    # Leg due north; vessel 1 m east of it, 3 m along: aim 2 m further along, back toward the line.
    assert los_heading_rad(3.0, 1.0, *NORTH, 2.0) == pytest.approx(math.atan2(-1.0, 2.0))
    # Inside the leg it is the classic LOS law: leg bearing - atan2(e, lookahead).
    prev, act = (1.0, 1.0), (4.0, 5.0)
    e = signed_cross_track_m(2.0, 3.5, prev, act)
    assert los_heading_rad(2.0, 3.5, prev, act, 2.0) == pytest.approx(math.atan2(4.0, 3.0)
                                                                      - math.atan2(e, 2.0))
    # Behind the start of the leg: aim at the look-ahead point from P_{i-1}.
    assert los_heading_rad(-5.0, 0.0, *NORTH, 2.0) == pytest.approx(0.0)
    # Near the end: never aim past the waypoint.
    assert los_heading_rad(9.5, 0.5, *NORTH, 2.0) == pytest.approx(math.atan2(-0.5, 0.5))
    # On the waypoint itself the heading is still defined (no atan2(0, 0)).
    assert math.isfinite(los_heading_rad(10.0, 0.0, *NORTH, 2.0))
