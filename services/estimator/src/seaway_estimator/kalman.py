"""The Kalman filter's steps, each one compiled function (``seaway.vessel.native``).

For the state ``z = [u, v, r, x, y, psi, d1, d2, d3]`` (``seaway_estimator.core``):

**Prediction** over ``h`` seconds with the thrust held:

* the mean: one ``seaway.vessel.model.rk4_step`` of the six vessel states, the disturbance held
  (a random walk has no drift);
* the covariance: ``P' = F P F^T + diag(q) h``, symmetrised, with ``F = I + A h + (A h)^2 / 2`` and
  ``A = d f / d z`` the exact Jacobian of ``seaway.vessel.model.derivative`` (the disturbance rows
  zero), by CasADi's automatic differentiation of the same expressions.

``d1, d2`` are a world-frame force (north, east) [N] that the model rotates into the body frame
(``world``), or body-frame surge and sway forces; ``d3`` is always the body yaw moment [N m].

**Update** with a measurement of ``m`` values (1 or 2), innovation ``nu``, rows ``H`` (m x 9) and
noise ``R`` (m x m): ``S = H P H^T + R``, the normalised innovation squared ``nis = nu^T S^-1 nu``
(the caller gates on it), ``K = P H^T S^-1``, ``z' = z + K nu`` and the Joseph form
``P' = (I - K H) P (I - K H)^T + K R K^T``, symmetrised.

Both are generated as C and called through ctypes: on 9 x 9 matrices the cost of numpy (or of a
CasADi ``Function`` called from Python) is its per-call overhead, not the arithmetic, and a period
makes two predictions (each with its complex-step Jacobian) and about five updates.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import casadi as ca
import numpy as np
from seaway.vessel import model
from seaway.vessel.model import NX, VesselParams
from seaway.vessel.native import NativeFunction, dense

NZ = 9
"""Filter state size: the six vessel states and the three disturbance components."""
IU, IV, IR, IX, IY, IPSI, ID1, ID2, ID3 = range(NZ)
"""The index of each state in ``z``."""


def disturbance(z: list, world: bool) -> tuple[tuple, tuple]:
    """The model's ``(tau_body, force_ne)`` for the disturbance in ``z[6:9]``: in the ``world``
    frame ``d1, d2`` are a force (north, east) the model rotates, else body surge and sway."""
    if world:
        return (0.0, 0.0, z[8]), (z[6], z[7])
    return (z[6], z[7], z[8]), model.ZERO2


def derivative(z: list, thrust: list, p: VesselParams, world: bool, ops: object = ca) -> list:
    """d/dt of the six vessel states with the disturbance in ``z[6:9]`` (the shared model)."""
    return model.derivative(z, thrust, p, ops, *disturbance(z, world))


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
    xn = model.rk4_step(zl, tl, h, p, ca, *disturbance(zl, world))
    z_next = ca.vertcat(*xn, *zl[NX:])  # the disturbance held
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
        # The matrices' buffers seen as matrices (column-major, as CasADi stores them): a matrix
        # goes in and out with one copy, not a transposed copy and then another.
        self._P_in = self._P.reshape(NZ, NZ, order="F")
        self._P_out = self._P_next.reshape(NZ, NZ, order="F")

    @property
    def compiled(self) -> bool:
        return self._fn.compiled

    def step(self, z: np.ndarray, P: np.ndarray, thrust: tuple[float, float], h_s: float
             ) -> tuple[np.ndarray, np.ndarray]:
        """``(z_next, P_next)`` after ``h_s`` seconds with ``thrust`` [N] held: new arrays."""
        self._z[:] = z
        self._P_in[...] = P
        self._thrust[0], self._thrust[1] = thrust
        self._h[0] = h_s
        self._fn()
        return self._z_next.copy(), self._P_out.copy()

    def jacobian(self, z: np.ndarray, thrust: tuple[float, float]) -> np.ndarray:
        """``A = d f / d z`` at ``z`` (9x9; the disturbance rows zero)."""
        self._z[:] = z
        self._thrust[0], self._thrust[1] = thrust
        self._h[0] = 0.0
        self._fn()
        return self._A.reshape(NZ, NZ, order="F").copy()


def update_function(m: int) -> ca.Function:
    """``update(z[9], P[9x9], nu[m], H[m x 9], R[m x m]) -> (nis, z_next[9], P_next[9x9])``."""
    z, P = ca.SX.sym("z", NZ), ca.SX.sym("P", NZ, NZ)
    nu, H, R = ca.SX.sym("nu", m), ca.SX.sym("H", m, NZ), ca.SX.sym("R", m, m)
    PHt = P @ H.T
    S_inv = ca.inv(H @ PHt + R)
    K = PHt @ S_inv
    IKH = ca.SX.eye(NZ) - K @ H
    P_next = IKH @ P @ IKH.T + K @ R @ K.T
    return ca.Function(f"seaway_ekf_update_{m}", [z, P, nu, H, R],
                       dense(nu.T @ S_inv @ nu, z + K @ nu, 0.5 * (P_next + P_next.T)),
                       ["z", "P", "nu", "H", "R"], ["nis", "z_next", "P_next"])


class Updater:
    """The update with ``m`` measured values, compiled (``update_function``)."""

    def __init__(self, m: int) -> None:
        self._fn = NativeFunction(update_function(m))
        self._z, self._P, self._nu, self._H, self._R = self._fn.inputs
        self._nis, self._z_next, self._P_next = self._fn.outputs
        self._unit = -1  # the state whose unit row H holds now (``scalar``); -1: another H
        # As matrices (column-major), filled and read with one copy each (``Predictor``).
        self._P_in = self._P.reshape(NZ, NZ, order="F")
        self._H_in = self._H.reshape(m, NZ, order="F")
        self._R_in = self._R.reshape(m, m, order="F")
        self._P_out = self._P_next.reshape(NZ, NZ, order="F")

    def step(self, z: np.ndarray, P: np.ndarray, nu: np.ndarray | float, H: np.ndarray,
             R: np.ndarray | float) -> tuple[float, np.ndarray, np.ndarray]:
        """``(nis, z_next, P_next)``; ``H`` is m x 9 (or a 9-vector for m = 1), ``R`` m x m (or
        the variance for m = 1). New arrays; nothing is gated here."""
        self._z[:] = z
        self._P_in[...] = P
        self._nu[:] = nu
        self._H_in[...] = H  # a 9-vector fills the one row of m = 1
        self._R_in[...] = R  # a variance fills the 1 x 1 of m = 1
        self._unit = -1
        self._fn()
        return float(self._nis[0]), self._z_next.copy(), self._P_out.copy()

    def scalar(self, z: np.ndarray, P: np.ndarray, nu: float, i: int, var: float
               ) -> tuple[float, np.ndarray, np.ndarray]:
        """``step`` of ``m = 1`` for a measurement of state ``i`` alone (H its unit row) with
        variance ``var``: the same numbers, without numpy's per-call cost of filling a 9-vector
        and a 1 x 1 (on values this small that cost is the cost)."""
        self._z[:] = z
        self._P_in[...] = P
        self._nu[0] = nu
        H = self._H
        if self._unit != i:
            if self._unit < 0:
                H.fill(0.0)
            else:
                H[self._unit] = 0.0
            H[i] = 1.0
            self._unit = i
        self._R[0] = var
        self._fn()
        return self._nis.item(0), self._z_next.copy(), self._P_out.copy()


@dataclass
class Filter:
    """The filter's state between calls (exposed for tests and diagnostics)."""

    t_ns: int
    z: np.ndarray
    P: np.ndarray
    last_gnss_ns: int
    last_heading_ns: int
    gnss_reject_run: int = 0
    heading_reject_run: int = 0
    sog_reject_run: int = 0
    yaw_rate_reject_run: int = 0
    degraded: bool = False
    moved: deque[tuple[int, list[float]]] | None = None
    """(time [ns], the motion of the six vessel states the prediction made up to it, summed), over
    the last ``late_tolerance_s``: kept from the first late measurement on (``Prediction._back``);
    None before."""
