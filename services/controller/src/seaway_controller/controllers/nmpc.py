"""NMPC, the tracking baseline: distance to the active waypoint, line-of-sight heading error and
thrust effort over the horizon (reproduction.md, "The NMPC baseline's cost"); no terminal cost, no
decision times. Its weights are ``OcpSpec.nmpc`` (``costs.NmpcWeights``)."""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

from seaway.vessel.model import VesselParams

from seaway_controller import costs
from seaway_controller.controllers._registry import Controller, register

if TYPE_CHECKING:
    from seaway_controller.ocp import Ocp, OcpSpec


def stage_cost(x_next: Sequence[Any], thrust: Sequence[Any], wp_active: Sequence[Any],
               task_power_w: Any, spec: OcpSpec, vessel: VesselParams, ops: ModuleType) -> Any:
    """q_p |p_{k+1} - P_i|^2 + q_psi (1 - cos(psi_LOS - psi_{k+1})) + r |T_k|^2 (no T^w: the NMPC
    does not weigh energy against time)."""
    return costs.nmpc_stage_cost(x_next, thrust, wp_active, spec.nmpc, ops)


def half_thrust(ocp: Ocp, task_power_w: float) -> tuple[float, float]:
    """Half the forward limit on both thrusters [N]: a tracking MPC has no economic cruise."""
    return (0.5 * ocp.vessel.thrust_max_n,) * 2


CONTROLLER = register(Controller("nmpc", stage_cost, half_thrust, None,
                                 "tracking nonlinear MPC (baseline)"))
