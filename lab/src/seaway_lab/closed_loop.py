"""The in-process closed loop: one loop for every benchmark and test that needs one.

It is built from the services' own pure cores, so it simulates what the lockstep stack runs:

* the vessel, its disturbances and its sensors are the simulator's core, ``seaway_sim.core.SimCore``
  (``seaway.simkit``'s plant and sensors; RK4 at 100 Hz, the command held over each tick);
* the estimator, when given, is ``seaway_estimator.core.EstimatorCore``, fed every sensor sample and
  every command in the order the lockstep protocol defines (services/sim/README.md): the samples
  up to tick t (attitude, then GNSS), then its estimate at t, then the command computed at t;
* the steering is either the controller's core, ``ControllerCore``, from the TRUE state as the
  paper's simulations do (``run_closed_loop``: the paper's table, ``seaway bench controller``), or the
  shared line-of-sight guidance (``seaway.vessel.guidance``) round the mission's waypoints, also
  from the true state, so that the estimator is the only thing measured and its errors cannot feed
  back into the trajectory (``run_estimator_loop``: ``seaway bench estimator``).

Time is the simulator's integer nanoseconds (``SimCore.t_ns``, epoch 0); every command is held for
one tick. The paper's metrics (energy, average cross-track error, travel time: reproduction.md,
"Metrics") are ``seaway.vessel.metrics.mission_metrics`` of the simulator's ``SimTruth`` at every
tick, the same function the report applies to a recording.

With an estimator, the loop records every input it gives it (``Run.trace``), so a run can be saved as
JSON lines and replayed (``seaway_estimator.replay``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    GnssFix,
    Message,
    SimTruth,
    StateEstimate,
    ThrustCommand,
)
from seaway.contract.units import NS_PER_S, s_to_ns
from seaway.runtime.run import CONTROL_PERIOD_S
from seaway.simkit.scenario import Scenario, SensorNoise, load_scenario
from seaway.vessel.frames import GeoOrigin, wrap_pi
from seaway.vessel.guidance import LosGains, los_thrust
from seaway.vessel.metrics import MissionMetrics, mission_metrics
from seaway.vessel.model import VesselParams, load_vessel
from seaway.vessel.thrusters import output_pair
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.mission import validate_mission
from seaway_controller.ocp import ControllerKind
from seaway_estimator.core import EstimatorCore
from seaway_sim.battery import report_due_at
from seaway_sim.core import Samples, SimCore

DEFAULT_MAX_TIME_S = 900.0
ESTIMATOR_TICK_NS = 50_000_000
"""The estimator benchmark's tick: every sensor instant of ``REALISTIC_NOISE`` falls on it, and the
estimator publishes at 20 Hz."""
CONTROL_PERIOD_NS = s_to_ns(CONTROL_PERIOD_S)
"""The run's default control period (``seaway.runtime.run``): the line-of-sight steering's too."""

# Realistic sensors (issue 5): GNSS 0.3 m at 5 Hz, heading 1 deg and a MEMS gyro at 20 Hz, and a
# GNSS velocity over ground of 0.05 m/s (a typical receiver's Doppler speed accuracy).
REALISTIC_NOISE = SensorNoise(gnss_rate_hz=5.0, gnss_std_m=0.3, heading_std_rad=math.radians(1.0),
                              yaw_rate_std_radps=0.005, sog_std_mps=0.05, attitude_rate_hz=20.0)

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

Point = tuple[float, float]


# -- what a run records -----------------------------------------------------------------------------


@dataclass
class Sample:
    """One published estimate against the truth at the same instant (truth frame = scenario's)."""

    t_s: float
    pos_err_m: float
    psi_err_rad: float
    tau_true: tuple[float, float, float]
    """The simulator's disturbance now, body frame (surge N, sway N, yaw N m): ``sim/disturbance``."""
    tau_est: tuple[float, float, float]
    degraded: bool
    est: StateEstimate


@dataclass
class Run:
    """What the loop saw: the truth at every tick and, with an estimator, its estimates and costs."""

    truth: list[SimTruth] = field(default_factory=list)
    """The simulator's truth at every tick, the last one at the end of the last command's tick."""
    samples: list[Sample] = field(default_factory=list)
    gnss_err_m: list[float] = field(default_factory=list)
    """2D error of each GNSS fix fed to the estimator against the truth at its tick [m]."""
    cost_ns: dict[str, list[int]] = field(default_factory=lambda: {
        "gnss": [], "attitude": [], "thrust": [], "publish": []})
    """Wall time of each estimator call, by kind [ns]."""
    trace: list[tuple[str, Message | int]] = field(default_factory=list)
    core: EstimatorCore | None = None


@dataclass
class ClosedLoopResult:
    """A mission flown by the controller: the paper's metrics, the solves and the trajectory."""

    scenario: str
    controller: str
    reached: bool
    travel_time_s: float
    """NaN when the mission did not complete."""
    energy_j: float
    cross_track_mean_m: float
    steps: int
    """Control periods simulated (commands held)."""
    solve_times_s: list[float] = field(default_factory=list)
    successes: list[bool] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    fallback_count: int = 0
    trajectory: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    """(t, x, y, T1, T2) per step [s, m, m, N, N]."""
    budgets: list[EnergyBudget] = field(default_factory=list)
    """The controller's energy budget of each active period (``seaway_controller.budget``)."""
    truth: list[SimTruth] = field(default_factory=list)
    """The simulator's truth at every tick."""
    metrics: MissionMetrics | None = None
    run: Run | None = None

    @property
    def unconverged(self) -> int:
        return sum(1 for ok in self.successes if not ok)


# -- steering ---------------------------------------------------------------------------------------


class Steering(Protocol):
    def command(self, truth: SimTruth) -> ThrustCommand | None:
        """The command for the true state ``truth`` (stamped with its stamp); None ends the run."""
        ...


def _state(truth: SimTruth) -> tuple[float, float, float, float, float, float]:
    return truth.u_mps, truth.v_mps, truth.r_radps, truth.x_m, truth.y_m, truth.psi_rad


class MissionSteering:
    """The controller's core on the TRUE state (the paper's setting), until its mission is over."""

    def __init__(self, core: ControllerCore,
                 battery: Callable[[SimTruth], BatteryState | None] | None = None) -> None:
        self.core = core
        self.battery = battery  # the pack's report at a true state, None when none is due
        self.state = "idle"
        self.solve_times_s: list[float] = []
        self.successes: list[bool] = []
        self.iterations: list[int] = []
        self.trajectory: list[tuple[float, float, float, float, float]] = []
        self.budgets: list[EnergyBudget] = []
        self.estimate: StateEstimate | None = None  # the estimator's latest, when one runs alongside

    def observe(self, est: StateEstimate) -> None:
        """The estimator's estimate: its disturbance and covariance go with the true state (the
        energy budget predicts under the estimated disturbance; the MPC only if asked to)."""
        self.estimate = est

    def command(self, truth: SimTruth) -> ThrustCommand | None:
        t = truth.stamp_ns
        est = self.estimate
        tau = ({"tau_d_surge_n": est.tau_d_surge_n, "tau_d_sway_n": est.tau_d_sway_n,
                "tau_d_yaw_nm": est.tau_d_yaw_nm, "covariance": est.covariance}
               if est is not None else {})
        state = StateEstimate.make(stamp_ns=t, u_mps=truth.u_mps, v_mps=truth.v_mps,
                                   r_radps=truth.r_radps, x_m=truth.x_m, y_m=truth.y_m,
                                   psi_rad=max(-math.pi, min(math.pi, truth.psi_rad)), **tau)
        report = self.battery(truth) if self.battery is not None else None
        if report is not None:
            self.core.on_battery(report)
        cmd, record, status = self.core.step(t, state)
        budget = self.core.take_budget()
        if budget is not None:
            self.budgets.append(budget)
        self.state = status.state
        if status.state != "active":
            if self.battery is not None and status.state == "paused":
                return cmd  # held by the energy budget: the run goes on, stopped
            return None
        if record is not None:
            self.solve_times_s.append(record.solve_time_s)
            self.successes.append(record.success)
            self.iterations.append(record.iterations)
        self.trajectory.append((t / NS_PER_S, truth.x_m, truth.y_m, cmd.thrust_port_n,
                                cmd.thrust_starboard_n))
        return cmd


@dataclass
class LosPatrol:
    """Line-of-sight guidance (``seaway.vessel.guidance``) round the waypoints, cycling back to the
    first after the last; P_i is passed on entering its circle of acceptance."""

    waypoints: Sequence[Point]
    vessel: VesselParams
    gains: LosGains
    coa_radius_m: float
    target: int = 1

    def command(self, truth: SimTruth) -> ThrustCommand:
        wps, n = self.waypoints, len(self.waypoints)
        b = wps[self.target % n]
        if math.hypot(b[0] - truth.x_m, b[1] - truth.y_m) <= self.coa_radius_m:
            self.target += 1
        a, b = wps[(self.target - 1) % n], wps[self.target % n]
        t1, t2 = los_thrust(_state(truth), a, b, self.vessel, self.gains)
        return ThrustCommand(stamp_ns=truth.stamp_ns, thrust_port_n=t1, thrust_starboard_n=t2,
                             source="los")


# -- the loop ---------------------------------------------------------------------------------------


def fly(sim: SimCore, steering: Steering, ticks: int, tick_ns: int, *, control_every: int = 1,
        model: VesselParams | None = None, estimator: EstimatorCore | None = None,
        publish_every: int = 1,
        gnss_filter: Callable[[int, GnssFix], GnssFix | None] | None = None,
        record_trace: bool = False, progress: Callable[[float], None] | None = None) -> Run:
    """Run ticks 0..``ticks`` of ``tick_ns``, or until ``steering`` ends the run.

    At each tick t: the simulator advances to t holding the last command; the estimator (if any) gets
    the samples taken since the last tick, then publishes (every ``publish_every`` ticks); every
    ``control_every`` ticks ``steering`` commands from the truth at t. After the last tick, its command
    is held for one tick as every command is. ``gnss_filter(stamp_ns, fix)`` may replace or drop
    (None) each fix before the estimator sees it (outliers, dropouts in tests). Each command reaches
    the plant through vehicle I/O's output stage with ``model``'s limits (default: the vessel the
    scenario models), as in the lockstep sim.
    """
    run = Run(core=estimator)
    limits = model or load_vessel(sim.scenario.vessel)
    thrust = (0.0, 0.0)
    for k in range(ticks + 1):
        if k > 0:
            sim.advance(thrust, tick_ns)
        truth = sim.truth()
        run.truth.append(truth)
        samples = sim.take_samples()
        if estimator is not None:
            _sense(run, estimator, sim, samples, truth, gnss_filter, record_trace)
            if k % publish_every == 0:
                est = _publish(run, estimator, sim, truth, record_trace)
                observe = getattr(steering, "observe", None)
                if est is not None and observe is not None:
                    observe(est)
        if k % control_every == 0:
            cmd = steering.command(truth)
            if cmd is None:
                return run
            thrust = output_pair(cmd.thrust_port_n, cmd.thrust_starboard_n, limits)
            if estimator is not None:
                t0 = time.perf_counter_ns()
                estimator.on_thrust(cmd)
                run.cost_ns["thrust"].append(time.perf_counter_ns() - t0)
                if record_trace:
                    run.trace.append(("thrust", cmd))
        if progress is not None:
            progress(sim.t_ns / NS_PER_S)
    sim.advance(thrust, tick_ns)
    run.truth.append(sim.truth())
    return run


def _sense(run: Run, core: EstimatorCore, sim: SimCore, samples: Samples, truth: SimTruth,
           gnss_filter: Callable[[int, GnssFix], GnssFix | None] | None, record_trace: bool) -> None:
    clock = time.perf_counter_ns
    for att in samples.attitude:
        t0 = clock()
        core.on_attitude(att)
        run.cost_ns["attitude"].append(clock() - t0)
        if record_trace:
            run.trace.append(("attitude", att))
    for sampled in samples.gnss:
        fix = sampled
        if fix is not None and gnss_filter is not None:
            fix = gnss_filter(fix.stamp_ns, fix)
        if fix is None:
            continue
        n, e, _ = sim.origin.to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m)
        run.gnss_err_m.append(math.hypot(n - truth.x_m, e - truth.y_m))
        t0 = clock()
        core.on_gnss(fix)
        run.cost_ns["gnss"].append(clock() - t0)
        if record_trace:
            run.trace.append(("gnss", fix))


