"""The first stage of the fit (``seaway_lab.identify.fit``), the equation error: the model integrated
over windows of ``WINDOW_S`` (no derivatives of noisy data): ``m11 (u_b - u_a) - m22 int(v r) + Xu
int(u) = int(T1 + T2)`` and likewise for sway and yaw, one weighted linear least squares over all
windows. It is biased (noise in the regressors) and only gives the output-error fit its start and
the dead-zone profile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from seaway.vessel.model import surge_friction_law_n

from seaway_lab.identify.parameters import DT_S, WINDOW_S, produced_thrust
from seaway_lab.identify.trace import Trace


@dataclass
class _Grid:
    t_s: np.ndarray
    u: np.ndarray
    v: np.ndarray
    r: np.ndarray
    cmd: np.ndarray


def _grid(trace: Trace, t_end_s: float) -> _Grid:
    t0 = max(trace.cmd_t_s[0], trace.gnss_t_s[0], trace.att_t_s[0])
    t = np.arange(t0, t_end_s, DT_S)
    uv = trace.body_velocity()
    return _Grid(t, np.interp(t, trace.gnss_t_s, uv[:, 0]), np.interp(t, trace.gnss_t_s, uv[:, 1]),
                 np.interp(t, trace.att_t_s, trace.r_radps), trace.command_at(t))


def _friction_shapes(u: np.ndarray, eps_mps: float) -> tuple[np.ndarray, np.ndarray]:
    """F_f(u) = F_c g_c(u) + F_s g_s(u): the law of ``seaway.vessel.model`` split into its two
    linear parts, each evaluated through that law (a unit F_c, then a unit F_s)."""
    return (surge_friction_law_n(u, 1.0, 0.0, eps_mps, np),
            surge_friction_law_n(u, 0.0, 1.0, eps_mps, np))


def _equation_rows(g: _Grid, thrust: np.ndarray, arm_m: float,
                   friction_eps_mps: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(A, b) of the windowed equations, rows [surge..., sway..., yaw...], columns ``PARAMS``
    (then ``FRICTION_PARAMS`` on the surge rows, for the build-up speed ``friction_eps_mps``)."""
    n = max(1, round(WINDOW_S / DT_S))
    ends = np.arange(n, len(g.t_s), n)
    starts = ends - n

    def integral(x: np.ndarray) -> np.ndarray:
        c = np.concatenate([[0.0], np.cumsum(0.5 * (x[1:] + x[:-1]) * DT_S)])
        return c[ends] - c[starts]

    def delta(x: np.ndarray) -> np.ndarray:
        return x[ends] - x[starts]

    # Thrust is piecewise constant on the grid (held over [t_k, t_k+1)): a left sum, not trapezoid.
    csum = np.concatenate([[0.0], np.cumsum(thrust[:-1].sum(axis=1) * DT_S)])
    cdiff = np.concatenate([[0.0], np.cumsum((thrust[:-1, 0] - thrust[:-1, 1]) * DT_S)])
    surge_f = csum[ends] - csum[starts]
    yaw_m = (cdiff[ends] - cdiff[starts]) * arm_m
    z = np.zeros(len(ends))
    ivr, iur, iuv = integral(g.v * g.r), integral(g.u * g.r), integral(g.u * g.v)
    surge = np.column_stack([delta(g.u), -ivr, z, integral(g.u), z, z])
    sway = np.column_stack([iur, delta(g.v), z, z, integral(g.v), z])
    yaw = np.column_stack([-iuv, iuv, delta(g.r), z, z, integral(g.r)])
    if friction_eps_mps is not None:
        g_c, g_s = _friction_shapes(g.u, friction_eps_mps)
        surge = np.column_stack([surge, integral(g_c), integral(g_s)])
        sway = np.column_stack([sway, z, z])
        yaw = np.column_stack([yaw, z, z])
    return np.vstack([surge, sway, yaw]), np.concatenate([surge_f, z, yaw_m])


def _weighted_lstsq(a: np.ndarray, b: np.ndarray, groups: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Least squares with each of ``groups`` equal blocks of rows weighted by its residual RMS
    (two passes); returns (theta, standard errors, weighted cost)."""
    m = len(b) // groups
    w = np.ones(len(b))
    for _ in range(2):
        theta, *_ = np.linalg.lstsq(a * w[:, None], b * w, rcond=None)
        res = a @ theta - b
        for k in range(groups):
            rms = float(np.sqrt(np.mean(res[k * m:(k + 1) * m] ** 2)))
            w[k * m:(k + 1) * m] = 1.0 / max(rms, 1e-12)
    aw = a * w[:, None]
    res_w = (a @ theta - b) * w
    dof = max(1, len(b) - a.shape[1])
    s2 = float(res_w @ res_w) / dof
    try:
        cov = np.linalg.inv(aw.T @ aw) * s2
        std = np.sqrt(np.abs(np.diag(cov)))
    except np.linalg.LinAlgError:
        std = np.full(a.shape[1], np.inf)
    # The profile compares candidates with the same weights: the unweighted cost would favour the
    # candidate with the smallest force scale, the weighted one is scale-free.
    return theta, std, float(np.sum(((a @ theta - b) / np.maximum(np.abs(b).max(), 1e-12)) ** 2))


def equation_error(trace: Trace, arm_m: float, dead_zone_n: float = 0.0, lag_s: float = 0.0,
                   t_end_s: float | None = None, friction_eps_mps: float | None = None,
                   ) -> tuple[np.ndarray, np.ndarray, float]:
    """Equation-error estimates of ``PARAMS`` (and ``FRICTION_PARAMS`` with ``friction_eps_mps``):
    values, standard errors, cost, on t < ``t_end_s``."""
    g = _grid(trace, trace.cmd_t_s[-1] if t_end_s is None else t_end_s)
    thrust = produced_thrust(g.cmd, dead_zone_n, lag_s, DT_S)
    a, b = _equation_rows(g, thrust, arm_m, friction_eps_mps)
    return _weighted_lstsq(a, b, 3)


def dead_zone_profile(trace: Trace, arm_m: float, candidates: np.ndarray, lag_s: float,
                      t_end_s: float, friction_eps_mps: float | None = None,
                      ) -> list[tuple[float, float]]:
    """The equation error's cost at each candidate dead zone [N]."""
    g = _grid(trace, t_end_s)
    out = []
    for dz in candidates:
        a, b = _equation_rows(g, produced_thrust(g.cmd, float(dz), lag_s, DT_S), arm_m,
                              friction_eps_mps)
        theta, _, _ = _weighted_lstsq(a, b, 3)
        res = a @ theta - b
        m = len(b) // 3
        # the surge and yaw rows carry the thrust: their relative residual, summed
        cost = sum(float(np.sum(res[k * m:(k + 1) * m] ** 2) / max(np.sum(b[k * m:(k + 1) * m] ** 2),
                                                                   1e-12)) for k in (0, 2))
        out.append((float(dz), cost))
    return out
