"""Pieces the two economic MPCs share (paper section IV): the energy stage cost and the cold guess."""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

from seaway.vessel import model
from seaway.vessel.model import VesselParams

from seaway_controller import costs

if TYPE_CHECKING:
    from seaway_controller.ocp import Ocp, OcpSpec


def energy_stage_cost(x_next: Sequence[Any], thrust: Sequence[Any], wp_active: Sequence[Any],
                      task_power_w: Any, spec: OcpSpec, vessel: VesselParams, ops: ModuleType) -> Any:
    """L_k = (alpha (T1^2 + T2^2) + T^w) dt [J] (paper eq. 3 and 15): energy, not tracking."""
    return costs.stage_cost_j(thrust[0], thrust[1], task_power_w, spec.dt_s, vessel)


def cruise_thrust(ocp: Ocp, task_power_w: float) -> tuple[float, float]:
    """Each thruster's share of the drag at the economic cruise u* [N]: Xu u* / 2 (plus half the
    sliding friction on a vessel with it: ``model.sliding_resistance_n``)."""
    u_c = ocp.cruise_speed_mps(task_power_w)
    return (model.sliding_resistance_n(u_c, ocp.vessel) / 2.0,) * 2
