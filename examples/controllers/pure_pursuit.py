"""Pure-pursuit MPC: a controller of one's own, in one file (docs/researcher/new-controller.md).

Over the horizon, the vessel points its bow at the active waypoint P_i (the line-of-sight heading,
pure pursuit) and sails at the economic cruise speed u* of the mission's task power T^w, while its
thrust stays near the cruise thrust T*. The stage cost of step k, scored at the state X_{k+1}
reached with the thrust U_k = [T1 port, T2 starboard] [N], is dimensionless:

    L_k = Q_HEADING (1 - cos(psi_LOS - psi))
        + Q_SPEED ((u - u*) / u*)^2
        + R_THRUST ((T1 - T*)^2 + (T2 - T*)^2) / T*^2

with psi_LOS = atan2(y_i - y, x_i - x) the bearing from the predicted position to P_i.

Frames and units are Seaway's: positions x (north), y (east) [m] in the local NED frame at the
run's origin; heading psi [rad] from north, clockwise; surge speed u [m/s] along the bow; thrust
per thruster [N], positive ahead. u* = sqrt(2 T^w / alpha) / Xu is ``costs.cruise_speed_mps`` (the
speed at which the propulsion power equals T^w), T* = (Xu u* + F_c) / 2 each thruster's share of
the drag there (``model.sliding_resistance_n``).

It is a tracking MPC (no decision times t_d, t_s and no terminal constraint), so the controller
flies it on the shared OCP skeleton (``seaway_controller.ocp``: H steps of the RK4 vessel model,
the thrust bounds, the measured state as X_0) with the compiled SQP and the same fallback chain as
the shipped controllers. Seaway finds it through ``--controller-module`` (``seaway-controller``,
``seaway launch``), which imports this file; the ``register`` call at the bottom adds it to the
registry under ``NAME``, and a mission asks for it with ``controller = "pure-pursuit"``.
"""

from __future__ import annotations

from collections.abc import Sequence
from types import ModuleType
from typing import Any

from seaway.vessel import model
from seaway.vessel.model import VesselParams
from seaway_controller import costs
from seaway_controller.controllers import Controller, register
from seaway_controller.ocp import Ocp, OcpSpec

NAME = "pure-pursuit"
"""The name a mission, ``--controller`` and the recording use for it."""
Q_HEADING = 4.0
"""Weight of the heading error 1 - cos(psi_LOS - psi) (0 on course, 2 heading away)."""
Q_SPEED = 1.0
"""Weight of the relative speed error ((u - u*) / u*)^2."""
R_THRUST = 0.05
"""Weight of each thruster's relative departure from the cruise thrust ((T - T*) / T*)^2: small,
so that turning (one thruster above T*, the other below) is cheap next to a heading error."""


def cruise_thrust_n(task_power_w: Any, vessel: VesselParams, ops: ModuleType) -> Any:
    """T* [N]: each thruster's share of the drag at the economic cruise u* (numbers or CasADi)."""
    return model.sliding_resistance_n(costs.cruise_speed_mps(task_power_w, vessel, ops), vessel) / 2


def stage_cost(x_next: Sequence[Any], thrust: Sequence[Any], wp_active: Sequence[Any],
               task_power_w: Any, spec: OcpSpec, vessel: VesselParams, ops: ModuleType) -> Any:
    """L_k (module docstring) of the state ``x_next`` = X_{k+1} = [u, v, r, x, y, psi] reached with
    ``thrust`` = U_k [N], against the active waypoint ``wp_active`` = P_i (x north, y east [m]).

    ``ops`` is ``math`` for numbers or ``casadi`` for the NLP's expressions: the same formula
    builds the solver and scores a plan."""
    u, x, y, psi = x_next[0], x_next[3], x_next[4], x_next[5]
    psi_los = ops.atan2(wp_active[1] - y, wp_active[0] - x)
    u_star = costs.cruise_speed_mps(task_power_w, vessel, ops)
    t_star = cruise_thrust_n(task_power_w, vessel, ops)
    speed_error = (u - u_star) / u_star
    effort = ((thrust[0] - t_star) ** 2 + (thrust[1] - t_star) ** 2) / (t_star * t_star)
    return (Q_HEADING * (1.0 - ops.cos(psi_los - psi)) + Q_SPEED * speed_error * speed_error
            + R_THRUST * effort)


def guess_thrust(ocp: Ocp, task_power_w: float) -> tuple[float, float]:
    """The cold first guess, held over the horizon: the cruise thrust T* on both thrusters [N]."""
    u_star = ocp.cruise_speed_mps(task_power_w)
    return (model.sliding_resistance_n(u_star, ocp.vessel) / 2.0,) * 2


CONTROLLER = register(Controller(NAME, stage_cost, guess_thrust, None,
                                 "pure pursuit of the active waypoint at the economic cruise "
                                 "(example: docs/researcher/new-controller.md)"))
