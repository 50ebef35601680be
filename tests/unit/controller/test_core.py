"""ControllerCore: idle/complete behaviour, stamps, replies and the fallback chain (injected solver)."""

from __future__ import annotations

import numpy as np
import pytest
from seaway.contract.messages import MissionCommand, MissionRequest, StateEstimate, Waypoint
from seaway.vessel.guidance import los_thrust
from seaway.vessel.model import load_vessel
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.solvers import SolveResult

VP = load_vessel("paper-sim")
DT_NS = 100_000_000


class ScriptedSolver:
    """Returns its warm start as the 'solution'; fails on calls in [fail_from, fail_until)."""

    name = "scripted"

    def __init__(self, fail_from: int = 10**9, fail_until: int = 10**9, time_s: float = 1e-4):
        self.calls = 0
        self.fail_from, self.fail_until, self.time_s = fail_from, fail_until, time_s

    def solve(self, w0, p, lam_x0, lam_g0) -> SolveResult:
        self.calls += 1
        ok = not (self.fail_from <= self.calls < self.fail_until)
        return SolveResult(w0.copy(), lam_x0.copy(), lam_g0.copy(), 1.0, ok,
                           "Solve_Succeeded" if ok else "injected_failure", 2, self.time_s)


def make_core(solver: ScriptedSolver, **cfg) -> ControllerCore:
    config = ControllerConfig(plan_reuse_steps=3, los_steps=4, **cfg)
    return ControllerCore(VP, config, solver_factory=lambda ocp: solver)


def mission(controller: str = "cc-empc", join_first_leg: bool = True) -> MissionRequest:
    # The states below are on the first leg, off P_0's circle: these tests fly that leg, joined
    # from there (by default a mission would go to P_0 first: test_start.py).
    return MissionRequest.make(stamp_ns=0, mission_id="m1", coa_radius_m=1.0, task_power_w=0.49,
                               controller=controller, join_first_leg=join_first_leg,
                               waypoints=[Waypoint(x_m=0, y_m=0), Waypoint(x_m=8, y_m=0),
                                          Waypoint(x_m=5.13, y_m=8.57)])


def state(k: int, x: float = 2.0, y: float = 0.5) -> StateEstimate:
    return StateEstimate.make(stamp_ns=k * DT_NS + 7, u_mps=0.05, v_mps=0.0, r_radps=0.0,
                              x_m=x, y_m=y, psi_rad=0.3)


def test_idle_gives_zero_thrust_and_no_solve():
    solver = ScriptedSolver()
    core = make_core(solver)
    cmd, record, status = core.step(5, state(0))
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)
    assert cmd.stamp_ns == state(0).stamp_ns
    assert record is None and status.state == "idle" and solver.calls == 0


def test_fallback_chain_plan_then_los_then_stop_then_recovery():
    solver = ScriptedSolver(fail_from=3, fail_until=12)
    core = make_core(solver)
    assert core.handle_mission(0, mission()).accepted
    out = [core.step(k * DT_NS + 7, state(k)) for k in range(13)]
    levels = [r.fallback_level for _, r, _ in out]
    sources = [c.source for c, _, _ in out]
    assert levels == [0, 0, 1, 1, 1, 2, 2, 2, 2, 3, 3, 0, 0]
    assert sources[:3] == ["cc-empc", "cc-empc", "plan-reuse"]
    assert sources[5:11] == ["los"] * 4 + ["stop"] * 2
    assert [r.fallback_count for _, r, _ in out] == [0, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 9, 9]
    assert all(not r.success for _, r, _ in out[2:11]) and out[11][1].success
    # Level 1 replays the last good plan (solved at step 1) shifted by its age.
    plan_thrusts = list(zip(out[1][1].predicted_thrust_port_n,
                            out[1][1].predicted_thrust_starboard_n, strict=True))
    for k, age in ((2, 1), (3, 2), (4, 3)):
        assert (out[k][0].thrust_port_n, out[k][0].thrust_starboard_n) == pytest.approx(
            plan_thrusts[age])
    # Level 2 is LOS guidance on the active leg.
    s = state(5)
    want = los_thrust((s.u_mps, s.v_mps, s.r_radps, s.x_m, s.y_m, s.psi_rad), (0, 0), (8, 0), VP)
    assert (out[5][0].thrust_port_n, out[5][0].thrust_starboard_n) == pytest.approx(want)
    assert want[0] != want[1]  # it steers (heading 0.3 rad off a leg due north)
    # Level 3 stops.
    assert (out[9][0].thrust_port_n, out[9][0].thrust_starboard_n) == (0.0, 0.0)
    assert all(c.stamp_ns == state(k).stamp_ns for k, (c, _, _) in enumerate(out))


