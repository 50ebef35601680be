"""The simulated plant: the vessel model integrated with its actuators and disturbances.

A pure core, stepped by the simulator's core (``seaway_sim.core.SimCore``), which the service and the
in-process closed loop (``seaway_lab.closed_loop``: benchmarks, the paper's table) share: no clock,
no bus, no randomness of its own (the scenario's seeded disturbance model is the only source).
``step(command, dt)`` holds the commanded thrusts over ``dt`` and integrates with RK4 at
``internal_dt_s`` (default 10 ms, 100 Hz), sampling the disturbance at each internal step.

Actuator model, applied in this order to each thruster's command [N]:

1. saturation: ``-reverse_max_n <= T <= thrust_max_n`` (vessel file; ``seaway.vessel.thrusters``);
2. dead zone (if enabled): ``|T| < dead_zone_n`` gives 0 (the real boat's 10 N; the same module);
3. a scheduled thruster fault (``seaway.simkit.faults``): times ``factor`` while it lasts, or the
   stuck thrust of a ``stuck_thruster``;
4. first-order lag (if enabled): ``T' = (T_cmd - T) / thruster_time_constant_s``, exact per step.

A scheduled ``grounding`` holds the vessel where it is while it lasts: zero speeds, the pose of the
step it began, whatever the thrust (which still costs its energy).

Energy: the paper's metric integrates ``alpha (T1^2 + T2^2)`` over the run (eq. 3); ``energy_j`` here is
that integral of the thrust actually produced, by the trapezoid rule over internal steps. The task
power T^w is a mission property and is added by whoever reports mission energy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from seaway.simkit.compiled import MAX_SUBSTEPS, Substeps
from seaway.simkit.faults import ThrusterFaults
from seaway.simkit.scenario import DisturbanceModel, Scenario, WorldGrid, body_force
from seaway.vessel import model
from seaway.vessel.model import VesselParams
from seaway.vessel.thrusters import apply_dead_zone, saturate


@dataclass
class PlantState:
    """Everything the plant carries between steps."""

    t_s: float
    x: list[float]  # [u, v, r, x, y, psi]
    thrust_n: tuple[float, float] = (0.0, 0.0)  # produced by the thrusters now
    energy_j: float = 0.0
    last_disturbance_body: tuple[float, float, float] = (0.0, 0.0, 0.0)
    last_current_ne: tuple[float, float] = (0.0, 0.0)
    history: list[tuple[float, ...]] = field(default_factory=list)


class Plant:
    """One simulated vessel in one scenario."""

    def __init__(self, scenario: Scenario, vessel: VesselParams, internal_dt_s: float = 0.01) -> None:
        if not internal_dt_s > 0:
            raise ValueError("internal_dt_s must be > 0")
        self.scenario = scenario
        self.p = vessel
        self.internal_dt_s = internal_dt_s
        self.dead_zone_n = vessel.dead_zone_n if scenario.dead_zone else 0.0
        tc = vessel.thruster_time_constant_s if scenario.thruster_lag else 0.0
        self.lag_tc_s = tc
        self.thruster_faults = ThrusterFaults(scenario.faults, (-vessel.reverse_max_n,
                                                                vessel.thrust_max_n))
        # Substeps whose inputs are all known before the first (no fault, no lag, no disturbance
        # field varying with position) are integrated compiled, the same floats
        # (``seaway.simkit.compiled``); the others in Python.
        batchable = (not self.thruster_faults.items and not self.thruster_faults.groundings
                     and tc == 0.0
                     and not any(isinstance(d, WorldGrid) for d in scenario.disturbances))
        self.substeps = Substeps.make(vessel) if batchable else None
        self.reset()

    def reset(self) -> None:
        s = self.scenario.start
        self.disturbance = DisturbanceModel(self.scenario.disturbances, self.scenario.seed)
        self.state = PlantState(t_s=0.0, x=[s.u_mps, 0.0, 0.0, s.x_m, s.y_m, s.psi_rad])

    def actuate(self, command_n: tuple[float, float]) -> tuple[float, float]:
        """Commanded thrusts after saturation and dead zone (before the lag) [N]."""
        return (apply_dead_zone(saturate(command_n[0], self.p), self.dead_zone_n),
                apply_dead_zone(saturate(command_n[1], self.p), self.dead_zone_n))

    def step(self, command_n: tuple[float, float], dt_s: float) -> PlantState:
        """Hold ``command_n`` (T1 port, T2 starboard) [N] for ``dt_s`` and integrate."""
        if not (math.isfinite(command_n[0]) and math.isfinite(command_n[1])):
            raise ValueError(f"thrust command must be finite, got {command_n}")
        if self.substeps is not None:
            return self._step_compiled(self.substeps, command_n, dt_s)
        st = self.state
        demanded = target = self.actuate(command_n)
        faults = (self.thruster_faults if self.thruster_faults.items or self.thruster_faults.groundings
                  else None)
        n = max(1, round(dt_s / self.internal_dt_s))
        h = dt_s / n
        decay = math.exp(-h / self.lag_tc_s) if self.lag_tc_s > 0 else 0.0
        p = self.p
        x = st.x
        thrust = st.thrust_n
        for _ in range(n):
            tau_body, force_ne, current_ne = self.disturbance.sample(st.t_s, x[3], x[4])
            if faults is not None:
                port, starboard = faults.factors(st.t_s)
                stuck = faults.stuck(st.t_s)
                target = (demanded[0] * port if stuck[0] is None else stuck[0],
                          demanded[1] * starboard if stuck[1] is None else stuck[1])
            if self.lag_tc_s > 0:
                new = (target[0] + (thrust[0] - target[0]) * decay,
                       target[1] + (thrust[1] - target[1]) * decay)
                held = ((thrust[0] + new[0]) / 2.0, (thrust[1] + new[1]) / 2.0)
            else:
                new = held = target
            p_before = model.propulsion_power_w(thrust if self.lag_tc_s > 0 else target, p)
            if faults is not None and faults.grounded(st.t_s):
                x = [0.0, 0.0, 0.0, *x[3:6]]  # aground: held where it is
            else:
                x = model.rk4_step(x, held, h, p, math, tau_body, force_ne, current_ne)
            st.energy_j += 0.5 * (p_before + model.propulsion_power_w(new, p)) * h
            thrust = new
            st.t_s += h
            st.last_disturbance_body = body_force(tau_body, force_ne, x[5])
            st.last_current_ne = current_ne
        x[5] = math.remainder(x[5], 2.0 * math.pi)  # keep psi in [-pi, pi] without changing the state
        st.x = x
        st.thrust_n = thrust
        return st

    def _step_compiled(self, substeps: Substeps, command_n: tuple[float, float], dt_s: float
                       ) -> PlantState:
        """``step`` without faults, lag or a position-dependent disturbance: the same substeps,
        their disturbance sampled first (it depends on time only), integrated compiled."""
        st = self.state
        target = self.actuate(command_n)
        n = max(1, round(dt_s / self.internal_dt_s))
        h = dt_s / n
        p = self.p
        # The thrust is held and produced at once: the energy of each substep, as ``step`` sums it.
        power = model.propulsion_power_w(target, p)
        substep_j = 0.5 * (power + power) * h
        x = st.x
        sample = self.disturbance.sample
        done = 0
        while done < n:
            k = min(MAX_SUBSTEPS, n - done)
            inputs: list[float] = []
            for _ in range(k):
                tau_body, force_ne, current_ne = sample(st.t_s, x[3], x[4])
                inputs += (target[0], target[1], h, *tau_body, *force_ne, *current_ne)
                st.energy_j += substep_j
                st.t_s += h
            x = substeps.run(x, inputs, k)
            done += k
        st.last_disturbance_body = body_force(tau_body, force_ne, x[5])
        st.last_current_ne = current_ne
        x[5] = math.remainder(x[5], 2.0 * math.pi)
        st.x = x
        st.thrust_n = target
        return st
