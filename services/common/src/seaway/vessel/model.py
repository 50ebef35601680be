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

And one optional term of the vessel file, zero for the paper's boat: **surge friction**
``F_f(u)`` (``surge_friction_n``), subtracted from the surge force. A hull in water has none; a
wheeled test plant (PX4 SITL's SIH rover) has Coulomb ground friction that a linear damping can
only fake by a secant over the speeds flown. The law is smooth, so the MPC can differentiate it::

    F_f(u) = F_c tanh(2 u / eps) + (F_s - F_c) (u / eps) exp((1 - (u / eps)^2) / 2)

``F_c`` (``friction_n``) the sliding friction, ``F_s`` (``static_friction_n``) the friction near rest
(the breakaway force, near ``u = eps``: Stribeck's hump), ``eps`` (``friction_speed_mps``)
the speed over which it builds up. Below ``F_s`` the model creeps (a fraction of ``eps``)
where the plant sticks; above ``eps`` it is ``F_c`` and the speed is ``(T - F_c) / X_u``. ``eps``
is bounded below (``FRICTION_TAU_MIN_S``) so that RK4 at the control period stays stable.

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

FRICTION_TAU_MIN_S = 0.05
"""The shortest time constant the surge friction may have, ``eps m11 / F_f'(0)`` [s]: its slope at
rest, ``(2 F_c + e^0.5 (F_s - F_c)) / eps``, is a stiffness the controller's and estimator's RK4
integrate at the 0.1 s control period, stable up to h lambda = 2.8; 0.05 s keeps it at 2."""


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
    friction_n: float = Field(default=0.0, ge=0, description="sliding (Coulomb) friction against "
                              "surge F_c [N]; 0 for a hull (seaway.vessel.model, surge_friction_n)")
    static_friction_n: float | None = Field(
        default=None, ge=0, description="surge friction near rest F_s, the breakaway force [N]; "
        "None: friction_n")
    friction_speed_mps: float = Field(default=0.4, gt=0, description="the speed eps over which "
                                      "the surge friction builds up [m/s]")
    battery: BatteryParams | None = Field(default=None, description="the propulsion battery "
                                          "(seaway.vessel.battery); None: not known")

    @model_validator(mode="after")
    def _dead_zone_below_the_bounds(self) -> VesselParams:
        if self.dead_zone_n >= min(self.thrust_max_n, self.reverse_max_n):
            raise ValueError(f"dead_zone_n {self.dead_zone_n:g} N must be below the thrust bounds "
                             f"(thrust_max_n {self.thrust_max_n:g} N, reverse {self.reverse_max_n:g} N):"
                             " the thrusters could never produce any thrust")
        return self

    @model_validator(mode="after")
    def _friction_integrable(self) -> VesselParams:
        if self.static_n < self.friction_n:
            raise ValueError(f"static_friction_n {self.static_n:g} N must be at least friction_n "
                             f"{self.friction_n:g} N (friction near rest is not below sliding)")
        force_n = friction_rise_n(self.friction_n, self.static_n)
        least_mps = FRICTION_TAU_MIN_S * force_n / self.m11_kg
        if self.friction_speed_mps < least_mps:
            raise ValueError(
                f"friction_speed_mps {self.friction_speed_mps:g} m/s is too small for friction_n "
                f"{self.friction_n:g} N and static_friction_n {self.static_n:g} N on m11_kg "
                f"{self.m11_kg:g} kg: the friction's time constant would be below "
                f"{FRICTION_TAU_MIN_S:g} s, where RK4 at the control period diverges; need "
                f">= {least_mps:.3g} m/s")
        return self

    @property
    def static_n(self) -> float:
        """F_s [N]: ``static_friction_n``, or ``friction_n`` when not given."""
        return self.friction_n if self.static_friction_n is None else self.static_friction_n

    @property
    def has_friction(self) -> bool:
        return self.friction_n > 0 or self.static_n > 0

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


def friction_rise_n(friction_n: float, static_n: float) -> float:
    """``eps F_f'(0)`` = 2 F_c + e^0.5 (F_s - F_c) [N]: the friction law's slope at rest times eps."""
    return 2.0 * friction_n + math.exp(0.5) * (static_n - friction_n)


def surge_friction_law_n(u_mps: Any, friction_n: Any, static_n: Any, speed_mps: Any,
                         ops: ModuleType = math) -> Any:
    """F_f(u) of the module docstring [N], opposing the surge speed ``u_mps`` (body frame).

    Written on its arguments, not a vessel file, so that the identification evaluates it on arrays
    of candidate values (``ops`` = numpy) as the simulator (math) and the MPC (casadi) do."""
    x = u_mps / speed_mps
    return (friction_n * ops.tanh(2.0 * x)
            + (static_n - friction_n) * x * ops.exp(0.5 * (1.0 - x * x)))


def surge_friction_n(u_mps: Any, p: VesselParams, ops: ModuleType = math) -> Any:
    """The vessel's surge friction F_f(u) [N]; 0 for a vessel without (the paper's)."""
    if not p.has_friction:
        return 0.0
    return surge_friction_law_n(u_mps, p.friction_n, p.static_n, p.friction_speed_mps, ops)


def surge_resistance_n(u_mps: Any, p: VesselParams, ops: ModuleType = math) -> Any:
    """The steady surge force that holds speed ``u_mps`` in still water: X_u u + F_f(u) [N]."""
    if not p.has_friction:
        return p.xu_kgps * u_mps
    return p.xu_kgps * u_mps + surge_friction_n(u_mps, p, ops)


def sliding_resistance_n(u_mps: Any, p: VesselParams) -> Any:
    """X_u u + F_c [N]: ``surge_resistance_n`` at a cruise above ``eps``, where the friction is the
    sliding one; no transcendental, so it prices cruising on floats, arrays and CasADi symbols."""
    if not p.has_friction:
        return p.xu_kgps * u_mps
    return p.xu_kgps * u_mps + p.friction_n


def steady_surge_speed_mps(surge_n: float, p: VesselParams) -> float:
    """The speed a steady surge force settles to once sliding [m/s]: (T - F_c sign T) / X_u, 0
    within the sliding friction (the inverse of ``surge_resistance_n`` above ``eps``)."""
    if not p.has_friction:
        return surge_n / p.xu_kgps
    return math.copysign(max(abs(surge_n) - p.friction_n, 0.0), surge_n) / p.xu_kgps


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
    # plant's RK4, the estimator's Jacobian), and a generator's set-up costs more than the indexing.
    u, v, r, psi = x[0], x[1], x[2], x[5]
    t1, t2 = thrust[0], thrust[1]
    c, s = ops.cos(psi), ops.sin(psi)
    wu, wv = world_to_body(force_ne[0], force_ne[1], c, s)
    fu, fv, fr = tau_body[0] + wu, tau_body[1] + wv, tau_body[2]
    m11, m22, m33 = p.m11_kg, p.m22_kg, p.m33_kgm2
    if p.has_friction:
        u_dot = (t1 + t2 + m22 * v * r - p.xu_kgps * u + fu - surge_friction_n(u, p, ops)) / m11
    else:  # the paper's model, the same operations as ever (the reproduction holds to the digit)
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
