"""In-process closed loop: the simulated plant and the controller core, the paper's setting.

Every ``dt`` the core gets the plant's TRUE state (as the paper's simulations do), its command is held
by the plant for ``dt``. Metrics as reproduction.md ("Metrics") defines them:

* energy: integral of alpha (T1^2 + T2^2) + T^w over the run [J] (the plant integrates the first
  term; T^w times the travel time is added);
* average cross-track error: mean over the 0.1 s samples of the distance from the active leg's line,
  counting only samples outside every circle of acceptance [m];
* travel time: from the start until the last circle of acceptance is entered [s].

Used by the tests and by ``seaway bench controller``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from seaway.contract.messages import MissionRequest, StateEstimate, Waypoint
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import Scenario, load_scenario
from seaway.vessel.model import VesselParams, load_vessel
from seaway_controller import costs
from seaway_controller.core import ControllerConfig, ControllerCore
from seaway_controller.ocp import ControllerKind

DEFAULT_MAX_TIME_S = 900.0

TABLE_I: dict[int, dict[str, tuple[float, float, float]]] = {
    # The paper's Table I: condition -> controller -> (energy J, average cross-track m, time s).
    1: {"nmpc": (2328.4, 1.686, 36.4), "eo-empc": (331.9, 0.531, 338.7),
        "cc-empc": (332.0, 0.521, 345.1)},
    2: {"nmpc": (2321.0, 1.680, 36.4), "eo-empc": (328.5, 0.542, 337.1),
        "cc-empc": (328.7, 0.520, 343.6)},
    3: {"nmpc": (2310.2, 1.672, 36.3), "eo-empc": (323.0, 0.685, 334.2),
        "cc-empc": (323.2, 0.664, 342.7)},
    4: {"nmpc": (2300.0, 1.623, 36.9), "eo-empc": (330.1, 0.507, 336.2),
        "cc-empc": (330.3, 0.477, 343.0)},
    5: {"nmpc": (2323.2, 1.655, 36.4), "eo-empc": (342.4, 0.376, 338.6),
        "cc-empc": (342.6, 0.369, 343.4)},
}


@dataclass
class ClosedLoopResult:
    scenario: str
    controller: str
    reached: bool
    travel_time_s: float
    energy_j: float
    cross_track_mean_m: float
    steps: int
    solve_times_s: list[float] = field(default_factory=list)
    successes: list[bool] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    fallback_count: int = 0
    trajectory: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    """(t, x, y, T1, T2) per step."""

    @property
    def unconverged(self) -> int:
        return sum(1 for ok in self.successes if not ok)


def scenario_mission_request(scenario: Scenario, controller: ControllerKind | None = None,
                             mission_id: str | None = None) -> MissionRequest:
    """The scenario's mission as a request (optionally with another controller)."""
    if scenario.mission is None:
        raise ValueError(f"scenario {scenario.name!r} has no mission section")
    m = scenario.mission
    return MissionRequest.make(
        stamp_ns=0, mission_id=mission_id or scenario.name,
        waypoints=[Waypoint(x_m=x, y_m=y) for x, y in m.waypoints_m],
        coa_radius_m=m.coa_radius_m, task_power_w=m.task_power_w,
        controller=controller or m.controller)


def run_closed_loop(scenario: str | Scenario, controller: ControllerKind,
                    core: ControllerCore | None = None, config: ControllerConfig | None = None,
                    vessel: VesselParams | None = None, max_time_s: float = DEFAULT_MAX_TIME_S,
                    progress: Callable[[float], None] | None = None) -> ClosedLoopResult:
    """Fly ``scenario``'s mission with ``controller``; stops on completion or at ``max_time_s``.

    Pass ``core`` to reuse compiled solvers across runs (its mission is replaced).
    """
    sc = load_scenario(scenario) if isinstance(scenario, str) else scenario
    vp = vessel or load_vessel(sc.vessel)
    cfg = config or ControllerConfig()
    core = core or ControllerCore(vp, cfg)
    dt = core.config.dt_s
    reply = core.handle_mission(0, scenario_mission_request(sc, controller))
    if not reply.accepted:
        raise ValueError(f"mission refused: {reply.reason}")
    mission = core.missions.mission
    assert mission is not None
    plant = Plant(sc, vp)
    result = ClosedLoopResult(sc.name, controller, False, math.nan, math.nan, math.nan, 0)
    xte_sum, xte_n = 0.0, 0
    n_max = round(max_time_s / dt)
    for k in range(n_max + 1):
        t = k * dt
        u, v, r, x, y, psi = plant.state.x
        stamp = round(t * 1e9)
        state = StateEstimate.make(stamp_ns=stamp, u_mps=u, v_mps=v, r_radps=r, x_m=x, y_m=y,
                                   psi_rad=max(-math.pi, min(math.pi, psi)))
        leg_before = core.missions.active
        cmd, record, status = core.step(stamp, state)
        if status.state == "complete":
            result.reached = True
            result.travel_time_s = t
            break
        if status.state != "active":
            break
        # Cross-track sample of this instant, against the leg active when it was taken.
        if not core.missions.inside_any_circle(x, y):
            wps = mission.waypoints_m
            i = leg_before
            xte_sum += abs(costs.signed_cross_track_m(x, y, wps[i - 1], wps[i]))
            xte_n += 1
        if record is not None:
            result.solve_times_s.append(record.solve_time_s)
            result.successes.append(record.success)
            result.iterations.append(record.iterations)
        thrust = (cmd.thrust_port_n, cmd.thrust_starboard_n)
        result.trajectory.append((t, x, y, thrust[0], thrust[1]))
        plant.step(thrust, dt)
        result.steps += 1
        if progress is not None:
            progress(t)
    end_t = result.travel_time_s if result.reached else result.steps * dt
    result.energy_j = plant.state.energy_j + mission.task_power_w * end_t
    result.cross_track_mean_m = xte_sum / xte_n if xte_n else math.nan
    result.fallback_count = core.fallback_count
    return result
