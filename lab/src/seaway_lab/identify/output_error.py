"""The second stage of the fit (``seaway_lab.identify.fit``), the output error: the model is simulated
(RK4 on a grid of ``DT_S``) from a fitted initial state, with the commanded thrusts, and the
dampings (as logarithms: they stay positive), the time constants m/d of surge, sway and yaw (as the
logarithm of their excess over ``TAU_MIN_S``: they stay above it), the water current and the initial
state are found by Levenberg-Marquardt on the weighted residuals of the measured velocity over
ground and yaw rate, each channel weighted by its residual RMS. Noise is then only in the outputs,
so the estimates are unbiased; standard errors come from the Gauss-Newton covariance s^2 (J^T J)^-1
(they assume white residuals: with unmodelled wind they are optimistic).
"""

from __future__ import annotations

import math

import numpy as np
from seaway.vessel.model import surge_friction_law_n

from seaway_lab.identify.parameters import DT_S, theta_of
from seaway_lab.identify.trace import Trace


def simulate(theta: np.ndarray, thrust: np.ndarray, arm_m: float, x0: np.ndarray,
             friction: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Simulate [u, v, r] on the grid (RK4, ``DT_S``) for P parameter sets at once.

    ``theta``: (P, 6) ``PARAMS`` values; ``thrust``: (n, 2) produced thrust held over each step;
    ``x0``: (P, 3); ``friction``: (F_c, F_s, eps) of each set, each (P,), or None. Returns
    (n, 3, P): the state at each grid instant. The model of ``seaway.vessel.model.derivative``
    without the kinematics, on arrays of parameter sets (its friction law is the model's own).
    """
    m11, m22, m33, xu, yv, nr = (theta[:, i] for i in range(6))
    inv11, inv22, inv33, dm = 1.0 / m11, 1.0 / m22, 1.0 / m33, m22 - m11

    def f(u: np.ndarray, v: np.ndarray, r: np.ndarray, fs: float, my: float):
        surge = fs + m22 * v * r - xu * u
        if friction is not None:
            surge = surge - surge_friction_law_n(u, friction[0], friction[1], friction[2], np)
        return (surge * inv11, (-m11 * u * r - yv * v) * inv22,
                (my - dm * u * v - nr * r) * inv33)

    n = len(thrust)
    out = np.empty((n, 3, theta.shape[0]))
    u, v, r = x0[:, 0].copy(), x0[:, 1].copy(), x0[:, 2].copy()
    h = DT_S
    fs_all = thrust.sum(axis=1)
    my_all = (thrust[:, 0] - thrust[:, 1]) * arm_m
    for k in range(n):
        out[k, 0], out[k, 1], out[k, 2] = u, v, r
        fs, my = float(fs_all[k]), float(my_all[k])
        a1 = f(u, v, r, fs, my)
        a2 = f(u + 0.5 * h * a1[0], v + 0.5 * h * a1[1], r + 0.5 * h * a1[2], fs, my)
        a3 = f(u + 0.5 * h * a2[0], v + 0.5 * h * a2[1], r + 0.5 * h * a2[2], fs, my)
        a4 = f(u + h * a3[0], v + h * a3[1], r + h * a3[2], fs, my)
        u = u + h / 6.0 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0])
        v = v + h / 6.0 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
        r = r + h / 6.0 * (a1[2] + 2 * a2[2] + 2 * a3[2] + a4[2])
    return out


def friction_of(z: np.ndarray, eps_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F_c, F_s, eps) of the fit's parameter vectors (P, 13): F_c = exp(z11), F_s = F_c + exp(z12)
    (so that F_s >= F_c > 0), and the build-up speed ``eps_mps``, held fixed during the fit: were it
    to follow F and m11 (``friction_speed_mps``), a small m11 and a large F would widen it into a
    second linear damping, a valley the fit was seen to fall into. Held fixed, such a vessel is too
    stiff for the fit's own RK4 and the step is refused."""
    z = np.atleast_2d(z)
    fc = np.exp(z[:, 11])
    fs = fc + np.exp(z[:, 12])
    return fc, fs, np.full(len(fc), eps_mps)


def physical_of(z: np.ndarray, least_mps: float | None) -> np.ndarray:
    """The fitted values in vessel-file units (P, 6 or 8): ``PARAMS``, then ``FRICTION_PARAMS``
    when ``least_mps`` is given (friction fitted)."""
    theta = theta_of(z)
    if least_mps is None:
        return theta
    fc, fs, _ = friction_of(z, least_mps)
    return np.concatenate([theta, fc[:, None], fs[:, None]], axis=1)


class OutputError:
    """Residuals of the output-error problem. Vector z = [PARAMS through ``theta_of`` (6), current
    n, e, u0, v0, r0] and, when friction is fitted, [log F_c, log (F_s - F_c)]."""

    def __init__(self, trace: Trace, arm_m: float, thrust: np.ndarray, t_grid: np.ndarray,
                 t_end_s: float, friction_least_mps: float | None = None) -> None:
        self.friction_least_mps = friction_least_mps
        self.nz = 11 if friction_least_mps is None else 13
        self.arm_m = arm_m
        self.thrust = thrust
        self.t_grid = t_grid
        gi = (trace.gnss_t_s >= t_grid[0]) & (trace.gnss_t_s <= t_end_s)
        ai = (trace.att_t_s >= t_grid[0]) & (trace.att_t_s <= t_end_s)
        self.gnss_t = trace.gnss_t_s[gi]
        self.vel = trace.vel_ne_mps[gi]
        self.psi = trace.heading_at(self.gnss_t)
        self.att_t = trace.att_t_s[ai]
        self.r = trace.r_radps[ai]
        self.sigma = np.array([0.05, 0.005])  # [m/s, rad/s]: re-estimated from the residuals
        # the last grid instant the measurements need
        self.n = int(np.searchsorted(t_grid, max(self.gnss_t[-1], self.att_t[-1]), side="right")) + 1
        self.n = min(self.n, len(t_grid))

    def predict(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(P, nz) -> predicted (vel_n, vel_e) (P, ng, 2), r (P, na), body (u, v) (P, ng, 2)."""
        z = np.atleast_2d(z)
        theta = theta_of(z)
        friction = (None if self.friction_least_mps is None
                    else friction_of(z, self.friction_least_mps))
        x = simulate(theta, self.thrust[:self.n], self.arm_m, z[:, 8:11], friction)
        tg = self.t_grid[:self.n]
        u = np.stack([np.interp(self.gnss_t, tg, x[:, 0, p]) for p in range(z.shape[0])])
        v = np.stack([np.interp(self.gnss_t, tg, x[:, 1, p]) for p in range(z.shape[0])])
        r = np.stack([np.interp(self.att_t, tg, x[:, 2, p]) for p in range(z.shape[0])])
        c, s = np.cos(self.psi), np.sin(self.psi)
        vn = c * u - s * v + z[:, 6:7]
        ve = s * u + c * v + z[:, 7:8]
        return np.stack([vn, ve], axis=-1), r, np.stack([u, v], axis=-1)

    def residuals(self, z: np.ndarray) -> np.ndarray:
        """(P, m) weighted residuals for P parameter vectors."""
        vel, r, _ = self.predict(z)
        ev = (vel - self.vel[None]) / self.sigma[0]
        er = (r - self.r[None]) / self.sigma[1]
        return np.concatenate([ev.reshape(len(ev), -1), er], axis=1)

    def channel_rms(self, z: np.ndarray) -> tuple[float, float]:
        vel, r, _ = self.predict(z)
        return (float(np.sqrt(np.mean((vel[0] - self.vel) ** 2))),
                float(np.sqrt(np.mean((r[0] - self.r) ** 2))))


_STEP = 1e-4
"""The forward-difference step of the Jacobian in z (logarithms, speeds [m/s], rates [rad/s])."""


def jacobian(prob: OutputError, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    zs = np.vstack([z, z + _STEP * np.eye(len(z))])
    res = prob.residuals(zs)
    return res[0], ((res[1:] - res[0]) / _STEP).T


def levenberg_marquardt(prob: OutputError, z: np.ndarray, max_iter: int = 40,
                        tol: float = 1e-8) -> tuple[np.ndarray, np.ndarray, int]:
    """Minimise |residuals|^2 from ``z``; returns (z, J at the optimum, iterations)."""
    lam = 1e-3
    e, jac = jacobian(prob, z)
    cost = float(e @ e)
    it = 0
    for _ in range(max_iter):
        it += 1
        jtj, jte = jac.T @ jac, jac.T @ e
        improved = False
        for _ in range(12):
            step = np.linalg.solve(jtj + lam * np.diag(np.diag(jtj) + 1e-12), -jte)
            cand = z + step
            e_c = prob.residuals(cand)[0]
            c_c = float(e_c @ e_c)
            if math.isfinite(c_c) and c_c < cost:
                improved = True
                lam = max(lam / 3.0, 1e-9)
                break
            lam *= 4.0
        if not improved:
            break
        rel = (cost - c_c) / cost
        z = cand
        e, jac = jacobian(prob, z)
        cost = float(e @ e)
        if rel < tol:
            break
    return z, jac, it
