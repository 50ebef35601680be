"""Line-of-sight fallback guidance (``seaway.vessel.guidance``) in the controller: alone, it can fly
a mission."""

from __future__ import annotations

import math

import pytest
from seaway.vessel.model import load_vessel
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.solvers import SolveResult
from seaway_lab.closed_loop import run_closed_loop

VP = load_vessel("paper-sim")


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


def test_the_fallback_asks_a_thruster_found_short_for_more() -> None:
    """Line-of-sight guidance wants a thrust from each side; the port thruster said to give 60 % of
    its command is asked for that divided by 0.6 (``seaway.vessel.thrusters.command_for``)."""
    from tests.unit.controller.test_core import mission, state

    config = ControllerConfig(plan_reuse_steps=0, los_steps=10)
    commands = []
    for short in (None, 0.4):
        core = ControllerCore(VP, config, solver_factory=lambda ocp: AlwaysFails())
        assert core.handle_mission(0, mission()).accepted
        s = state(1).model_copy(update={"thrust_short_side": None if short is None else "port",
                                        "thrust_short_frac": short})
        cmd, _, _ = core.step(s.stamp_ns, s)
        assert cmd.source == "los"
        commands.append((cmd.thrust_port_n, cmd.thrust_starboard_n))
    (port, starboard), (weak_port, weak_starboard) = commands
    assert 0.0 < abs(port) < 0.6 * min(VP.thrust_max_n, VP.reverse_max_n)  # not saturated
    assert weak_port == pytest.approx(port / 0.6) and weak_starboard == pytest.approx(starboard)