def test_late_solve_is_not_applied():
    solver = ScriptedSolver(time_s=0.5)  # succeeds, but slower than the 0.1 s period
    core = make_core(solver)
    core.handle_mission(0, mission())
    cmd, record, _ = core.step(7, state(0))
    assert not record.success and "late" in record.status
    assert record.fallback_level == 2 and cmd.source == "los"  # no earlier plan to reuse
    relaxed = make_core(ScriptedSolver(time_s=0.5), solve_budget_s=None)
    relaxed.handle_mission(0, mission())
    assert relaxed.step(7, state(0))[1].success


def test_record_carries_the_cost_split_in_joules():
    core = make_core(ScriptedSolver())
    core.handle_mission(0, mission())
    _, rec, status = core.step(7, state(0))
    assert rec.controller == "cc-empc" and rec.success and rec.iterations == 2
    assert len(rec.predicted_x_m) == 11 and len(rec.predicted_thrust_port_n) == 10
    assert rec.cost_stage_j > 0 and rec.cost_dynamic_j > 0 and rec.cost_static_j > 0
    assert rec.cost_track_j > 0  # terminal point 0.5 m off the leg, outside both circles
    assert rec.leg_energy_to_go_j == pytest.approx(rec.cost_stage_j + rec.cost_dynamic_j
                                                   + rec.cost_static_j)
    assert 1.0 <= rec.t_d_s <= 60.0 and rec.t_s_s >= 0.0
    assert status.state == "active" and status.active_leg == 1
    assert status.cross_track_m == pytest.approx(0.5)
    assert status.leg_energy_to_go_j == pytest.approx(rec.leg_energy_to_go_j)
    # The mission's energy to go is the budget's (seaway_controller.energy), not the leg's.
    budget = core.take_budget()
    assert budget is not None and status.energy_to_go_j == pytest.approx(budget.energy_to_go_j)


def test_nmpc_record_has_no_empc_terms():
    core = make_core(ScriptedSolver())
    core.handle_mission(0, mission("nmpc"))
    _, rec, _ = core.step(7, state(0))
    assert rec.controller == "nmpc" and rec.cost_dynamic_j is None and rec.t_d_s is None


def test_completion_pause_and_refusals():
    core = make_core(ScriptedSolver())
    refused = core.handle_mission(0, MissionRequest.make(
        stamp_ns=0, waypoints=[Waypoint(x_m=0, y_m=0)], coa_radius_m=1, task_power_w=0.49))
    assert not refused.accepted and "at least 2 waypoints" in refused.reason
    assert not core.handle_command(0, MissionCommand.make(stamp_ns=0, command="resume")).accepted
    core.handle_mission(0, mission())
    assert core.handle_command(0, MissionCommand.make(stamp_ns=0, command="pause")).accepted
    cmd, rec, status = core.step(7, state(0))
    assert rec is None and status.state == "paused" and cmd.thrust_port_n == 0.0
    core.handle_command(0, MissionCommand.make(stamp_ns=0, command="resume"))
    core.step(DT_NS, state(1, x=7.5, y=0.0))  # enters P_1's circle: switch to leg 2
    assert core.missions.active == 2
    cmd, rec, status = core.step(2 * DT_NS, state(2, x=5.3, y=8.2))
    assert status.state == "complete" and rec is None
    # At the end it holds station at the last waypoint (test_hold.py), no MPC solve.
    assert cmd.source == "hold" and (status.hold_x_m, status.hold_y_m) == (5.13, 8.57)


def test_energy_used_integrates_commands():
    core = make_core(ScriptedSolver())
    core.handle_mission(0, mission())
    c0, _, _ = core.step(0, state(0))
    _, _, status = core.step(DT_NS, state(1))
    p = VP.alpha_w_per_n2 * (c0.thrust_port_n ** 2 + c0.thrust_starboard_n ** 2) + 0.49
    assert status.energy_used_j == pytest.approx(p * 0.1)
    assert np.isfinite(status.energy_used_j)


