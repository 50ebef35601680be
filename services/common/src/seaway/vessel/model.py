"""The vessel model of the paper's section II, written once.

Dynamics (paper eq. 1) and kinematics (eq. 2), Fossen's 3-DOF model with the paper's matrices::

    M v' + C(v) v + D v = tau + tau_d        v   = [u, v, r]          (body frame, FRD)
    eta' = R(psi) v (+ current)              eta = [x, y, psi]        (local NED: x north, y east)

    M = diag(m11, m22, m33)      D = diag(Xu, Yv, Nr)
    C(v) v = [-m22 v r,  m11 u r,  (m22 - m11) u v]
    tau = [T1 + T2, 0, (T1 - T2) l]           T1 port, T2 starboard  [N]
    power h_p(T) = alpha T^2 per thruster (eq. 3)                     [W]

The state vector is always ``[u, v, r, x, y, psi]`` in [m/s, m/s, rad/s, m, m, rad].

Extensions beyond the paper (all default to zero, which is the paper's model):

* ``tau_body``: a disturbance given in the body frame [N, N, N m] (paper's condition #2);
* ``force_ne``: a disturbance force given in the world frame [N north, N east], rotated into the body
  frame with the heading of each evaluation (conditions #3-#5, wind);
* ``current_ne``: an irrotational water current [m/s north, m/s east]. Then u, v are speeds through the
  water and the current is added to the kinematics (Fossen 2011, eq. 10.139 for constant current).

Every function here takes an ``ops`` namespace providing ``sin`` and ``cos``: pass ``math`` for the
fast plain-float path (the simulator, the estimator) or ``casadi`` for symbolic expressions (the
MPC). That is how the model exists once and is used by every service (see ``model_casadi``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from pydantic import Field, model_validator

from seaway.contract.config import ConfigError, ConfigModel, deploy_named, load_config
from seaway.vessel.battery import BatteryParams

STATE_NAMES = ("u_mps", "v_mps", "r_radps", "x_m", "y_m", "psi_rad")
NX = 6
NU = 2

ZERO3 = (0.0, 0.0, 0.0)
ZERO2 = (0.0, 0.0)


class VesselParams(ConfigModel):
    """A vessel file (``deploy/vessels/*.toml``): the paper's Table II plus the thruster limits."""

    name: str = Field(min_length=1)
    description: str = ""
    m11_kg: float = Field(gt=0, description="surge mass incl. added mass [kg]")
    m22_kg: float = Field(gt=0, description="sway mass incl. added mass [kg]")
    m33_kgm2: float = Field(gt=0, description="yaw inertia incl. added inertia [kg m^2]")
    xu_kgps: float = Field(gt=0, description="linear surge damping X_u [kg/s]")
    yv_kgps: float = Field(gt=0, description="linear sway damping Y_v [kg/s]")
    nr_kgm2ps: float = Field(gt=0, description="linear yaw damping N_r [kg m^2/s]")
    arm_m: float = Field(gt=0, description="thruster distance from the centre line l [m]")
    alpha_w_per_n2: float = Field(gt=0, description="power per squared thrust, per thruster [W/N^2]")
    thrust_max_n: float = Field(gt=0, description="|T| bound per thruster, ahead [N]")
    reverse_thrust_max_n: float | None = Field(
        default=None, gt=0, description="|T| bound astern if it differs from thrust_max_n [N]"
    )
    dead_zone_n: float = Field(default=0.0, ge=0, description="|T| below this gives no thrust [N]")
    thruster_time_constant_s: float = Field(default=0.0, ge=0, description="first-order lag [s]")
    battery: BatteryParams | None = Field(default=None, description="the propulsion battery "
                                          "(seaway.vessel.battery); None: not known")

    @model_validator(mode="after")
    def _dead_zone_below_the_bounds(self) -> VesselParams:
        if self.dead_zone_n >= min(self.thrust_max_n, self.reverse_max_n):
            raise ValueError(f"dead_zone_n {self.dead_zone_n:g} N must be below the thrust bounds "
                             f"(thrust_max_n {self.thrust_max_n:g} N, reverse {self.reverse_max_n:g} N):"
                             " the thrusters could never produce any thrust")
        return self

    @property
    def reverse_max_n(self) -> float:
        return self.thrust_max_n if self.reverse_thrust_max_n is None else self.reverse_thrust_max_n


def load_vessel(name_or_path: str | Path) -> VesselParams:
    """Load a vessel file by path, or by name from ``deploy/vessels/<name>.toml``."""
    return load_config(deploy_named("vessels", name_or_path, "vessel file"), VesselParams)


def check_vessel_files(**files: str | Path | None) -> None:
    """Load each vessel file given (``role=name or path``; None is skipped), so that a bad one is
    refused before anything uses it: ConfigError naming the role, the file and each bad field with
    its allowed range (e.g. ``model vessel file x.toml: m11_kg: Input should be greater than 0``)."""
    for role, name in files.items():
        if name is None:
            continue
        try:
            load_vessel(name)
        except ConfigError as err:
            raise ConfigError(f"{role.replace('_', ' ')} vessel file: {err}") from None


def world_to_body(north: Any, east: Any, cos_psi: Any, sin_psi: Any) -> tuple[Any, Any]:
    """A world-frame (NED) horizontal vector in the body frame: R(psi)^T [north, east] (eq. 2)."""
    return cos_psi * north + sin_psi * east, -sin_psi * north + cos_psi * east


def derivative(
    x: Sequence[Any],
    thrust: Sequence[Any],
    p: VesselParams,
    ops: ModuleType = math,
    tau_body: Sequence[Any] = ZERO3,
    force_ne: Sequence[Any] = ZERO2,
    current_ne: Sequence[Any] = ZERO2,
) -> list[Any]:
    """Time derivative of the state (paper eq. 1-2), as a list of six expressions or floats.

    ``x`` = [u, v, r, x, y, psi]; ``thrust`` = [T1, T2] in N; see the module docstring for the rest.
    """
    # Indexed, not unpacked through a generator: this runs some 70 times a simulated period (the
    # plant's RK4, the estimator's Jacobian), and the generator made it 1.35 us a call, not 0.88.
    u, v, r, psi = x[0], x[1], x[2], x[5]
    t1, t2 = thrust[0], thrust[1]
    c, s = ops.cos(psi), ops.sin(psi)
    wu, wv = world_to_body(force_ne[0], force_ne[1], c, s)
    fu, fv, fr = tau_body[0] + wu, tau_body[1] + wv, tau_body[2]
    m11, m22, m33 = p.m11_kg, p.m22_kg, p.m33_kgm2
    u_dot = (t1 + t2 + m22 * v * r - p.xu_kgps * u + fu) / m11
    v_dot = (-m11 * u * r - p.yv_kgps * v + fv) / m22
    r_dot = ((t1 - t2) * p.arm_m - (m22 - m11) * u * v - p.nr_kgm2ps * r + fr) / m33
    return [
        u_dot,
        v_dot,
        r_dot,
        u * c - v * s + current_ne[0],
        u * s + v * c + current_ne[1],
        r,
    ]


def rk4_step(
    x: Sequence[Any],
    thrust: Sequence[Any],
    dt_s: float | Any,
    p: VesselParams,
    ops: ModuleType = math,
    tau_body: Sequence[Any] = ZERO3,
    force_ne: Sequence[Any] = ZERO2,
    current_ne: Sequence[Any] = ZERO2,
) -> list[Any]:
    """One classical Runge-Kutta 4 step of ``derivative`` with inputs held over the step."""

    def f(xs: Sequence[Any]) -> list[Any]:
        return derivative(xs, thrust, p, ops, tau_body, force_ne, current_ne)

    # The same operations in the same order as the textbook form (so the same floats, bit for bit),
    # over zip rather than indices: the plant takes ten of these a period.
    half, sixth = 0.5 * dt_s, dt_s / 6.0
    x = [x[i] for i in range(NX)]  # a CasADi vector as its six entries; a list as a copy
    k1 = f(x)
    k2 = f([xi + half * ki for xi, ki in zip(x, k1, strict=True)])
    k3 = f([xi + half * ki for xi, ki in zip(x, k2, strict=True)])
    k4 = f([xi + dt_s * ki for xi, ki in zip(x, k3, strict=True)])
    return [xi + sixth * (a + 2.0 * b + 2.0 * c + d)
            for xi, a, b, c, d in zip(x, k1, k2, k3, k4, strict=True)]


def thruster_power_w(thrust_n: float | Any, p: VesselParams) -> float | Any:
    """h_p(T) = alpha T^2, one thruster (paper eq. 3) [W]."""
    return p.alpha_w_per_n2 * thrust_n * thrust_n


def propulsion_power_w(thrust: Sequence[Any], p: VesselParams) -> float | Any:
    """Both thrusters' power alpha (T1^2 + T2^2) [W]."""
    return thruster_power_w(thrust[0], p) + thruster_power_w(thrust[1], p)


def wrench(thrust: Sequence[Any], p: VesselParams) -> tuple[Any, Any, Any]:
    """tau = [T1 + T2, 0, (T1 - T2) l] [N, N, N m]."""
    return (thrust[0] + thrust[1], 0.0, (thrust[0] - thrust[1]) * p.arm_m)


def thrusts_for_wrench(surge_n: float, yaw_nm: float, p: VesselParams) -> tuple[float, float]:
    """Inverse of ``wrench`` for the actuated DOFs: (T1, T2) giving surge force and yaw moment."""
    half_diff = yaw_nm / (2.0 * p.arm_m)
    return (surge_n / 2.0 + half_diff, surge_n / 2.0 - half_diff)