def _publish(run: Run, core: EstimatorCore, sim: SimCore, truth: SimTruth, record_trace: bool
             ) -> StateEstimate | None:
    t = truth.stamp_ns
    t0 = time.perf_counter_ns()
    est = core.predict_to(t)
    run.cost_ns["publish"].append(time.perf_counter_ns() - t0)
    if record_trace:
        run.trace.append(("tick", t))
    if est is not None and core.origin is not None:
        d = sim.disturbance()
        run.samples.append(_sample(est, truth, (d.surge_n, d.sway_n, d.yaw_nm), core.origin, sim.origin))
    return est


def _sample(est: StateEstimate, truth: SimTruth, tau_true: tuple[float, float, float],
            est_origin: GeoOrigin, truth_origin: GeoOrigin) -> Sample:
    # Compare positions as geodetic points: the estimator's origin (the first fix) need not be the
    # scenario's, and a frame offset is not an estimation error.
    if est_origin == truth_origin:
        n, e = est.x_m, est.y_m
    else:
        lat, lon, alt = est_origin.to_geodetic(est.x_m, est.y_m, 0.0)
        n, e, _ = truth_origin.to_ned(lat, lon, alt)
    return Sample(
        t_s=truth.stamp_ns / NS_PER_S,
        pos_err_m=math.hypot(n - truth.x_m, e - truth.y_m),
        psi_err_rad=wrap_pi(est.psi_rad - truth.psi_rad),
        tau_true=tau_true,
        tau_est=(est.tau_d_surge_n, est.tau_d_sway_n, est.tau_d_yaw_nm),
        degraded=est.degraded,
        est=est,
    )


