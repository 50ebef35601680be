"""The filter's prediction step, one compiled function of the shared vessel model.

For the state ``z = [u, v, r, x, y, psi, d1, d2, d3]`` (``seaway_estimator.core``) and a step of
``h`` seconds with the thrust held:

* the mean: one ``seaway.vessel.model.rk4_step`` of the six vessel states, the disturbance held
  (a random walk has no drift);
* the covariance: ``P' = F P F^T + diag(q) h``, symmetrised, with ``F = I + A h + (A h)^2 / 2`` and
  ``A = d f / d z`` the exact Jacobian of ``seaway.vessel.model.derivative`` (the disturbance rows
  zero), by CasADi's automatic differentiation of the same expressions.

``d1, d2`` are a world-frame force (north, east) [N] that the model rotates into the body frame
(``world``), or body-frame surge and sway forces; ``d3`` is always the body yaw moment [N m].

The whole step is one ``seaway.vessel.native.NativeFunction``: about 3 us a step, where the same
with Python floats, a complex-step Jacobian and numpy took 65-76 us, two steps each simulated
period (docs/results.md, 2026-12-01).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
from seaway.vessel import model
from seaway.vessel.model import NX, VesselParams
from seaway.vessel.native import NativeFunction, dense

NZ = 9
"""Filter state size: the six vessel states and the three disturbance components."""


def derivative(z: list, thrust: list, p: VesselParams, world: bool, ops: object = ca) -> list:
    """d/dt of the six vessel states with the disturbance in ``z[6:9]`` (the shared model)."""
    if world:
        return model.derivative(z, thrust, p, ops, (0.0, 0.0, z[8]), (z[6], z[7]))
    return model.derivative(z, thrust, p, ops, (z[6], z[7], z[8]))


def prediction_function(p: VesselParams, world: bool) -> ca.Function:
    """``predict(z[9], P[9x9], thrust[2], h, q[9]) -> (z_next[9], P_next[9x9], A[9x9])``.

    ``A`` is the Jacobian at ``z`` (for tests and diagnostics); ``psi`` is not wrapped here."""
    z, P = ca.SX.sym("z", NZ), ca.SX.sym("P", NZ, NZ)
    thrust, h, q = ca.SX.sym("thrust", 2), ca.SX.sym("h"), ca.SX.sym("q", NZ)
    zl, tl = [z[i] for i in range(NZ)], [thrust[0], thrust[1]]
    xdot = ca.vertcat(*derivative(zl, tl, p, world))
    A = ca.vertcat(ca.jacobian(xdot, z), ca.SX.zeros(NZ - NX, NZ))
    Ah = A * h
    F = ca.SX.eye(NZ) + Ah + 0.5 * (Ah @ Ah)
    d = zl[NX:]
    if world:
        xn = model.rk4_step(zl, tl, h, p, ca, (0.0, 0.0, d[2]), (d[0], d[1]))
    else:
        xn = model.rk4_step(zl, tl, h, p, ca, (d[0], d[1], d[2]))
    z_next = ca.vertcat(*xn, *d)
    P_next = F @ P @ F.T + ca.diag(q * h)
    P_next = 0.5 * (P_next + P_next.T)
    frame = "world" if world else "body"
    return ca.Function(f"seaway_ekf_predict_{frame}", [z, P, thrust, h, q],
                       dense(z_next, P_next, A), ["z", "P", "thrust", "h", "q"],
                       ["z_next", "P_next", "A"])


class Predictor:
    """The prediction step of one vessel, compiled (``prediction_function``)."""

    def __init__(self, p: VesselParams, world: bool, q: np.ndarray) -> None:
        self._fn = NativeFunction(prediction_function(p, world))
        self._z, self._P, self._thrust, self._h, self._q = self._fn.inputs
        self._q[:] = q
        self._z_next, self._P_next, self._A = self._fn.outputs

    @property
    def compiled(self) -> bool:
        return self._fn.compiled

    def step(self, z: np.ndarray, P: np.ndarray, thrust: tuple[float, float], h_s: float
             ) -> tuple[np.ndarray, np.ndarray]:
        """``(z_next, P_next)`` after ``h_s`` seconds with ``thrust`` [N] held: new arrays."""
        self._z[:] = z
        self._P[:] = P.ravel(order="F")
        self._thrust[0], self._thrust[1] = thrust
        self._h[0] = h_s
        self._fn()
        return self._z_next.copy(), self._P_next.reshape(NZ, NZ, order="F").copy()

    def jacobian(self, z: np.ndarray, thrust: tuple[float, float]) -> np.ndarray:
        """``A = d f / d z`` at ``z`` (9x9; the disturbance rows zero)."""
        self._z[:] = z
        self._thrust[0], self._thrust[1] = thrust
        self._h[0] = 0.0
        self._fn()
        return self._A.reshape(NZ, NZ, order="F").copy()
