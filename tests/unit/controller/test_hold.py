"""Issue #57 item 4, the end: after the last waypoint and while the operator pauses, the controller
holds station (``seaway_controller.hold``) against current and wind with the estimator's disturbance,
until told otherwise; it drifts only if the mission asks to (``MissionRequest.at_rest``). The status
says it holds and where; the energy the hold takes is counted (battery and ``hold_energy_j``)."""

from __future__ import annotations

import math

import pytest
from seaway.contract.messages import MissionCommand, StateEstimate
from seaway.vessel.model import propulsion_power_w
from seaway.vessel.thrusters import loss_of
from seaway_controller.budget import SUDDEN_DECIDE_S
from seaway_controller.hold import hold_thrust
from seaway_lab.bench.hold import fly_hold

from tests.unit.controller.test_core import DT_NS, VP, ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_vehicle_pause import status as vehicle_status

LAST = (5.13, 8.57)
SUDDEN_STEPS = round(SUDDEN_DECIDE_S * 1e9 / DT_NS)  # the periods a sudden shortfall must last


def at(k: int, x: float, y: float, tau: tuple[float, float, float] = (0.0, 0.0, 0.0),
       psi: float = 0.0) -> StateEstimate:
    return StateEstimate.make(stamp_ns=k * DT_NS + 7, u_mps=0.0, v_mps=0.0, r_radps=0.0, x_m=x,
                              y_m=y, psi_rad=psi, tau_d_surge_n=tau[0], tau_d_sway_n=tau[1],
                              tau_d_yaw_nm=tau[2])


def completed(**kw):
    core = make_core(ScriptedSolver())
    assert core.handle_mission(0, mission().model_copy(update=kw)).accepted
    core.step(DT_NS, state(1, x=7.5, y=0.0))  # P_1
    _, _, st = core.step(2 * DT_NS, state(2, x=5.3, y=8.2))  # the last circle
    assert st.state == "complete"
    return core


def test_the_law_pushes_against_the_disturbance_and_back_to_the_point() -> None:
    # At the point, heading north, 3 N pushing it forward (north): it pushes astern, 3 N, and
    # turns its bow round into the push.
    t1, t2 = hold_thrust((0, 0, 0, 0.0, 0.0, 0.0), (0.0, 0.0), (3.0, 0.0, 0.0), VP)
    assert t1 + t2 == pytest.approx(-3.0) and abs(t1 - t2) > 1.0
    # 2 m south of the point, calm: ahead, toward it.
    t1, t2 = hold_thrust((0, 0, 0, -2.0, 0.0, 0.0), (0.0, 0.0), (0.0, 0.0, 0.0), VP)
    assert t1 + t2 > 0 and t1 == pytest.approx(t2)
    # Pushed sideways (east, to starboard): it turns its bow into it (to port: T2 > T1).
    t1, t2 = hold_thrust((0, 0, 0, 0.0, 0.0, 0.0), (0.0, 0.0), (0.0, 3.0, 0.0), VP)
    assert t2 > t1
    # Calm at the point: nothing to do.
    assert hold_thrust((0, 0, 0, 0.0, 0.0, 0.0), (0.0, 0.0), (0.0, 0.0, 0.0), VP) == (0.0, 0.0)


def test_after_the_last_waypoint_it_holds_there_and_says_so() -> None:
    core = completed()
    # Pushed north-east by the estimated disturbance, at the point: it holds, no MPC solve.
    cmd, record, st = core.step(3 * DT_NS, at(3, *LAST, tau=(2.0, 1.0, 0.0)))
    assert record is None and cmd.source == "hold" and st.state == "complete"
    assert (st.hold_x_m, st.hold_y_m) == LAST
    assert cmd.thrust_port_n + cmd.thrust_starboard_n < 0  # astern, against the push ahead
    expected = hold_thrust((0, 0, 0, *LAST, 0.0), LAST, (2.0, 1.0, 0.0), VP)
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == pytest.approx(expected)
    # The hold's energy is counted: to the status and to the battery's count.
    counted, held = core.energy_counted_j, st.hold_energy_j
    _, _, st = core.step(4 * DT_NS, at(4, *LAST, tau=(2.0, 1.0, 0.0)))
    power = propulsion_power_w(expected, VP) + 0.49
    assert st.hold_energy_j - held == pytest.approx(power * 0.1)
    assert core.energy_counted_j - counted == pytest.approx(power * 0.1)
    assert st.energy_used_j == core.energy_used_j  # the mission's own count ended with it


def test_it_drifts_only_on_request() -> None:
    core = completed(at_rest="drift")
    cmd, _, st = core.step(3 * DT_NS, at(3, 6.0, 8.0, tau=(2.0, 1.0, 0.0)))
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and st.hold_x_m is None


def test_on_pause_it_holds_where_it_was_until_resumed() -> None:
    core = make_core(ScriptedSolver())
    assert core.handle_mission(0, mission()).accepted
    core.step(DT_NS, state(1, x=3.0, y=0.2))
    assert core.handle_command(DT_NS, MissionCommand.make(stamp_ns=0, command="pause")).accepted
    cmd, record, st = core.step(2 * DT_NS, at(2, 3.5, 0.2))  # carried on a little
    assert st.state == "paused" and record is None and cmd.source == "hold"
    assert (st.hold_x_m, st.hold_y_m) == (3.0, 0.2)
    assert cmd.thrust_port_n + cmd.thrust_starboard_n < 0  # back, astern
    assert core.handle_command(3 * DT_NS, MissionCommand.make(stamp_ns=0, command="resume")).accepted
    cmd, record, st = core.step(3 * DT_NS, at(3, 3.5, 0.2))
    assert st.state == "active" and record is not None and st.hold_x_m is None


