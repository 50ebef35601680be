"""What a controller is, and the registry its module adds it to.

A controller is an optimal control problem over the shared multiple-shooting skeleton (``ocp.Ocp``:
H steps of the RK4 vessel model, thrust bounds, the measured state as X_0) plus the pieces that
differ between formulations: the stage cost, and, for the economic MPCs (paper eq. 15), the terminal
cost and constraint with the decision times t_d and t_s. ``Ocp`` and ``MpcController`` ask the
registered definition for those pieces and never test a controller's name.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import ModuleType
from typing import TYPE_CHECKING, Any

from seaway.contract.messages import CONTROLLER_NAME_PATTERN, ControllerName
from seaway.vessel.model import VesselParams

from seaway_controller import costs

if TYPE_CHECKING:
    from seaway_controller.ocp import Ocp, OcpSpec

StageCost = Callable[[Sequence[Any], Sequence[Any], Sequence[Any], Any, "OcpSpec", VesselParams,
                      ModuleType], Any]
"""(X_{k+1}, U_k, P_i, T^w, spec, vessel, ops) -> the stage cost of step k (floats or CasADi)."""
TerminalCost = Callable[[Sequence[Any], Any, Any, Sequence[Any], Sequence[Any], Any, Any, "OcpSpec",
                         VesselParams, ModuleType], costs.TerminalTerms]
"""(X_H, t_d [s], t_s [s], P_{i-1}, P_i, T^w, track gate, spec, vessel, ops) -> the terminal terms."""
GuessThrust = Callable[["Ocp", float], tuple[float, float]]
"""(ocp, T^w [W]) -> the thrust pair [N] held over the horizon in a cold first guess."""


@dataclass(frozen=True)
class Controller:
    """One registered controller: its name on the wire and its pieces of the OCP."""

    name: ControllerName
    stage_cost: StageCost
    guess_thrust: GuessThrust
    terminal: TerminalCost | None = None
    """The EMPC terminal terms (E_d, E_s, Y and the constraint, eq. 15); None for a controller
    without t_d, t_s and terminal constraint (the NMPC baseline)."""
    summary: str = ""

    @property
    def economic(self) -> bool:
        """True for an economic MPC: decision times t_d, t_s and the terminal constraint (eq. 15d)."""
        return self.terminal is not None


_REGISTERED: dict[str, Controller] = {}


def register(controller: Controller) -> Controller:
    """Add ``controller`` under its name (once); its module calls this at import. ValueError for a
    name spelled otherwise than ``CONTROLLER_NAME_PATTERN`` allows, or one already taken."""
    if not re.fullmatch(CONTROLLER_NAME_PATTERN, controller.name):
        raise ValueError(f"controller name {controller.name!r}: lower case letters, digits and '-', "
                         f"starting with a letter, at most 32 characters ({CONTROLLER_NAME_PATTERN})")
    if controller.name in _REGISTERED:
        raise ValueError(f"controller {controller.name!r} is registered twice")
    _REGISTERED[controller.name] = controller
    return controller


def registered() -> dict[str, Controller]:
    """Every controller registered so far, by name (in registration order)."""
    return dict(_REGISTERED)