# -- the two ways it is used ------------------------------------------------------------------------


def run_closed_loop(scenario: str | Scenario, controller: ControllerKind,
                    core: ControllerCore | None = None, config: ControllerConfig | None = None,
                    vessel: VesselParams | None = None, max_time_s: float = DEFAULT_MAX_TIME_S,
                    progress: Callable[[float], None] | None = None,
                    estimator: EstimatorCore | None = None,
                    battery_j: float | None = None, battery: bool = False,
                    join_first_leg: bool = False) -> ClosedLoopResult:
    """Fly ``scenario``'s mission with ``controller`` from the true state, one control period per
    tick; stops on completion or after ``max_time_s``.

    Pass ``core`` to reuse compiled solvers across runs (its origin and mission are replaced).
    ``estimator``, if given, runs alongside on the scenario's sensors (``ClosedLoopResult.run``);
    it does not steer. ``battery_j``: the pack starts with this much usable energy [J] and the
    controller hears the simulator's report (``SimCore.battery``, what the lockstep sim
    publishes) once a second; the run then goes on while the energy budget holds the mission, until
    ``max_time_s``. ``battery``: the same reports from the scenario's own pack (as a lockstep stack
    runs: the controller's budget then prices its point of no return once a second).
    ``join_first_leg``: the mission joins P_0 -> P_1 from the start pose instead of going to P_0
    first (``MissionRequest.join_first_leg``; the same run when the vessel starts at P_0).
    """
    sc = load_scenario(scenario) if isinstance(scenario, str) else scenario
    if sc.mission is None:
        raise ValueError(f"scenario {sc.name!r} has no mission section")
    if battery_j is not None:
        sc = sc.model_copy(update={"battery": sc.battery.model_copy(
            update={"initial_energy_j": battery_j})})
    vp = vessel or load_vessel(sc.vessel)
    # A simulation in process, like lockstep: a slow solve is never late, so that the result does
    # not depend on how busy the machine is (a solve budget would count a solve slowed by load as
    # unconverged).
    core = core or ControllerCore(vp, config or ControllerConfig(solve_budget_s=None))
    # The plant is the scenario's (it may differ from the model: a robustness run), as in the sim.
    sim = SimCore(sc, vp if vessel is not None else load_vessel(sc.plant_vessel_file))
    core.set_origin(sim.origin)
    req = sc.mission.to_request(0, mission_id=sc.name, controller=controller)
    reply = core.handle_mission(0, req.model_copy(update={"join_first_leg": join_first_leg}))
    if not reply.accepted:
        raise ValueError(f"mission refused: {reply.reason}")
    mission = core.missions.mission
    assert mission is not None
    reports = battery or battery_j is not None
    dt_s = core.config.dt_s

    def battery_report(truth: SimTruth) -> BatteryState | None:  # as the lockstep sim reports it
        return sim.battery() if report_due_at(truth.stamp_ns, s_to_ns(dt_s)) else None

    steering = MissionSteering(core, battery_report if reports else None)
    run = fly(sim, steering, round(max_time_s / dt_s), s_to_ns(dt_s), model=vp, estimator=estimator,
              progress=progress)
    m = mission_metrics(run.truth, mission.waypoints_m, mission.coa_radius_m, mission.task_power_w,
                        energy_j=[s.energy_j for s in run.truth], state_source=keys.SIM_TRUTH.suffix)
    reached = steering.state == "complete"
    return ClosedLoopResult(
        scenario=sc.name, controller=controller, reached=reached,
        travel_time_s=m.travel_time_s if reached and m.travel_time_s is not None else math.nan,
        energy_j=m.energy_j,
        cross_track_mean_m=m.avg_cross_track_m if m.avg_cross_track_m is not None else math.nan,
        steps=len(run.truth) - 1, solve_times_s=steering.solve_times_s, successes=steering.successes,
        iterations=steering.iterations, fallback_count=core.fallback_count,
        trajectory=steering.trajectory, metrics=m, budgets=steering.budgets, truth=run.truth,
        run=run if estimator is not None else None)


