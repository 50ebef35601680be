"""Simulation (producer: the sim)."""

from __future__ import annotations

from typing import ClassVar

from pydantic import Field

from seaway.contract.messages.base import Message


class SimTruth(Message):
    """True state of the simulated vessel and the thrust actually applied (after saturation)."""

    SCHEMA: ClassVar[str] = "seaway.v1.SimTruth"
    u_mps: float
    v_mps: float
    r_radps: float
    x_m: float
    y_m: float
    psi_rad: float
    thrust_port_n: float
    thrust_starboard_n: float
    energy_j: float = Field(ge=0, description="propulsion energy sum alpha*T^2 dt since start [J]")


class DisturbanceForce(Message):
    """Disturbance acting on the simulated vessel now, body frame (paper's tau_d), and current."""

    SCHEMA: ClassVar[str] = "seaway.v1.DisturbanceForce"
    surge_n: float
    sway_n: float
    yaw_nm: float
    current_n_mps: float = 0.0
    current_e_mps: float = 0.0


class ClockTick(Message):
    """The simulator's clock: ``stamp_ns`` is simulated time now."""

    SCHEMA: ClassVar[str] = "seaway.v1.ClockTick"
    lockstep: bool
    real_time_factor: float | None = Field(default=None, ge=0)
