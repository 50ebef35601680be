"""The fit of the paper's model to a run: equation error for a start, output error to finish.

Model (``seaway.vessel.model``, body frame, T1 port, T2 starboard, l the thruster arm)::

    m11 u' =  T1 + T2 + m22 v r - Xu u
    m22 v' = -m11 u r - Yv v
    m33 r' = (T1 - T2) l - (m22 - m11) u v - Nr r

with the thrust produced from the command by the dead zone (|T| < dz gives 0) and, if asked, a
first-order lag. Measured: the velocity over ground, NED, at each GNSS fix, which is R(psi) [u, v]
plus a constant water current (fitted), and the yaw rate r of each attitude sample.

What such data can and cannot determine:

* the thrust is taken to be the commanded force in newtons. A thrust-mapping gain error k (the
  thrusters give k T for T commanded) scales every mass and damping by 1/k and is invisible in
  the motion; the model found is the one that matches the commands, which is what the controller
  needs, as long as it commands through the same mapping;
* in yaw, the moment is (T1 - T2) l, so m33/l and Nr/l are what the yaw data fix; l enters nowhere
  else except through the Munk moment (m22 - m11) u v, too small to pin it. So l is fixed (the
  vessel drawing: the distance from the centre line to each thruster) and m33, Nr follow; an
  error of x % in l is an error of x % in both;
* the power per squared thrust alpha (paper eq. 3) needs a power measurement: not in the motion,
  so it is copied from the reference vessel file, as are the thrust bounds;
* the dead zone shows where the slow ramp of the manoeuvre first moves the vessel; it is chosen by
  profiling the equation error over candidate values;
* the thruster time constant, when it is a few tenths of a second, trades against m11 (both slow
  the surge response); it is fitted only when asked (``fit_lag``), by the same profile;
* surge friction (``fit_friction``; the law ``F_f(u)`` of ``seaway.vessel.model``): the sliding
  friction F_c and the friction near rest F_s, for a plant that has them (a wheeled test rover).
  F_c shows as the thrust the vessel needs to keep moving beyond what X_u u explains, F_s in how
  it starts from rest. The speed ``eps`` over which the friction builds up is not identified: it
  is set where the model stays integrable at the control period (``FRICTION_TAU_MIN_S``, with a
  margin) or at ``friction_speed_mps`` if that is larger, a function of F_c, F_s and m11 that moves
  with them during the fit. A dead zone and friction both explain a vessel that does not move on
  a small command; fit friction with the dead zone given (0 for a plant without one).

Equation error: the model integrated over windows of ``WINDOW_S`` (no derivatives of noisy data):
``m11 (u_b - u_a) - m22 int(v r) + Xu int(u) = int(T1 + T2)`` and likewise for sway and yaw, one
weighted linear least squares over all windows. It is biased (noise in the regressors) and only
gives the output-error fit its start and the dead-zone profile.

Output error: the model is simulated (RK4 on a grid of ``DT_S``) from a fitted initial state, with the
commanded thrusts, and the dampings (as logarithms: they stay positive), the time constants m/d of
surge, sway and yaw (as the logarithm of their excess over ``TAU_MIN_S``: they stay above it), the
water current and the initial state are found by Levenberg-Marquardt on the weighted residuals of the measured
velocity over ground and yaw rate, each channel weighted by its residual RMS. Noise is then only in
the outputs, so the estimates are unbiased; standard errors come from the Gauss-Newton covariance
s^2 (J^T J)^-1 (they assume white residuals: with unmodelled wind they are optimistic).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from seaway.vessel.model import FRICTION_TAU_MIN_S, friction_rise_n, surge_friction_law_n

from seaway_lab.identify.trace import IdentifyError, Trace

PARAMS = ("m11_kg", "m22_kg", "m33_kgm2", "xu_kgps", "yv_kgps", "nr_kgm2ps")
"""The fitted model parameters, in the order of the parameter vector (vessel-file names)."""
DT_S = 0.1
"""The simulation grid of the output-error fit [s]: RK4 on it is accurate to about 1e-3 for a
surge or sway time constant of 0.2 s."""
TAU_MIN_S = 0.1
"""The shortest time constant m/d (surge m11/Xu, sway m22/Yv, yaw m33/Nr) a fit may give [s]: the
control period. The controller integrates the model with RK4 at that period, which diverges for a
time constant below 0.036 s (h lambda > 2.8) and, measured on ArduPilot SITL with 0.05 s in yaw,
made its solver fail to converge in turns; this fit's own integrator on ``DT_S`` is the same; and a
response faster than one period is neither resolved by 5-10 Hz sensors nor something a command
every period can shape. A vessel that is quicker (ArduPilot SITL's boat sets its yaw rate
instantly) gets this floor, and the note says so."""
WINDOW_S = 1.0
"""The equation error's integration window [s]."""
FRICTION_PARAMS = ("friction_n", "static_friction_n")
"""The surge friction's fitted parameters (vessel-file names), after PARAMS when fitted."""
FRICTION_SPEED_MPS = 0.3
"""The friction's build-up speed eps the fit starts from and uses at least [m/s] (``fit``'s
``friction_speed_mps``): raised, with F_c, F_s and m11, to keep the friction integrable."""
FRICTION_MARGIN = 1.2
"""eps is set to this times the least integrable eps (``seaway.vessel.model.FRICTION_TAU_MIN_S``)
so that a file written from the fit loads whatever its rounding."""


