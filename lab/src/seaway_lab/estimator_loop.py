"""In-process closed loop for the benchmark and the tests: plant, sensors, steering, estimator.

``seaway.simkit.plant.Plant`` is the true vessel and ``seaway.simkit.sensors.SensorSuite``
synthesises its sensors (seeded); a line-of-sight steering law computed from the TRUE state drives
the vessel round the
scenario's mission waypoints (cycling back to the start), so the estimator is the only thing measured
and its errors cannot feed back into the trajectory. Time is integer nanoseconds on a 50 ms grid,
which every sensor instant and control tick falls on.

The loop records every input it gives the estimator (``trace``), so a run can be saved as JSON lines
and replayed (``seaway_estimator.replay``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from seaway.contract.messages import Message, StateEstimate, ThrustCommand
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import Scenario, SensorNoise
from seaway.simkit.sensors import SensorSuite, instants_in, origin_of
from seaway.vessel import model
from seaway.vessel.frames import GeoOrigin, wrap_pi
from seaway_estimator.core import EstimatorCore

NS_PER_S = 1_000_000_000
STEP_NS = 50_000_000  # the simulation grid: every sensor instant and control tick is on it
CONTROL_PERIOD_NS = 100_000_000  # 10 Hz, the controller's rate

# Realistic sensors (issue 5): GNSS 0.3 m at 5 Hz, heading 1 deg and a MEMS gyro at 20 Hz, and a
# GNSS velocity over ground of 0.05 m/s (a typical receiver's Doppler speed accuracy).
REALISTIC_NOISE = SensorNoise(gnss_rate_hz=5.0, gnss_std_m=0.3, heading_std_rad=math.radians(1.0),
                              yaw_rate_std_radps=0.005, sog_std_mps=0.05, attitude_rate_hz=20.0)


@dataclass
class LosSteering:
    """Line-of-sight steering along waypoints (cycled) at a fixed surge force, from the true state."""

    waypoints: list[tuple[float, float]]
    p: model.VesselParams
    speed_mps: float = 0.25
    coa_m: float = 1.0
    lookahead_m: float = 2.0
    omega_radps: float = 0.8
    target: int = 1

    def command(self, x: list[float]) -> tuple[float, float]:
        wps = self.waypoints
        a, b = wps[(self.target - 1) % len(wps)], wps[self.target % len(wps)]
        if math.hypot(b[0] - x[3], b[1] - x[4]) < self.coa_m:
            self.target += 1
            a, b = wps[(self.target - 1) % len(wps)], wps[self.target % len(wps)]
        leg = math.atan2(b[1] - a[1], b[0] - a[0])
        # Signed cross-track error e (positive right of the leg) and the LOS heading.
        e = -(x[3] - a[0]) * math.sin(leg) + (x[4] - a[1]) * math.cos(leg)
        psi_ref = leg - math.atan2(e, self.lookahead_m)
        m33 = self.p.m33_kgm2
        kp, kd = m33 * self.omega_radps ** 2, 2 * 0.9 * self.omega_radps * m33 - self.p.nr_kgm2ps
        yaw = kp * wrap_pi(psi_ref - x[5]) - kd * x[2]
        surge = self.p.xu_kgps * self.speed_mps
        return model.thrusts_for_wrench(surge, yaw, self.p)


@dataclass
class Sample:
    """One published estimate against the truth at the same instant (truth frame = scenario's)."""

    t_s: float
    pos_err_m: float
    psi_err_rad: float
    tau_true: tuple[float, float, float]
    tau_est: tuple[float, float, float]
    degraded: bool
    est: StateEstimate


@dataclass
class Run:
    samples: list[Sample] = field(default_factory=list)
    gnss_err_m: list[float] = field(default_factory=list)
    cost_ns: dict[str, list[int]] = field(default_factory=lambda: {
        "gnss": [], "attitude": [], "thrust": [], "publish": []})
    trace: list[tuple[str, Message | int]] = field(default_factory=list)
    core: EstimatorCore | None = None


def run_closed_loop(scenario: Scenario, core: EstimatorCore, duration_s: float,
                    noise: SensorNoise | None = None, speed_mps: float = 0.25,
                    publish_every: int = 1,
                    gnss_filter: Callable[[int, object], object | None] | None = None,
                    record_trace: bool = False) -> Run:
    """Run ``duration_s`` of ``scenario`` with ``core`` estimating; return errors and timings.

    ``noise`` replaces the scenario's sensors section; ``gnss_filter(stamp_ns, fix)`` may replace or
    drop (None) each fix before the estimator sees it (outliers, dropouts in tests).
    """
    plant = Plant(scenario, model.load_vessel(scenario.vessel))
    sensors = SensorSuite(noise or scenario.sensors, scenario.origin, scenario.seed)
    truth_origin = origin_of(scenario.origin)
    mission = scenario.mission
    wps = mission.waypoints_m if mission else [(0.0, 0.0), (10.0, 0.0)]
    steer = LosSteering(list(wps), plant.p, speed_mps=speed_mps,
                        coa_m=mission.coa_radius_m if mission else 1.0)
    run = Run(core=core)
    clock = time.perf_counter_ns
    t_prev, t = -1, 0
    n_steps = round(duration_s * NS_PER_S / STEP_NS)
    cmd = (0.0, 0.0)
    for k in range(n_steps + 1):
        if k > 0:
            plant.step(cmd, STEP_NS / NS_PER_S)
        t = k * STEP_NS
        x = list(plant.state.x)
        for ts in instants_in(sensors.attitude_period_ns, t_prev, t):
            att = sensors.attitude(ts, x)
            t0 = clock()
            core.on_attitude(att)
            run.cost_ns["attitude"].append(clock() - t0)
            if record_trace:
                run.trace.append(("attitude", att))
        for ts in instants_in(sensors.gnss_period_ns, t_prev, t):
            fix = sensors.gnss(ts, x, plant.state.last_current_ne)
            if fix is not None and gnss_filter is not None:
                fix = gnss_filter(ts, fix)
            if fix is None:
                continue
            n, e, _ = truth_origin.to_ned(fix.lat_rad, fix.lon_rad, fix.alt_m)
            run.gnss_err_m.append(math.hypot(n - x[3], e - x[4]))
            t0 = clock()
            core.on_gnss(fix)
            run.cost_ns["gnss"].append(clock() - t0)
            if record_trace:
                run.trace.append(("gnss", fix))
        t_prev = t
        if k % publish_every == 0:
            t0 = clock()
            est = core.predict_to(t)
            run.cost_ns["publish"].append(clock() - t0)
            if record_trace:
                run.trace.append(("tick", t))
            if est is not None and core.origin is not None:
                run.samples.append(_sample(t, est, x, plant, core.origin, truth_origin))
        if t % CONTROL_PERIOD_NS == 0:
            cmd = steer.command(x)
            tc = ThrustCommand(stamp_ns=t, thrust_port_n=cmd[0], thrust_starboard_n=cmd[1],
                               source="los")
            t0 = clock()
            core.on_thrust(tc)
            run.cost_ns["thrust"].append(clock() - t0)
            if record_trace:
                run.trace.append(("thrust", tc))
    return run


def _sample(t: int, est: StateEstimate, x: list[float], plant: Plant, est_origin: GeoOrigin,
            truth_origin: GeoOrigin) -> Sample:
    # Compare positions as geodetic points: the estimator's origin (the first fix) need not be the
    # scenario's, and a frame offset is not an estimation error.
    if est_origin == truth_origin:
        n, e = est.x_m, est.y_m
    else:
        lat, lon, alt = est_origin.to_geodetic(est.x_m, est.y_m, 0.0)
        n, e, _ = truth_origin.to_ned(lat, lon, alt)
    return Sample(
        t_s=t / NS_PER_S,
        pos_err_m=math.hypot(n - x[3], e - x[4]),
        psi_err_rad=wrap_pi(est.psi_rad - x[5]),
        tau_true=plant.state.last_disturbance_body,
        tau_est=(est.tau_d_surge_n, est.tau_d_sway_n, est.tau_d_yaw_nm),
        degraded=est.degraded,
        est=est,
    )


def rms(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values) / len(values)) if values else math.nan


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
