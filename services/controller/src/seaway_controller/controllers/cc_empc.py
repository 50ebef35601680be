"""CC-EMPC, the paper's controller (eq. 15): energy over the horizon, the terminal energy to reach
the active waypoint E_d + E_s, and the cross-track cost Y when the track gate is on (r_f > r_COA,
reproduction.md item 2)."""

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
    """E_d, E_s, the constraint (eq. 15d) and Y, which counts where the gate says so."""
    return costs.terminal_terms(x_h, t_d_s, t_s_s, wp_prev, wp_active, task_power_w, track_gate,
                                spec.profile_n, vessel, ops)


CONTROLLER = register(Controller("cc-empc", energy_stage_cost, cruise_thrust, terminal,
                                 "cross-track-constrained economic MPC (the paper's)"))