def run_estimator_loop(scenario: Scenario, core: EstimatorCore, duration_s: float,
                       noise: SensorNoise | None = None, speed_mps: float = 0.25,
                       publish_every: int = 1,
                       gnss_filter: Callable[[int, GnssFix], GnssFix | None] | None = None,
                       record_trace: bool = False) -> Run:
    """Run ``duration_s`` of ``scenario`` with ``core`` estimating, steered by line-of-sight guidance
    round the mission's waypoints at ``speed_mps``; return its errors and timings.

    Ticks of ``ESTIMATOR_TICK_NS``, a command every ``CONTROL_PERIOD_NS``. ``noise`` replaces the
    scenario's sensors section; ``gnss_filter(stamp_ns, fix)`` may replace or drop (None) each fix
    before the estimator sees it (outliers, dropouts in tests).
    """
    sc = scenario if noise is None else scenario.model_copy(update={"sensors": noise})
    vp = load_vessel(sc.vessel)
    sim = SimCore(sc, load_vessel(sc.plant_vessel_file))
    if sc.mission is not None:
        spec = sc.mission
        wps: Sequence[Point] = validate_mission(spec.to_request(0, sc.name), sim.origin).waypoints_m
        coa = spec.coa_radius_m
    else:
        wps, coa = [(0.0, 0.0), (10.0, 0.0)], 1.0
    steering = LosPatrol(wps, vp, LosGains(speed_mps=speed_mps), coa)
    return fly(sim, steering, round(duration_s * NS_PER_S / ESTIMATOR_TICK_NS), ESTIMATOR_TICK_NS,
               control_every=CONTROL_PERIOD_NS // ESTIMATOR_TICK_NS, estimator=core,
               publish_every=publish_every, gnss_filter=gnss_filter, record_trace=record_trace)


# -- estimator figures ------------------------------------------------------------------------------


def force_error_ratio(s: Sample) -> float:
    """|est - true| / |true| of the body-frame force (surge, sway) as a vector."""
    de = math.hypot(s.tau_est[0] - s.tau_true[0], s.tau_est[1] - s.tau_true[1])
    mag = math.hypot(s.tau_true[0], s.tau_true[1])
    return de / mag if mag > 0 else math.inf


def convergence(samples: list[Sample], tol: float = 0.2) -> tuple[float | None, float | None]:
    """(first time within ``tol``, time from which it stays within ``tol`` to the end) [s]."""
    first = next((s.t_s for s in samples if force_error_ratio(s) <= tol), None)
    settled = None
    for s in reversed(samples):
        if force_error_ratio(s) > tol:
            break
        settled = s.t_s
    return first, settled
