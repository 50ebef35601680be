"""The simulated propulsion battery: the plant vessel file's pack, drained by the propulsion energy
the plant integrates plus the scenario's hotel power.

Pure: no clock, no bus. The pack is the plant vessel file's ``[battery]`` (``seaway.vessel.battery``;
a vessel file without one gets ``NOMINAL_PACK``); it starts at the scenario's
``[battery].initial_energy_j`` (default full) and, after ``elapsed_ns`` of simulated time since the
scenario (re)started, has given

    drawn_j = propulsion_j + hotel_power_w * elapsed_ns / 1e9        [J]

where ``propulsion_j`` is the plant's sum alpha T^2 dt (``SimTruth.energy_j``, paper eq. 3) and
``hotel_power_w`` is ``Scenario.hotel_power_w`` (default the mission's task power T^w). What is left
is ``max(0, initial_j - drawn_j)``; the voltage falls linearly with it (``pack_state``). The
simulator keeps running on an empty pack: the thrusters are not cut (the controller's energy budget
is what is under test, not a brown-out).

Both of the sim's outputs come from one ``PackReading``: the lockstep ``BatteryState`` on
``vehicle/battery`` (``PackReading.message``) and, in real time, the PX4-like SYS_STATUS and
BATTERY_STATUS (``px4_telemetry``), so the two never disagree. Both come at ``REPORT_HZ``.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.contract.config import ConfigError
from seaway.contract.messages import BatteryState
from seaway.contract.units import NS_PER_S
from seaway.simkit.scenario import Scenario
from seaway.simkit.sensors import instants_in, period_ns
from seaway.vessel.battery import J_PER_WH, BatteryParams, pack_state
from seaway.vessel.model import VesselParams

REPORT_HZ = 1.0
"""How often the pack is reported, at whole seconds of the sim's clock: the simulated PX4's
BATTERY_STATUS (PX4 streams it at 0.5 Hz on its onboard link) and the lockstep sim's
``vehicle/battery``, as an autopilot would (each 0.1 s period, it was one sample in seven of the
sim's, heard by the estimator, controller, recorder and launcher alike) [Hz]."""


def report_due(after_ns: int, upto_ns: int) -> bool:
    """Whether a report is due in (``after_ns``, ``upto_ns``] of the sim's clock [ns]."""
    return bool(instants_in(period_ns(REPORT_HZ), after_ns, upto_ns))


def report_due_at(stamp_ns: int, length_ns: int) -> bool:
    """Whether the lockstep period ending at ``stamp_ns`` reports the pack: one of length
    ``length_ns`` [ns] with a report instant in it, and the episode's first (t_0 = 0)."""
    return report_due(stamp_ns - length_ns if stamp_ns > 0 else -1, stamp_ns)


NOMINAL_PACK = BatteryParams(capacity_ah=10.0, nominal_voltage_v=14.8, full_voltage_v=16.8,
                             empty_voltage_v=13.2, reserve_frac=0.2)
"""The pack of a plant vessel file without ``[battery]``: a 4S Li-ion 10 A h at 14.8 V (533 kJ),
16.8 V full, 13.2 V empty, a fifth kept in reserve (what the sim always had before vessel files
named their battery)."""

MAH_PER_J_AT_1V = 1000.0 / J_PER_WH
"""1 J drawn at 1 V is 1/3.6 mA h: charge [mA h] = energy [J] / (3.6 x voltage [V])."""


@dataclass(frozen=True)
class PackReading:
    """The simulated pack now, as a battery monitor would measure it (SI units)."""

    voltage_v: float  # pack voltage [V]
    current_a: float  # current drawn [A], power / voltage
    power_w: float  # power drawn now: propulsion + hotel [W]
    consumed_j: float  # energy drawn since the scenario (re)started [J]
    consumed_mah: float  # the same as charge at the nominal voltage [mA h]
    remaining_j: float  # usable energy left [J], never below 0
    remaining_frac: float  # remaining_j over the usable energy, [0, 1]
    capacity_j: float  # usable energy full to empty [J]
    reserve_j: float  # what a return home must leave [J]

    def message(self, stamp_ns: int) -> BatteryState:
        """The lockstep sim's ``vehicle/battery`` report, every field filled."""
        return BatteryState.make(
            stamp_ns=stamp_ns, source="sim", voltage_v=self.voltage_v, current_a=self.current_a,
            power_w=self.power_w, consumed_j=self.consumed_j, remaining_j=self.remaining_j,
            remaining_frac=self.remaining_frac, capacity_j=self.capacity_j,
            reserve_j=self.reserve_j)


@dataclass(frozen=True)
class SimPack:
    """The pack of one scenario on one plant vessel, full or at its initial energy."""

    params: BatteryParams
    initial_j: float  # usable energy at the scenario's start [J]
    hotel_power_w: float  # drawn besides the thrusters [W]

    @classmethod
    def of(cls, scenario: Scenario, vessel: VesselParams) -> SimPack:
        """The pack ``scenario`` runs on ``vessel`` (the plant's). ConfigError if the scenario
        starts it with more energy than it holds."""
        params = vessel.battery if vessel.battery is not None else NOMINAL_PACK
        initial = scenario.battery.initial_energy_j
        if initial is None:
            initial = params.energy_j
        elif initial > params.energy_j:
            raise ConfigError(
                f"scenario {scenario.name}: [battery] initial_energy_j {initial:g} J is more than "
                f"the pack of vessel {vessel.name} holds ({params.energy_j:g} J usable); allowed: "
                f"[0, {params.energy_j:g}] J")
        return cls(params=params, initial_j=initial, hotel_power_w=scenario.hotel_power_w)

    def drawn_j(self, propulsion_j: float, elapsed_ns: int) -> float:
        """Energy drawn after ``elapsed_ns`` [ns] of simulated time with ``propulsion_j`` [J] of
        propulsion: propulsion + hotel power x time [J]."""
        return propulsion_j + self.hotel_power_w * elapsed_ns / NS_PER_S

    def reading(self, propulsion_j: float, elapsed_ns: int, propulsion_power_w: float) -> PackReading:
        """The pack after ``elapsed_ns`` since the start with ``propulsion_j`` [J] drawn by the
        thrusters, which draw ``propulsion_power_w`` [W] now."""
        drawn = self.drawn_j(propulsion_j, elapsed_ns)
        st = pack_state(self.params, self.initial_j, drawn)
        power = propulsion_power_w + self.hotel_power_w
        return PackReading(
            voltage_v=st.voltage_v, current_a=power / st.voltage_v, power_w=power,
            consumed_j=drawn, consumed_mah=drawn * MAH_PER_J_AT_1V / self.params.nominal_voltage_v,
            remaining_j=st.remaining_j, remaining_frac=st.remaining_frac,
            capacity_j=self.params.energy_j, reserve_j=self.params.reserve_energy_j)
