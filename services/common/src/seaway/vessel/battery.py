"""The propulsion battery a vessel file names, written once: its usable energy, its reserve, and the
pack's state after an amount of energy drawn (the simulator's, and vehicle_io's conversions).

Units: energy [J], charge [A h], voltage [V], power [W]. 1 A h at V volts is 3600 V joules.

The battery is described by its usable energy (``usable_energy_j``), or by its capacity and nominal
voltage (``capacity_ah`` x ``nominal_voltage_v``), and a reserve that a return home must leave in
it (``reserve_j`` or ``reserve_frac`` of the usable energy). The voltage a simulated pack reports
falls linearly from ``full_voltage_v`` to ``empty_voltage_v`` with the energy drawn: a stand-in,
good enough for an autopilot's battery messages; nothing in Seaway decides from the voltage.
"""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import Field, model_validator

from seaway.contract.config import ConfigModel

J_PER_WH = 3600.0
"""1 W h = 3600 J; so 1 A h at V volts = 3600 V joules, 1 mA h = 3.6 V joules."""
DEFAULT_RESERVE_FRAC = 0.2
"""Reserve when the vessel file gives none: a fifth of the usable energy (a common rule for small
electric craft; the last fifth of a Li-ion pack also sags the most under load)."""


class BatteryParams(ConfigModel):
    """A vessel file's ``[battery]`` table."""

    usable_energy_j: float | None = Field(default=None, gt=0, description="energy the pack delivers "
                                          "from full to empty [J]; or give capacity_ah")
    capacity_ah: float | None = Field(default=None, gt=0, description="rated capacity [A h], with "
                                      "nominal_voltage_v; or give usable_energy_j")
    nominal_voltage_v: float = Field(gt=0, description="nominal pack voltage [V] (converts the "
                                     "autopilot's A and mA h into W and J)")
    full_voltage_v: float | None = Field(default=None, gt=0, description="voltage when full [V] "
                                         "(simulator; default 1.13 x nominal, a Li-ion pack)")
    empty_voltage_v: float | None = Field(default=None, gt=0, description="voltage when empty [V] "
                                          "(simulator; default 0.89 x nominal)")
    reserve_j: float | None = Field(default=None, ge=0, description="energy a return home must "
                                    "leave in the pack [J]; or give reserve_frac")
    reserve_frac: float | None = Field(default=None, ge=0, lt=1, description="the reserve as a "
                                       "fraction of the usable energy, [0, 1); default 0.2")

    @model_validator(mode="after")
    def _one_of_each(self) -> BatteryParams:
        if (self.usable_energy_j is None) == (self.capacity_ah is None):
            raise ValueError("give exactly one of usable_energy_j [J] and capacity_ah [A h]")
        if self.reserve_j is not None and self.reserve_frac is not None:
            raise ValueError("give at most one of reserve_j [J] and reserve_frac")
        if self.reserve_j is not None and self.reserve_j >= self.energy_j:
            raise ValueError(f"reserve_j {self.reserve_j:g} J must be below the usable energy "
                             f"{self.energy_j:g} J")
        if self.full_v <= self.empty_v:
            raise ValueError(f"full_voltage_v {self.full_v:g} V must be above empty_voltage_v "
                             f"{self.empty_v:g} V")
        return self

    @property
    def energy_j(self) -> float:
        """Usable energy, full to empty [J]."""
        if self.usable_energy_j is not None:
            return self.usable_energy_j
        assert self.capacity_ah is not None
        return self.capacity_ah * self.nominal_voltage_v * J_PER_WH

    @property
    def reserve_energy_j(self) -> float:
        """The reserve [J]."""
        if self.reserve_j is not None:
            return self.reserve_j
        frac = DEFAULT_RESERVE_FRAC if self.reserve_frac is None else self.reserve_frac
        return frac * self.energy_j

    @property
    def full_v(self) -> float:
        return self.full_voltage_v if self.full_voltage_v is not None else 1.13 * self.nominal_voltage_v

    @property
    def empty_v(self) -> float:
        return (self.empty_voltage_v if self.empty_voltage_v is not None
                else 0.89 * self.nominal_voltage_v)

    def joules_from_mah(self, mah: float) -> float:
        """Charge drawn [mA h] as energy at the nominal voltage [J]."""
        return mah * 3.6 * self.nominal_voltage_v


@dataclass(frozen=True)
class PackState:
    """A pack after ``consumed_j`` drawn from ``initial_j`` (what a simulated autopilot reports)."""

    remaining_j: float
    remaining_frac: float
    voltage_v: float
    consumed_j: float


def pack_state(params: BatteryParams, initial_j: float, consumed_j: float) -> PackState:
    """The state of a pack that held ``initial_j`` [J] after ``consumed_j`` [J] were drawn: the
    remaining energy (never below 0), its fraction of the usable energy, and the linear voltage."""
    remaining = max(0.0, initial_j - consumed_j)
    frac = min(1.0, remaining / params.energy_j)
    volts = params.empty_v + (params.full_v - params.empty_v) * frac
    return PackState(remaining_j=remaining, remaining_frac=frac, voltage_v=volts,
                     consumed_j=consumed_j)
