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

The fit has two stages, each in a module of its own: the equation error
(``seaway_lab.identify.equation_error``) gives the start and the dead-zone profile, the output
error (``seaway_lab.identify.output_error``) the estimates. The parameter vector, its constants
and the thrusters' model are ``seaway_lab.identify.parameters``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from seaway.vessel.model import FRICTION_TAU_MIN_S, friction_rise_n

from seaway_lab.identify.equation_error import dead_zone_profile, equation_error
from seaway_lab.identify.output_error import OutputError, jacobian, levenberg_marquardt, physical_of
from seaway_lab.identify.parameters import (
    DT_S,
    FRICTION_PARAMS,
    FRICTION_SPEED_MPS,
    PARAMS,
    TAU_MIN_S,
    friction_speed_mps,
    produced_thrust,
    z_of,
)
from seaway_lab.identify.trace import IdentifyError, Trace

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
    prob = OutputError(trace, arm_m, thrust, t_grid, split, least)
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
    _, jac = jacobian(prob, z)
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
    full = OutputError(trace, arm_m, thrust, t_grid, t_end, least)
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
