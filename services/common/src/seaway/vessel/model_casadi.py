"""The vessel model of ``seaway.vessel.model`` as CasADi functions (needs the ``casadi`` extra).

Nothing is re-derived here: the same ``derivative`` and ``rk4_step`` are evaluated on CasADi SX
symbols, so the MPC predicts with exactly the model the simulator integrates.
"""

from __future__ import annotations

import casadi as ca

from seaway.vessel import model
from seaway.vessel.model import NU, NX, VesselParams


def _split(sym: ca.SX, n: int) -> list[ca.SX]:
    return [sym[i] for i in range(n)]


def continuous_dynamics(p: VesselParams) -> ca.Function:
    """``f(x[6], u[2], tau_body[3], force_ne[2], current_ne[2]) -> x_dot[6]`` (paper eq. 1-2)."""
    x, u = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    tb, fne, cne = ca.SX.sym("tau_body", 3), ca.SX.sym("force_ne", 2), ca.SX.sym("current_ne", 2)
    xdot = model.derivative(_split(x, NX), _split(u, NU), p, ca, _split(tb, 3), _split(fne, 2),
                            _split(cne, 2))
    return ca.Function("vessel_f", [x, u, tb, fne, cne], [ca.vertcat(*xdot)],
                       ["x", "u", "tau_body", "force_ne", "current_ne"], ["x_dot"])


def rk4_discrete(p: VesselParams, dt_s: float, with_disturbance: bool = True) -> ca.Function:
    """One RK4 step as a CasADi function.

    With ``with_disturbance``: ``F(x, u, tau_body) -> x_next``; without: ``F(x, u) -> x_next``
    (the paper's controllers predict with tau_d = 0).
    """
    x, u = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    tb = ca.SX.sym("tau_body", 3)
    tau = _split(tb, 3) if with_disturbance else model.ZERO3
    xn = model.rk4_step(_split(x, NX), _split(u, NU), dt_s, p, ca, tau)
    inputs = [x, u, tb] if with_disturbance else [x, u]
    names = ["x", "u", "tau_body"] if with_disturbance else ["x", "u"]
    return ca.Function("vessel_rk4", inputs, [ca.vertcat(*xn)], names, ["x_next"])
