"""A mission that cannot be flown is refused before it starts, saying why (issue #56, item 24).

``seaway mission paper-c1`` sent to the lake stack turned at once into a return home whose energy
was infinite: paper condition #1's task power (0.49 W) on the lake boat cruises at 0.045 m/s on
1.5 N of thrust, which the lake's wind and current (about 1.5 N, as the estimator had it) leave
no way on some courses."""

from __future__ import annotations

import math

from seaway.contract.messages import BatteryState, MissionRequest, StateEstimate, Waypoint
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_controller.acceptance import why_not_flyable
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.energy import EnergyModel

from tests.unit.controller.test_core import ScriptedSolver

BOAT = load_vessel("paper-boat")
C1 = load_scenario("paper-c1").mission
LAKE = load_scenario("lake").mission
# The lake stack's estimate when paper-c1 was sent: tau_d (surge, sway) [N] at heading ~0.
LAKE_TAU_N = (0.81, -1.25, 0.0)


def lake_state(x: float = 0.5, y: float = -0.5, tau=LAKE_TAU_N, k: int = 0) -> StateEstimate:
    return StateEstimate.make(stamp_ns=k * 100_000_000, u_mps=0.02, v_mps=0.0, r_radps=0.0,
                              x_m=x, y_m=y, psi_rad=0.0, tau_d_surge_n=tau[0], tau_d_sway_n=tau[1],
                              tau_d_yaw_nm=tau[2])


def model(task_power_w: float) -> EnergyModel:
    return EnergyModel(BOAT, task_power_w, 1.0, True, False)


def test_a_cruise_inside_the_thrusters_dead_zone_is_named_with_its_figures() -> None:
    why = why_not_flyable(model(C1.task_power_w), None, C1.waypoints_m, C1.waypoints_m[0])
    assert why is not None and "dead zone" in why and "0.0446 m/s" in why
    least_w = float(why.split("a task power of ")[1].split(" W")[0])
    assert model(least_w).cruise_speed_mps * BOAT.xu_kgps / 2 >= BOAT.dead_zone_n
    # The lake's own task power (1 m/s on 34 N), with the lake's wind, flies.
    assert why_not_flyable(model(LAKE.task_power_w), lake_state(), C1.waypoints_m,
                           C1.waypoints_m[0]) is None


def test_a_cruise_the_disturbance_leaves_no_way_is_named_with_its_figures() -> None:
    no_dead_zone = EnergyModel(BOAT.model_copy(update={"dead_zone_n": 0.0}), C1.task_power_w, 1.0,
                               True, False)
    why = why_not_flyable(no_dead_zone, lake_state(), C1.waypoints_m, C1.waypoints_m[0])
    assert why is not None and "cannot be made good" in why and "m/s on that course" in why
    # No disturbance known, or none estimated: flown.
    assert why_not_flyable(no_dead_zone, None, C1.waypoints_m, C1.waypoints_m[0]) is None
    assert why_not_flyable(no_dead_zone, lake_state(tau=(0.0, 0.0, 0.0)), C1.waypoints_m,
                           C1.waypoints_m[0]) is None
    # The NMPC holds no economic cruise: not judged.
    nmpc = EnergyModel(BOAT, C1.task_power_w, 1.0, False, False)
    assert why_not_flyable(nmpc, lake_state(), C1.waypoints_m, C1.waypoints_m[0]) is None


def request(task_power_w: float, mission_id: str = "c1") -> MissionRequest:
    return MissionRequest.make(stamp_ns=0, mission_id=mission_id, coa_radius_m=C1.coa_radius_m,
                               task_power_w=task_power_w, controller="cc-empc",
                               waypoints=[Waypoint(x_m=x, y_m=y) for x, y in C1.waypoints_m])


def test_the_controller_refuses_it_and_flies_nothing() -> None:
    core = ControllerCore(BOAT, ControllerConfig(), solver_factory=lambda ocp: ScriptedSolver())
    core.step(0, lake_state())  # idle: the state the mission is judged on
    reply = core.handle_mission(1, request(C1.task_power_w))
    assert not reply.accepted
    assert "cannot be flown" in reply.reason and "0.0446 m/s" in reply.reason
    assert core.missions.state == "idle" and core.budget is None and core.accepted is None
    # A mission it can fly is taken as before.
    assert core.handle_mission(2, request(LAKE.task_power_w, "fast")).accepted


def test_a_battery_short_of_the_mission_is_refused_unless_forced_and_said_at_the_start() -> None:
    core = ControllerCore(BOAT, ControllerConfig(), solver_factory=lambda ocp: ScriptedSolver())
    core.on_battery(BatteryState.make(stamp_ns=0, source="sim", remaining_j=1_000.0, reserve_j=600.0))
    core.step(0, lake_state(tau=(0.0, 0.0, 0.0)))
    # The mission check (mission_check.py): it cannot finish and get home on 400 J.
    refused = core.handle_mission(1, request(LAKE.task_power_w))
    assert not refused.accepted and "send it with force" in refused.reason
    assert "less its 600 J reserve (400 J)" in refused.reason
    assert core.missions.state == "idle"
    # Forced by the operator: flown, the shortfall said, and the force recorded.
    reply = core.handle_mission(1, request(LAKE.task_power_w).model_copy(update={"force": True}))
    assert reply.accepted and "400 J above its reserve" in reply.reason
    assert core.accepted is not None and core.accepted.forced
    needs = float(reply.reason.split("needs about ")[1].split(" J")[0])
    assert math.isfinite(needs) and needs > 400.0


def test_an_uncertain_disturbance_refuses_nothing_a_settled_one_does() -> None:
    """The same estimated force: with the uncertainty of an estimate just started (a standard
    deviation as large as the force) the mission is flown; settled (a fiftieth of it), refused as
    before. Seen on PX4's firmware: 140 N estimated at rest a second after boot refused the lake."""
    no_dead_zone = EnergyModel(BOAT.model_copy(update={"dead_zone_n": 0.0}), C1.task_power_w, 1.0,
                               True, False)

    def with_std(std_n: float) -> StateEstimate:
        cov = [0.0] * 81
        for i, var in ((6, std_n ** 2), (7, std_n ** 2), (8, 0.01)):
            cov[i * 9 + i] = var
        return lake_state().model_copy(update={"covariance": cov})

    force = math.hypot(LAKE_TAU_N[0], LAKE_TAU_N[1])
    assert why_not_flyable(no_dead_zone, with_std(force), C1.waypoints_m, C1.waypoints_m[0]) is None
    settled = why_not_flyable(no_dead_zone, with_std(0.02 * force), C1.waypoints_m, C1.waypoints_m[0])
    assert settled is not None and "cannot be made good" in settled
