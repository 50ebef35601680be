"""Station keeping (issue #57): the paper's vessel holds a point in a 0.15 m/s current and 2 N of
wind force for 120 s; how far it strays and the energy it takes.

In the in-process closed loop (``seaway_lab.closed_loop.fly``: the simulator's, estimator's and
controller's own cores). The controller steers from the true state, as in the paper's runs, and
holds with the estimator's disturbance estimate, which runs alongside on realistic sensors
(``closed_loop.REALISTIC_NOISE``) from a cold start, so its convergence is part of the figure. The
mission's last waypoint is where the vessel starts, so the mission completes at its first period
and the whole run is the hold that follows it (``MissionRequest.at_rest`` ``hold``, the default);
the hold point is the last waypoint. The current runs east (across the bow at the start), the wind
blows from the north; gusts are added, the 2 N being their mean force.

Figures: the distance from the hold point at every control period of the hold (mean, p95, max),
the energy the hold took (the simulator's propulsion energy, T^w beside it, and the controller's own
count, ``MissionStatus.hold_energy_j``). Targets: mean <= 1 m, p95 <= 2 m.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from seaway.contract.messages import (
    MissionRequest,
    MissionStatus,
    SimTruth,
    StateEstimate,
    ThrustCommand,
    Waypoint,
)
from seaway.contract.units import NS_PER_S, s_to_ns
from seaway.runtime.argtypes import non_negative_float, positive_float
from seaway.simkit.scenario import AIR_DENSITY_KGPM3, load_scenario
from seaway.vessel.model import load_vessel
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_estimator.core import EstimatorCore
from seaway_sim.core import SimCore

from seaway_lab.bench.common import BenchResult
from seaway_lab.closed_loop import CONTROL_PERIOD_NS, ESTIMATOR_TICK_NS, REALISTIC_NOISE, fly

CURRENT_MPS = 0.15
WIND_FORCE_N = 2.0
DRAG_AREA_M2 = 0.05
HOLD_S = 120.0
MEAN_TARGET_M = 1.0
P95_TARGET_M = 2.0
TASK_POWER_W = 0.49  # the paper's T^w


class HoldSteering:
    """The controller's core on the true state with the estimator's disturbance, for ``hold_s``
    of simulated time; records the distance from the hold point and the statuses."""

    def __init__(self, core: ControllerCore, hold_s: float) -> None:
        self.core, self.end_ns = core, s_to_ns(hold_s)
        self.estimate: StateEstimate | None = None
        self.statuses: list[MissionStatus] = []
        self.commands: list[ThrustCommand] = []

    def observe(self, est: StateEstimate) -> None:
        self.estimate = est

    def command(self, truth: SimTruth) -> ThrustCommand | None:
        if truth.stamp_ns > self.end_ns:
            return None
        est = self.estimate
        tau = ({"tau_d_surge_n": est.tau_d_surge_n, "tau_d_sway_n": est.tau_d_sway_n,
                "tau_d_yaw_nm": est.tau_d_yaw_nm} if est is not None else {})
        state = StateEstimate.make(stamp_ns=truth.stamp_ns, u_mps=truth.u_mps, v_mps=truth.v_mps,
                                   r_radps=truth.r_radps, x_m=truth.x_m, y_m=truth.y_m,
                                   psi_rad=math.remainder(truth.psi_rad, 2 * math.pi), **tau)
        cmd, _, status = self.core.step(truth.stamp_ns, state)
        self.statuses.append(status)
        self.commands.append(cmd)
        return cmd


def wind_speed_for(force_n: float, drag_area_m2: float = DRAG_AREA_M2) -> float:
    """The wind speed whose drag on ``drag_area_m2`` is ``force_n`` (the simulator's law) [m/s]."""
    return math.sqrt(2.0 * force_n / (AIR_DENSITY_KGPM3 * drag_area_m2))


def fly_hold(hold_s: float = HOLD_S, gust_std_mps: float = 1.0, seed: int = 1) -> dict[str, float]:
    """Hold for ``hold_s`` and return the figures (see the module docstring)."""
    base = load_scenario("paper-c1")
    sc = type(base).model_validate({
        **base.model_dump(), "name": "hold", "seed": seed, "mission": None,
        "sensors": REALISTIC_NOISE.model_dump(),
        "disturbances": [
            {"kind": "current", "north_mps": 0.0, "east_mps": CURRENT_MPS},
            {"kind": "wind", "speed_mps": wind_speed_for(WIND_FORCE_N), "from_rad": 0.0,
             "drag_area_m2": DRAG_AREA_M2, "gust_std_mps": gust_std_mps,
             "gust_time_constant_s": 10.0}]})
    vessel = load_vessel(sc.vessel)
    sim = SimCore(sc, load_vessel(sc.plant_vessel_file))
    core = ControllerCore(vessel, ControllerConfig(solve_budget_s=None))
    core.set_origin(sim.origin)
    start = (sc.start.x_m, sc.start.y_m)
    req = MissionRequest.make(stamp_ns=0, mission_id="hold", coa_radius_m=1.0,
                              task_power_w=TASK_POWER_W, join_first_leg=True,
                              waypoints=[Waypoint(x_m=start[0] - 5.0, y_m=start[1]),
                                         Waypoint(x_m=start[0], y_m=start[1])])
    reply = core.handle_mission(0, req)
    if not reply.accepted:
        raise RuntimeError(f"the hold's mission was refused: {reply.reason}")
    steering = HoldSteering(core, hold_s)
    run = fly(sim, steering, round(hold_s * NS_PER_S / ESTIMATOR_TICK_NS) + 1, ESTIMATOR_TICK_NS,
              control_every=CONTROL_PERIOD_NS // ESTIMATOR_TICK_NS, model=vessel,
              estimator=EstimatorCore(vessel=vessel))
    holding = [s for s in steering.statuses if s.hold_x_m is not None]
    if len(holding) != len(steering.statuses) or not holding:
        raise RuntimeError("the controller did not hold station the whole run: "
                           f"{sorted({s.state for s in steering.statuses})}")
    point = (holding[-1].hold_x_m, holding[-1].hold_y_m)
    truths = [t for t in run.truth if t.stamp_ns % CONTROL_PERIOD_NS == 0]
    dist = np.array([math.dist((t.x_m, t.y_m), point) for t in truths])  # type: ignore[arg-type]
    duration_s = (run.truth[-1].stamp_ns - run.truth[0].stamp_ns) / NS_PER_S
    propulsion_j = run.truth[-1].energy_j - run.truth[0].energy_j
    thrust = np.array([(c.thrust_port_n, c.thrust_starboard_n) for c in steering.commands])
    return {
        "hold_s": duration_s, "mean_distance_m": float(dist.mean()),
        "p95_distance_m": float(np.percentile(dist, 95)), "max_distance_m": float(dist.max()),
        "final_distance_m": float(dist[-1]),
        "propulsion_energy_j": propulsion_j, "task_energy_j": TASK_POWER_W * duration_s,
        "mean_power_w": propulsion_j / duration_s,
        "controller_hold_energy_j": float(holding[-1].hold_energy_j or 0.0),
        "mean_abs_thrust_n": float(np.abs(thrust).mean()),
        "hold_x_m": float(point[0]), "hold_y_m": float(point[1]),  # type: ignore[arg-type]
    }


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench hold", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="hold 30 s instead of 120 s")
    ap.add_argument("--seconds", type=positive_float, help=f"how long to hold [s] (default {HOLD_S:g})")
    ap.add_argument("--gust-std-mps", type=non_negative_float, default=1.0,
                    help="the wind's gust speed std [m/s] (default 1; 0: a steady wind)")
    args = ap.parse_args(argv)
    hold_s = args.seconds or (30.0 if args.quick else HOLD_S)
    if not 1.0 <= hold_s <= 3600.0:
        ap.error(f"argument --seconds: {hold_s:g} s is outside [1, 3600] s")
    if args.gust_std_mps > 10.0:
        ap.error(f"argument --gust-std-mps: {args.gust_std_mps:g} m/s is above 10 m/s")
    f = fly_hold(hold_s, args.gust_std_mps)
    res = BenchResult("hold", f"Station keeping, paper-sim, {CURRENT_MPS} m/s current + "
                      f"{WIND_FORCE_N:g} N wind, {hold_s:g} s")
    res.add("mean_distance_m", f["mean_distance_m"], f"<= {MEAN_TARGET_M:g}",
            f["mean_distance_m"] <= MEAN_TARGET_M)
    res.add("p95_distance_m", f["p95_distance_m"], f"<= {P95_TARGET_M:g}",
            f["p95_distance_m"] <= P95_TARGET_M)
    res.add("max_distance_m", f["max_distance_m"])
    res.add("final_distance_m", f["final_distance_m"])
    res.add("propulsion_energy_j", f["propulsion_energy_j"], note="the simulator's alpha T^2 integral")
    res.add("mean_power_w", f["mean_power_w"], note="propulsion")
    res.add("task_energy_j", f["task_energy_j"], note=f"T^w = {TASK_POWER_W:g} W")
    res.add("controller_hold_energy_j", f["controller_hold_energy_j"],
            note="MissionStatus.hold_energy_j: propulsion + T^w, by the controller's count")
    res.add("mean_abs_thrust_n", f["mean_abs_thrust_n"])
    res.add("hold_s", f["hold_s"])
    res.meta.update({"current_mps": CURRENT_MPS, "wind_force_n": WIND_FORCE_N,
                     "gust_std_mps": args.gust_std_mps, "vessel": "paper-sim",
                     "loop": "in-process (seaway_lab.closed_loop), estimator on realistic sensors",
                     "hold_point": f"({f['hold_x_m']:g}, {f['hold_y_m']:g}) m"})
    return res