def friction_speed_mps(fc: np.ndarray, fs: np.ndarray, m11: np.ndarray,
                       least_mps: float = FRICTION_SPEED_MPS) -> np.ndarray:
    """The build-up speed eps [m/s] for friction F_c, F_s on mass m11 (arrays of candidates):
    ``least_mps``, or the least the control period can integrate times ``FRICTION_MARGIN``."""
    return np.maximum(least_mps, FRICTION_MARGIN * FRICTION_TAU_MIN_S * friction_rise_n(fc, fs) / m11)


def theta_of(z: np.ndarray) -> np.ndarray:
    """PARAMS values (P, 6) of the fit's parameter vectors (P, >= 6): dampings as logarithms, the
    masses through their time constants, ``m = d (TAU_MIN_S + exp(z))``, so every time constant
    stays above ``TAU_MIN_S``."""
    z = np.atleast_2d(z)
    d = np.exp(z[:, 3:6])
    m = d * (TAU_MIN_S + np.exp(z[:, 0:3]))
    return np.concatenate([m, d], axis=1)


def z_of(theta: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The parameter vector of PARAMS values ``theta`` (6,); a time constant at or below
    ``TAU_MIN_S`` is raised just above it (its mass with it), and named in the second value."""
    d = theta[3:6]
    excess = theta[0:3] / d - TAU_MIN_S
    raised = [PARAMS[i] for i in range(3) if excess[i] <= 0.01 * TAU_MIN_S]
    excess = np.maximum(excess, 0.01 * TAU_MIN_S)
    return np.concatenate([np.log(excess), np.log(d)]), raised
HOLDOUT_FRACTION = 0.25


@dataclass
class Estimate:
    value: float
    std: float

    @property
    def rel_std(self) -> float:
        return self.std / abs(self.value) if self.value else math.inf


@dataclass
class Prediction:
    """Measured against predicted on the run's time axis [s]."""

    t_s: np.ndarray
    u_meas: np.ndarray
    u_pred: np.ndarray
    v_meas: np.ndarray
    v_pred: np.ndarray
    r_t_s: np.ndarray
    r_meas: np.ndarray
    r_pred: np.ndarray


@dataclass
class FitResult:
    params: dict[str, Estimate]
    arm_m: float
    dead_zone_n: float
    dead_zone_profile: list[tuple[float, float]]
    """(candidate dead zone [N], equation-error cost): the profile it was chosen from."""
    lag_s: float
    current_ne_mps: tuple[float, float]
    start: dict[str, float]
    """The equation-error estimates the output-error fit started from."""
    split_s: float
    """Fitted on t < split_s; held out after."""
    rms_fit: dict[str, float]
    rms_holdout: dict[str, float]
    iterations: int
    samples: int
    prediction: Prediction
    notes: list[str] = field(default_factory=list)
    friction: dict[str, Estimate] = field(default_factory=dict)
    """FRICTION_PARAMS when fitted (``fit_friction``), else empty."""
    friction_speed_mps: float = 0.0
    """The friction's build-up speed eps of the fitted values [m/s] (0: no friction fitted)."""

    @property
    def ratios(self) -> dict[str, float]:
        """What the yaw data determine whatever l is: m33/l [kg m] and Nr/l [kg m/s]."""
        return {"m33_over_arm_kgm": self.params["m33_kgm2"].value / self.arm_m,
                "nr_over_arm_kgmps": self.params["nr_kgm2ps"].value / self.arm_m}


# -- the thrusters ------------------------------------------------------------------------------


def produced_thrust(cmd_n: np.ndarray, dead_zone_n: float, lag_s: float, dt_s: float) -> np.ndarray:
    """(n, 2) thrust produced on a uniform grid from the commands held on it [N]: dead zone, then
    a first-order lag (exact for a command held over each step; the grid value is the step mean)."""
    out = np.where(np.abs(cmd_n) < dead_zone_n, 0.0, cmd_n)
    if lag_s <= 0:
        return out
    a = math.exp(-dt_s / lag_s)
    mean_gain = 1.0 - lag_s / dt_s * (1.0 - a)  # fraction of the step's change reached, on average
    lagged = np.empty_like(out)
    state = np.zeros(2)
    for k in range(len(out)):
        lagged[k] = state + (out[k] - state) * mean_gain
        state = out[k] + (state - out[k]) * a
    return lagged


# -- equation error -----------------------------------------------------------------------------


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


# -- output error -------------------------------------------------------------------------------


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


class _OutputError:
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


def _jacobian(prob: _OutputError, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    zs = np.vstack([z, z + _STEP * np.eye(len(z))])
    res = prob.residuals(zs)
    return res[0], ((res[1:] - res[0]) / _STEP).T


def levenberg_marquardt(prob: _OutputError, z: np.ndarray, max_iter: int = 40,
                        tol: float = 1e-8) -> tuple[np.ndarray, np.ndarray, int]:
    """Minimise |residuals|^2 from ``z``; returns (z, J at the optimum, iterations)."""
    lam = 1e-3
    e, jac = _jacobian(prob, z)
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
        e, jac = _jacobian(prob, z)
        cost = float(e @ e)
        if rel < tol:
            break
    return z, jac, it


# -- the whole fit ------------------------------------------------------------------------------


def fit(trace: Trace, arm_m: float, *, fit_dead_zone: bool = True, dead_zone_n: float = 0.0,
        lag_s: float = 0.0, fit_lag: bool = False,
        holdout_fraction: float = HOLDOUT_FRACTION,
        start_theta: np.ndarray | None = None, fit_friction: bool = False,
        friction_least_mps: float = FRICTION_SPEED_MPS) -> FitResult:
    """Fit ``PARAMS`` to ``trace`` with the arm ``arm_m`` fixed (see the module docstring).

    ``dead_zone_n`` and ``lag_s`` are used as given unless ``fit_dead_zone`` / ``fit_lag``. The
    last ``holdout_fraction`` of the run is held out: not fitted, only predicted. ``start_theta``
    (PARAMS values, e.g. the base vessel file's) is tried as the start beside the equation error's.
    ``fit_friction`` fits ``FRICTION_PARAMS`` too, with a build-up speed of at least
    ``friction_least_mps`` [m/s].
    """
    if not arm_m > 0:
        raise IdentifyError(f"the thruster arm must be > 0 m (the vessel drawing's distance from the "
                            f"centre line to each thruster), got {arm_m}")
    if not 0.0 <= holdout_fraction < 0.9:
        raise IdentifyError(f"holdout fraction must be in [0, 0.9), got {holdout_fraction}")
    t0 = max(trace.cmd_t_s[0], trace.gnss_t_s[0], trace.att_t_s[0])
    t_end = min(trace.cmd_t_s[-1], trace.gnss_t_s[-1], trace.att_t_s[-1])
    split = t_end - holdout_fraction * (t_end - t0)
    if not friction_least_mps > 0:
        raise IdentifyError(f"the friction's build-up speed must be > 0 m/s, got {friction_least_mps}")
    least = friction_least_mps if fit_friction else None
    notes = []
    peak = float(np.max(np.abs(trace.cmd_n)))
    profile: list[tuple[float, float]] = []
    if fit_lag:
        lags = np.array([0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 0.4, 0.6, 0.8, 1.0])
        costs = [equation_error(trace, arm_m, dead_zone_n, float(tc), split, least)[2] for tc in lags]
        lag_s = float(lags[int(np.argmin(costs))])
    if fit_dead_zone:
        cands = np.linspace(0.0, 0.35 * peak, 36)
        profile = dead_zone_profile(trace, arm_m, cands, lag_s, split, least)
        dead_zone_n = profile[int(np.argmin([c for _, c in profile]))][0]
    start_all, _, _ = equation_error(trace, arm_m, dead_zone_n, lag_s, split, least)
    theta0 = start_all[:6]
    start = dict(zip(PARAMS, map(float, theta0), strict=True))
    bad = [p for p, v in start.items() if not v > 0]
    if bad:
        notes.append(f"equation error gave non-positive {', '.join(bad)}: started from 1 instead")
        theta0 = np.where(theta0 > 0, theta0, 1.0)
    z_friction: list[float] = []
    if fit_friction:
        fc0, fs0 = float(start_all[6]), float(start_all[7])
        start.update(friction_n=fc0, static_friction_n=fs0)
        if not fc0 > 0:
            notes.append(f"equation error gave friction_n {fc0:.3g} N: started from 1 N instead")
            fc0 = 1.0
        fs0 = max(fs0, 1.05 * fc0)  # F_s > F_c is the parametrisation's
    t_grid = np.arange(t0, t_end + DT_S, DT_S)
    thrust = produced_thrust(trace.command_at(t_grid), dead_zone_n, lag_s, DT_S)
    prob = _OutputError(trace, arm_m, thrust, t_grid, split, least)
    uv0 = trace.body_velocity()
    x0 = np.array([np.interp(t0, trace.gnss_t_s, uv0[:, 0]), np.interp(t0, trace.gnss_t_s, uv0[:, 1]),
                   np.interp(t0, trace.att_t_s, trace.r_radps)])
    # The start: the equation error's values, or the base vessel's if they predict the run better
    # (the equation error is biased, and on a vessel far from the model's form it can start the
    # simulation somewhere it cannot recover from).
    starts = [("the equation error", theta0)]
    if start_theta is not None:
        starts.append(("the base vessel file", np.asarray(start_theta, dtype=float)))
    best: tuple[float, str, np.ndarray, list[str]] | None = None
    for label, th in starts:
        zs, raised = z_of(th)
        if fit_friction:  # a friction start this start's m11 integrates (FRICTION_TAU_MIN_S)
            scale = min(1.0, 0.8 * least * th[0] / FRICTION_TAU_MIN_S / friction_rise_n(fc0, fs0))
            z_friction = [math.log(scale * fc0), math.log(scale * (fs0 - fc0))]
        cand = np.concatenate([zs, [0.0, 0.0], x0, z_friction])
        with np.errstate(all="ignore"):
            e0 = prob.residuals(cand)[0]
        cost = float(e0 @ e0)
        if math.isfinite(cost) and (best is None or cost < best[0]):
            best = (cost, label, cand, raised)
    if best is None:
        raise IdentifyError("the model cannot follow this run from any start (its simulation "
                            "diverges): check that the commands reached the thrusters")
    _, label, z, raised = best
    if label != "the equation error":
        notes.append(f"started from {label} (it predicts the run better than the equation error)")
    if raised:
        notes.append(f"the start's time constants of {', '.join(raised)} were below "
                     f"{TAU_MIN_S:g} s: raised to it")
    iters = 0
    with np.errstate(all="ignore"):  # a trial step may diverge: LM refuses it (non-finite cost)
        for _ in range(3):  # re-weight each channel by its residual RMS, then refit
            z, jac, it = levenberg_marquardt(prob, z)
            iters += it
            prob.sigma = np.maximum(np.array(prob.channel_rms(z)), 1e-9)
    e = prob.residuals(z)[0]
    _, jac = _jacobian(prob, z)
    dof = max(1, len(e) - len(z))
    s2 = float(e @ e) / dof
    # The pseudo-inverse: a time constant pressed to its floor leaves its column of J near zero (the
    # data say nothing more about it), which must not turn every other standard error into NaN.
    try:
        cov = np.linalg.pinv(jac.T @ jac) * s2
    except np.linalg.LinAlgError:
        cov = np.full((len(z), len(z)), np.inf)
    values = physical_of(z, least)[0]
    theta = values[:6]
    # Standard errors by the delta method through physical_of (a mass depends on two entries of
    # z, F_s on two, eps on no fitted entry of its own).
    grad = np.zeros((len(values), len(z)))
    for j in range(len(z)):
        dz = np.zeros_like(z)
        dz[j] = 1e-6
        grad[:, j] = (physical_of(z + dz, least)[0] - values) / 1e-6
    var = np.einsum("ij,jk,ik->i", grad, cov, grad)
    estimates = [Estimate(float(values[i]), float(math.sqrt(abs(var[i])))) for i in range(len(values))]
    params = dict(zip(PARAMS, estimates[:6], strict=True))
    friction = dict(zip(FRICTION_PARAMS, estimates[6:], strict=True)) if least is not None else {}
    eps = 0.0
    if least is not None:
        eps = float(friction_speed_mps(values[6], values[7], values[0], least))
        if eps > least:  # the file must load (seaway.vessel.model's integrability bound)
            notes.append(f"friction_speed_mps raised from {least:g} to {eps:.3g} m/s: the fitted "
                         "friction is too stiff for the control period at the speed fitted with")
    at_floor = [PARAMS[i] for i in range(3) if theta[i] / theta[i + 3] < 1.05 * TAU_MIN_S]
    if at_floor:
        notes.append(f"time constant of {', '.join(at_floor)} at the {TAU_MIN_S:g} s floor: this "
                     "vessel responds faster than the model can be integrated at the control period")

    # Prediction over the whole run with the fitted model, compared on both parts.
    full = _OutputError(trace, arm_m, thrust, t_grid, t_end, least)
    full.sigma = prob.sigma
    _, r_pred, uv_pred = full.predict(z)
    current = (float(z[6]), float(z[7]))
    uv_meas = trace.body_velocity(current)
    gsel = (trace.gnss_t_s >= t0) & (trace.gnss_t_s <= t_end)
    uv_meas = uv_meas[gsel]
    pred = Prediction(full.gnss_t, uv_meas[:, 0], uv_pred[0, :, 0], uv_meas[:, 1], uv_pred[0, :, 1],
                      full.att_t, full.r, r_pred[0])

    def rms(sel_g: np.ndarray, sel_a: np.ndarray) -> dict[str, float]:
        def one(a: np.ndarray, b: np.ndarray) -> float:
            return float(np.sqrt(np.mean((a - b) ** 2))) if len(a) else math.nan
        return {"u_mps": one(pred.u_meas[sel_g], pred.u_pred[sel_g]),
                "v_mps": one(pred.v_meas[sel_g], pred.v_pred[sel_g]),
                "r_radps": one(pred.r_meas[sel_a], pred.r_pred[sel_a])}

    return FitResult(
        params=params, arm_m=arm_m, dead_zone_n=float(dead_zone_n), dead_zone_profile=profile,
        lag_s=float(lag_s), current_ne_mps=current, start=start, split_s=float(split),
        rms_fit=rms(pred.t_s < split, pred.r_t_s < split),
        rms_holdout=rms(pred.t_s >= split, pred.r_t_s >= split),
        iterations=iters, samples=len(e), prediction=pred, notes=notes, friction=friction,
        friction_speed_mps=eps)
