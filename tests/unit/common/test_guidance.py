"""seaway.vessel.guidance: the line-of-sight thrust law (the controller's fallback, the estimator
benchmark's steering): turn direction, limits, and the speed it holds on the line."""

from __future__ import annotations

import math

import pytest
from seaway.vessel.guidance import LosGains, los_thrust
from seaway.vessel.model import load_vessel, rk4_step

VP = load_vessel("paper-sim")
NORTH = ((0.0, 0.0), (10.0, 0.0))


def test_thrust_turns_toward_the_leg_and_respects_the_limits():
    # Heading east (psi = +pi/2) on a leg due north: turn left (counter-clockwise) -> more starboard.
    t1, t2 = los_thrust((0.1, 0.0, 0.0, 0.0, 0.0, math.pi / 2), *NORTH, VP)
    assert t2 > t1
    # Right of the line, heading along it: turn left toward it as well.
    t1, t2 = los_thrust((0.1, 0.0, 0.0, 5.0, 1.0, 0.0), *NORTH, VP)
    assert t2 > t1
    for state in [(0.0, 0.0, 0.0, 0.0, 0.0, math.pi), (2.0, 0.0, 1.0, 0.0, 0.0, 0.0)]:
        t1, t2 = los_thrust(state, *NORTH, VP)
        assert -VP.reverse_max_n <= t1 <= VP.thrust_max_n
        assert -VP.reverse_max_n <= t2 <= VP.thrust_max_n


def test_on_the_line_at_the_reference_speed_it_holds_the_drag_and_does_not_turn():
    u = 0.25
    t1, t2 = los_thrust((u, 0.0, 0.0, 5.0, 0.0, 0.0), *NORTH, VP, LosGains(speed_mps=u))
    assert t1 == pytest.approx(t2)
    assert t1 + t2 == pytest.approx(VP.xu_kgps * u)  # surge force = Xu u: steady at u


def test_the_speed_hint_replaces_the_gains_speed():
    state = (0.0, 0.0, 0.0, 5.0, 0.0, 0.0)
    assert los_thrust(state, *NORTH, VP, LosGains(speed_mps=0.1), speed_mps=0.3) == \
        los_thrust(state, *NORTH, VP, LosGains(speed_mps=0.3))


def test_it_converges_onto_the_line():
    x = [0.0, 0.0, 0.0, 0.0, 3.0, 0.5]  # 3 m right of a northbound leg, heading off it
    leg = ((0.0, 0.0), (200.0, 0.0))
    for _ in range(600):  # 60 s at 10 Hz
        x = rk4_step(x, los_thrust(x, *leg, VP, LosGains(speed_mps=0.25)), 0.1, VP, math)
    assert abs(x[4]) < 0.1 and abs(x[5]) < 0.05
    assert x[0] == pytest.approx(0.25, abs=0.02)
