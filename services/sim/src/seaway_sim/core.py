"""The simulator's pure core: plant + disturbances + sensors of one scenario, stepped by the caller.

No clock, bus or socket: ``advance(thrust, dt_ns)`` moves simulated time forward and the caller
reads the outputs. Time ``t_ns`` is nanoseconds since the sim epoch (0 when the sim starts);
messages are stamped ``epoch_ns + t_ns`` (``epoch_ns`` = 0 in lockstep, the wall clock at start
in real time).

* the plant is ``seaway.simkit.plant.Plant`` (paper eq. 1-2, RK4 at 100 Hz inside, saturation, optional
  dead zone and thruster lag from the scenario flags);
* the scenario's scheduled faults (``seaway.simkit.faults``) act in both: thruster faults in the
  plant, sensor faults in the sensors, timed from the scenario's start, so that real-time and
  lockstep runs get the same;
* the sensors are ``seaway.simkit.sensors.SensorSuite``; a step is split at each sensor sample instant, so
  a sample is taken of the state at its own instant whatever step the caller takes. The split does
  not change the command (held over the whole step) and keeps the 10 ms internal grid when the
  sample instants lie on it (they do for every rate dividing 100 Hz).

The battery (``seaway_sim.battery``) is the plant vessel's pack: drained by the plant's propulsion
energy plus the scenario's hotel power over the simulated time since the scenario (re)started, and
refilled by every ``load``.

The disturbance reported "now" is evaluated at the plant's current time. Evaluating it draws the
wind gust that the plant's next internal step would draw at the same instant anyway (the
disturbance model draws only when time has moved), so reporting never changes the trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from seaway.contract.messages import Attitude, BatteryState, DisturbanceForce, GnssFix, SimTruth
from seaway.contract.units import NS_PER_S
from seaway.simkit.plant import Plant
from seaway.simkit.scenario import Scenario, body_force
from seaway.simkit.sensors import SensorSuite, instants_in, origin_of
from seaway.vessel import model
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import VesselParams

from seaway_sim.battery import PackReading, SimPack


@dataclass
class Samples:
    """Sensor samples taken since they were last taken, in time order per sensor."""

    gnss: list[GnssFix | None] = field(default_factory=list)  # None: due but inside a dropout
    attitude: list[Attitude] = field(default_factory=list)


class SimCore:
    """One simulated vessel in one scenario, on the sim's clock."""

    def __init__(self, scenario: Scenario, vessel: VesselParams, epoch_ns: int = 0) -> None:
        self.epoch_ns = epoch_ns
        self.t_ns = 0
        self.load(scenario, vessel)

    def load(self, scenario: Scenario, vessel: VesselParams, restart_time: bool = False) -> None:
        """Start ``scenario`` afresh (vessel at its start pose, seeded streams restarted).

        Simulated time goes on (listeners' clocks never run backwards) unless ``restart_time``: a
        lockstep episode starts at t = 0, so that it runs exactly as in a fresh sim. Sensors sample
        now, so the new scenario's first outputs describe its start pose. The pack is refilled to
        the scenario's initial energy. ConfigError (nothing changed) if the scenario's battery does
        not fit the vessel's pack.
        """
        pack = SimPack.of(scenario, vessel)
        if restart_time:
            self.t_ns = 0
        self.pack = pack
        self.pack_since_ns = self.t_ns  # the hotel load counts from here
        self.scenario = scenario
        self.vessel = vessel
        self.plant = Plant(scenario, vessel)
        # The scenario's faults are timed from its start (the plant's time), not the sim's epoch.
        self.sensors = SensorSuite(scenario.sensors, scenario.origin, scenario.seed, scenario.faults,
                                   since_ns=self.t_ns)
        self.origin: GeoOrigin = origin_of(scenario.origin)
        self.command_n: tuple[float, float] = (0.0, 0.0)
        self.pending = Samples()
        self._sample(self.t_ns, gnss=True, attitude=True)

    # -- stepping -----------------------------------------------------------------------------

    def advance(self, command_n: tuple[float, float], dt_ns: int) -> None:
        """Hold ``command_n`` (T1 port, T2 starboard) [N] for ``dt_ns``; sample the sensors due."""
        if dt_ns <= 0:
            raise ValueError(f"dt_ns must be > 0, got {dt_ns}")
        self.command_n = command_n
        t_end = self.t_ns + dt_ns
        gnss_due = set(instants_in(self.sensors.gnss_period_ns, self.t_ns, t_end))
        att_due = set(instants_in(self.sensors.attitude_period_ns, self.t_ns, t_end))
        for t in sorted(gnss_due | att_due | {t_end}):
            self.plant.step(command_n, (t - self.t_ns) / NS_PER_S)
            self.t_ns = t
            self._sample(t, gnss=t in gnss_due, attitude=t in att_due)

    def _sample(self, t_ns: int, gnss: bool, attitude: bool) -> None:
        x = self.plant.state.x
        if gnss:
            self.pending.gnss.append(self.sensors.gnss(t_ns, x, self.current_ne(), self.epoch_ns))
        if attitude:
            self.pending.attitude.append(self.sensors.attitude(t_ns, x, self.epoch_ns))

    def take_samples(self) -> Samples:
        out, self.pending = self.pending, Samples()
        return out

    # -- outputs ------------------------------------------------------------------------------

    @property
    def stamp_ns(self) -> int:
        return self.epoch_ns + self.t_ns

    def _disturbance_now(self) -> tuple[tuple[float, float, float], tuple[float, float]]:
        st = self.plant.state
        tau_body, force_ne, current_ne = self.plant.disturbance.sample(st.t_s, st.x[3], st.x[4])
        return body_force(tau_body, force_ne, st.x[5]), current_ne

    def current_ne(self) -> tuple[float, float]:
        return self._disturbance_now()[1]

    def truth(self) -> SimTruth:
        st = self.plant.state
        u, v, r, x, y, psi = st.x
        return SimTruth(stamp_ns=self.stamp_ns, u_mps=u, v_mps=v, r_radps=r, x_m=x, y_m=y,
                        psi_rad=psi,
                        thrust_port_n=st.thrust_n[0], thrust_starboard_n=st.thrust_n[1],
                        energy_j=st.energy_j)

    def disturbance(self) -> DisturbanceForce:
        (su, sv, sr), (cn, ce) = self._disturbance_now()
        return DisturbanceForce(stamp_ns=self.stamp_ns, surge_n=su, sway_n=sv, yaw_nm=sr,
                                current_n_mps=cn, current_e_mps=ce)

    def pack_reading(self) -> PackReading:
        """The battery now (``seaway_sim.battery``)."""
        return self.pack.reading(self.plant.state.energy_j, self.t_ns - self.pack_since_ns,
                                 self.propulsion_power_w())

    def battery(self) -> BatteryState:
        """The battery now as the lockstep sim reports it on ``vehicle/battery``: its remaining
        energy is the scenario's initial energy less exactly ``truth().energy_j`` + hotel x t."""
        return self.pack_reading().message(self.stamp_ns)

    def propulsion_power_w(self) -> float:
        return model.propulsion_power_w(self.plant.state.thrust_n, self.vessel)

    def gnss_ok(self) -> bool:
        """False while a GNSS dropout (random or scheduled) is on (asked at the current time)."""
        return not self.sensors.gnss_lost(self.t_ns)
