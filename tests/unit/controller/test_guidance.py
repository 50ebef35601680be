"""Line-of-sight fallback guidance: geometry, limits, and that it alone can fly a mission."""

from __future__ import annotations

import math

import pytest
from seaway.vessel.model import load_vessel
from seaway_controller.core import ControllerConfig, ControllerCore
from seaway_controller.guidance import los_heading_rad, los_thrust
from seaway_controller.solvers import SolveResult
from seaway_lab.closed_loop import run_closed_loop

VP = load_vessel("paper-sim")


def test_heading_aims_at_the_look_ahead_point_on_the_leg():
    # Leg due north; vessel 1 m east of it, 3 m along: aim 2 m further along, back toward the line.
    psi = los_heading_rad(3.0, 1.0, (0.0, 0.0), (10.0, 0.0), 2.0)
    assert psi == pytest.approx(math.atan2(-1.0, 2.0))
    # Behind the start of the leg: aim at the look-ahead point from P_{i-1}.
    assert los_heading_rad(-5.0, 0.0, (0.0, 0.0), (10.0, 0.0), 2.0) == pytest.approx(0.0)
    # Near the end: never aim past the waypoint.
    psi_end = los_heading_rad(9.5, 0.5, (0.0, 0.0), (10.0, 0.0), 2.0)
    assert psi_end == pytest.approx(math.atan2(-0.5, 0.5))


def test_thrust_turns_toward_the_leg_and_respects_the_limits():
    # Heading east (psi = +pi/2) on a leg due north: turn left (counter-clockwise) -> more starboard.
    t1, t2 = los_thrust((0.1, 0.0, 0.0, 0.0, 0.0, math.pi / 2), (0.0, 0.0), (10.0, 0.0), VP)
    assert t2 > t1
    for state in [(0.0, 0.0, 0.0, 0.0, 0.0, math.pi), (2.0, 0.0, 1.0, 0.0, 0.0, 0.0)]:
        t1, t2 = los_thrust(state, (0.0, 0.0), (10.0, 0.0), VP)
        assert -VP.reverse_max_n <= t1 <= VP.thrust_max_n
        assert -VP.reverse_max_n <= t2 <= VP.thrust_max_n


class AlwaysFails:
    name = "always-fails"

    def solve(self, w0, p, lam_x0, lam_g0) -> SolveResult:
        return SolveResult(w0, lam_x0, lam_g0, math.nan, False, "injected_failure", 50, 1e-4)


def test_los_alone_completes_the_paper_mission():
    # With a solver that never succeeds, the chain must still bring the vessel home (level 2 only).
    config = ControllerConfig(plan_reuse_steps=0, los_steps=10**6)
    core = ControllerCore(VP, config, solver_factory=lambda ocp: AlwaysFails())
    r = run_closed_loop("paper-c1", "cc-empc", core=core, max_time_s=300.0)
    assert r.reached
    assert r.fallback_count == r.steps and r.unconverged == r.steps
    assert r.cross_track_mean_m < 1.0