def test_no_hold_while_the_vehicle_withholds_the_thrust() -> None:
    core = completed()
    core.on_vehicle_status(vehicle_status(3 * DT_NS, "disarmed"))
    cmd, _, st = core.step(3 * DT_NS + 1, at(3, 6.0, 8.0, tau=(2.0, 1.0, 0.0)))
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and st.hold_x_m is None


def test_it_holds_in_a_current_and_wind_in_the_closed_loop() -> None:
    # `seaway bench hold`'s loop, shortened: simulator, estimator on realistic sensors, controller.
    f = fly_hold(hold_s=30.0)
    assert f["mean_distance_m"] <= 1.0 and f["p95_distance_m"] <= 2.0
    # Drifting, a 0.15 m/s current alone carries it 4.5 m in 30 s.
    assert f["propulsion_energy_j"] > 0 and math.isfinite(f["controller_hold_energy_j"])
    assert f["controller_hold_energy_j"] == pytest.approx(
        f["propulsion_energy_j"] + f["task_energy_j"], rel=0.05)


def test_the_energy_budget_prices_the_hold_and_returns_home_when_it_must() -> None:
    from seaway.contract.messages import BatteryState

    core = completed()
    # Enough above the reserve to hold for a while, not to get home (8.6 m at the cruise, ~200 J).
    core.on_battery(BatteryState.make(stamp_ns=2 * DT_NS, source="sim", remaining_j=1_100.0,
                                      reserve_j=1_000.0))
    sources = []
    # A shortfall from the first pricing decides once it has lasted (SUDDEN_DECIDE_S).
    for k in range(3, 40 + SUDDEN_STEPS):
        cmd, _, st = core.step(k * DT_NS, at(k, *LAST, tau=(0.5, 0.0, 0.0)))
        sources.append(cmd.source)
        if st.state == "active":
            break
    # Priced while holding (the hold drains the battery): the policy 'return' flies home.
    assert sources[0] == "hold" and core.budget is not None and core.budget.returning
    assert st.mission_id == "m1/return" and st.state == "active"


def test_the_budgets_hold_policy_stops_the_station_keeping() -> None:
    from seaway.contract.messages import BatteryState

    core = completed(on_low_energy="hold")
    core.on_battery(BatteryState.make(stamp_ns=2 * DT_NS, source="sim", remaining_j=1_100.0,
                                      reserve_j=1_000.0))
    # A shortfall from the first pricing decides once it has lasted (SUDDEN_DECIDE_S).
    for k in range(3, 40 + SUDDEN_STEPS):
        cmd, _, st = core.step(k * DT_NS, at(k, *LAST, tau=(0.5, 0.0, 0.0)))
    assert st.state == "complete" and st.hold_x_m is None and "energy budget" in st.reason
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)


def test_abort_stops_the_hold_at_the_end() -> None:
    core = completed()
    cmd, _, _ = core.step(3 * DT_NS, at(3, *LAST, tau=(2.0, 1.0, 0.0)))
    assert cmd.source == "hold"
    reply = core.handle_command(3 * DT_NS, MissionCommand.make(stamp_ns=0, command="abort"))
    assert reply.accepted
    cmd, _, st = core.step(4 * DT_NS, at(4, *LAST, tau=(2.0, 1.0, 0.0)))
    assert st.state == "aborted" and st.hold_x_m is None
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0)
    # Nothing left to stop: a second abort is refused.
    assert not core.handle_command(5 * DT_NS, MissionCommand.make(stamp_ns=0, command="abort")).accepted


def test_a_thruster_found_short_is_asked_for_more_and_its_loss_not_held_against() -> None:
    """The estimate says the port thruster gives 50 % of its command. Its disturbance carries that
    loss at the last command; the hold takes it out (it would push against a loss, not against the
    water) and asks the port thruster for twice the thrust it wants from it."""
    plain, weak = completed(), completed()
    assert plain._last_command == weak._last_command
    given = (0.5, 1.0)
    surge_n, yaw_nm = loss_of(*weak._last_command, given, VP.arm_m)
    tau = (0.6, 0.3, 0.0)
    cmd, _, _ = plain.step(3 * DT_NS, at(3, LAST[0] - 0.5, LAST[1], tau=tau))
    said = at(3, LAST[0] - 0.5, LAST[1], tau=(tau[0] + surge_n, tau[1], tau[2] + yaw_nm))
    said = said.model_copy(update={"thrust_short_side": "port", "thrust_short_frac": 0.5})
    cmd_weak, _, st = weak.step(3 * DT_NS, said)
    assert cmd_weak.source == "hold" and st.hold_x_m is not None
    assert 0.0 < abs(cmd.thrust_port_n) < VP.thrust_max_n / 2
    assert cmd_weak.thrust_port_n == pytest.approx(2.0 * cmd.thrust_port_n)
    assert cmd_weak.thrust_starboard_n == pytest.approx(cmd.thrust_starboard_n)
