"""EO-EMPC, the energy-only baseline: CC-EMPC's problem (eq. 15) without the cross-track cost Y."""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

from seaway.vessel.model import VesselParams

from seaway_controller import costs
from seaway_controller.controllers._economic import cruise_thrust, energy_stage_cost
from seaway_controller.controllers._registry import Controller, register

if TYPE_CHECKING:
    from seaway_controller.ocp import OcpSpec


def terminal(x_h: Sequence[Any], t_d_s: Any, t_s_s: Any, wp_prev: Sequence[Any],
             wp_active: Sequence[Any], task_power_w: Any, track_gate: Any, spec: OcpSpec,
             vessel: VesselParams, ops: ModuleType) -> costs.TerminalTerms:
    """E_d, E_s and the constraint (eq. 15d); Y is always off (gate 0), whatever the track gate."""
    return costs.terminal_terms(x_h, t_d_s, t_s_s, wp_prev, wp_active, task_power_w, 0.0,
                                spec.profile_n, vessel, ops)


CONTROLLER = register(Controller("eo-empc", energy_stage_cost, cruise_thrust, terminal,
                                 "energy-only economic MPC (baseline)"))
