"""The parameters of the fit (``seaway_lab.identify.fit``): the parameter vector and its
constants, and the thrusters' model (the dead zone and the lag).
"""

from __future__ import annotations

import math

import numpy as np
from seaway.vessel.model import FRICTION_TAU_MIN_S, friction_rise_n

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