class CapturingSolver(ScriptedSolver):
    def __init__(self):
        super().__init__()
        self.params = []

    def solve(self, w0, p, lam_x0, lam_g0):
        self.params.append(p.copy())
        return super().solve(w0, p, lam_x0, lam_g0)


@pytest.mark.parametrize("enabled", [False, True])
def test_disturbance_estimate_is_predicted_only_when_enabled(enabled):
    solver = CapturingSolver()
    core = make_core(solver, predict_disturbance=enabled)
    core.handle_mission(0, mission())
    s = StateEstimate.make(stamp_ns=7, u_mps=0.05, v_mps=0.0, r_radps=0.0, x_m=2.0, y_m=0.5,
                           psi_rad=0.3, tau_d_surge_n=0.015, tau_d_sway_n=0.02, tau_d_yaw_nm=0.001)
    core.step(7, s)
    want = [0.015, 0.02, 0.001] if enabled else [0.0, 0.0, 0.0]
    assert solver.params[0][12:15].tolist() == want


def test_a_state_no_vessel_could_be_in_gets_zero_thrust_and_moves_no_waypoint() -> None:
    """An estimator that ran away published 10^27 m/s as finite; the controller planned from it,
    its model's rollout threw a math domain error and the solver ground on for a second a period.
    Now such a state is refused before the MPC: zero thrust, counted, and the mission as it was."""
    solver = ScriptedSolver()
    core = make_core(solver)
    assert core.handle_mission(0, mission()).accepted
    core.step(0, state(0))
    calls = solver.calls
    wild = StateEstimate.make(stamp_ns=DT_NS + 7, u_mps=-9e27, v_mps=5e27, r_radps=1e28,
                              x_m=7.9, y_m=0.0, psi_rad=0.3)  # inside P1's circle, yet no switch
    cmd, record, status = core.step(DT_NS, wild)
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and cmd.source == "absurd_state"
    assert record is None and solver.calls == calls and core.absurd_states == 1
    assert status.state == "active" and status.active_leg == 1
    cmd, record, _ = core.step(2 * DT_NS, state(2))  # a sane state: flown again
    assert record is not None and solver.calls == calls + 1


@pytest.mark.parametrize("fields, named", [
    ({"x_m": 1e308, "y_m": -1e308}, "position"),
    ({"tau_d_surge_n": 1e8}, "disturbance force"),
    ({"tau_d_yaw_nm": 1000.0}, "disturbance moment"),
    ({"covariance": [1e308] * 81}, "covariance"),
    ({"covariance": [-1.0] * 81}, "covariance"),
])
def test_a_state_past_any_frame_disturbance_or_covariance_is_refused_naming_why(fields, named):
    """A position no local frame holds overflowed the station-keeping thrust into a NaN that was
    kept as the last command (the hold's energy stayed NaN, every status after it failed); a
    disturbance or covariance of 1e8 or 1e308 made the MPC or the energy band raise an unnamed
    error every period. Each is an absurd state now: zero thrust, counted, the reason named."""
    solver = ScriptedSolver()
    core = make_core(solver)
    assert core.handle_mission(0, mission()).accepted
    core.step(0, state(0))
    base = {"stamp_ns": DT_NS, "u_mps": 0.5, "v_mps": 0.0, "r_radps": 0.0, "x_m": 2.0, "y_m": 0.5,
            "psi_rad": 0.3}
    assert core._absurd(StateEstimate.make(**{**base, **fields})) is not None
    assert named in core._absurd(StateEstimate.make(**{**base, **fields}))
    cmd, record, status = core.step(DT_NS, StateEstimate.make(**{**base, **fields}))
    assert cmd.source == "absurd_state" and record is None and core.absurd_states == 1
    assert np.isfinite(status.energy_used_j)
    cmd, record, _ = core.step(2 * DT_NS, state(2))  # a sane state: flown again
    assert record is not None and cmd.source != "absurd_state"


def test_a_command_that_is_not_finite_is_never_kept_as_the_last() -> None:
    core = make_core(ScriptedSolver())
    core._last_command = (1.0, 2.0)
    with pytest.raises(ValueError, match="thrust_port_n"):
        core._command(0, (float("nan"), 0.0), "test")
    assert core._last_command == (1.0, 2.0)
