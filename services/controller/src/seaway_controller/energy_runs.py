"""The energy of the runs the energy budget (``seaway_controller.energy``) prices a path with: a
steady straight run along a course under a disturbance, and a turn by a change of course. Pure.

Energies count what the paper's energy counts (eq. 3): alpha (T1^2 + T2^2) plus the task power T^w,
over time [J]. Speeds [m/s], forces [N], moments [N m], angles from north [rad].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from seaway.vessel.model import VesselParams, sliding_resistance_n

from seaway_controller import costs

TURN_TABLE_POINTS = 91
"""Turn angles [0, pi] at which the turn's extra energy is tabulated (2 deg apart), interpolated."""


# -- the cruise ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Cruise:
    """A steady straight run along a course [m/s, W, N]."""

    ground_speed_mps: float
    power_w: float
    thrust_port_n: float
    thrust_starboard_n: float

    @property
    def j_per_m(self) -> float:
        """Energy per metre made good [J/m]; inf when the vessel makes no way."""
        return self.power_w / self.ground_speed_mps if self.ground_speed_mps > 0 else math.inf


def cruise(vessel: VesselParams, task_power_w: float, speed_mps: float, course_rad: float,
           force_ne: tuple[float, float] = (0.0, 0.0), yaw_nm: float = 0.0,
           pay_in_thrust: bool = True) -> Cruise:
    """The steady run along ``course_rad`` at model surge speed ``speed_mps`` under a world-frame
    force ``force_ne`` [N north, N east] and a yaw moment ``yaw_nm`` [N m] (module docstring;
    ``cruise_courses`` for many at once, which this is one of)."""
    g, pw, t1, t2 = cruise_courses(vessel, task_power_w, speed_mps, course_rad, force_ne[0],
                                   force_ne[1], yaw_nm, pay_in_thrust)
    return Cruise(float(g), float(pw), float(t1), float(t2))


def cruise_courses(vessel: VesselParams, task_power_w: float, speed_mps: float,
                   courses_rad: np.ndarray | float, force_n: np.ndarray | float = 0.0,
                   force_e: np.ndarray | float = 0.0, yaw_nm: np.ndarray | float = 0.0,
                   pay_in_thrust: bool = True
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Steady runs at model surge speed ``speed_mps``: (ground speeds [m/s], powers [W], port and
    starboard thrusts [N]), broadcast over the courses [rad] and the world-frame disturbances
    (force north and east [N], yaw moment [N m]) (module docstring).

    ``pay_in_thrust``: the controller knows the force and holds its speed with thrust; else it
    keeps the thrust of the undisturbed cruise and the speed changes. Thrusts are bounded by the
    vessel's limits (a cruise beyond them is flown at the bound, and the speed follows).

    Arrays because the budget prices its legs under seven disturbances and ~50 runs home a period:
    one at a time, that cost more than the MPC's solve."""
    p = vessel
    # Not broadcast up front: every operation below is elementwise and broadcasts by itself (the
    # same floats), and the crab angle has the whole shape from the first iteration on. Clips are
    # written as maximum then minimum, which is what np.clip computes, at half its call's cost.
    courses, fn, fe, yaw = (np.asarray(a, dtype=float) for a in
                            (courses_rad, force_n, force_e, yaw_nm))
    shape = np.broadcast(courses, fn, fe, yaw).shape
    lo, hi = -2 * p.reverse_max_n, 2 * p.thrust_max_n
    resistance_n = sliding_resistance_n(speed_mps, p)
    friction, xu, yv = p.has_friction, p.xu_kgps, p.yv_kgps
    t_sum = None if pay_in_thrust else np.full(shape, min(max(resistance_n, lo), hi))
    beta = np.zeros(shape)  # crab angle: heading - course
    for _ in range(6):  # the crab angle and the forces it sees agree within 1e-6 rad in 3
        psi = courses + beta
        c, s = np.cos(psi), np.sin(psi)
        f_u = c * fn + s * fe
        if pay_in_thrust:
            t_sum = np.minimum(np.maximum(resistance_n - f_u, lo), hi)
        if friction:  # the speed the surge force slides at (model.steady_surge_speed_mps)
            net = t_sum + f_u
            u = np.sign(net) * np.maximum(np.abs(net) - p.friction_n, 0.0) / xu
        else:
            u = (t_sum + f_u) / xu
        v = (c * fe - s * fn) / yv
        before, beta = beta, np.where(u > 0, -np.arctan2(v, u), 0.0)
        # Every element on until the last agrees: one that agreed earlier only moves closer to
        # its fixed point (within 1e-9 rad of where cruise stops), and the arrays stay whole.
        if np.maximum.reduce(np.abs(beta - before), axis=None, initial=0.0) < 1e-9:  # = .max()
            break
    t_diff = ((p.m22_kg - p.m11_kg) * u * v - yaw) / p.arm_m
    t_lo, t_hi = -p.reverse_max_n, p.thrust_max_n
    t1 = np.minimum(np.maximum((t_sum + t_diff) / 2.0, t_lo), t_hi)
    t2 = np.minimum(np.maximum((t_sum - t_diff) / 2.0, t_lo), t_hi)
    ground = np.where(u > 0, np.hypot(u, v), 0.0)
    power = p.alpha_w_per_n2 * (t1 * t1 + t2 * t2) + task_power_w
    return ground, power, t1, t2


def _per_m(ground_mps: np.ndarray, power_w: np.ndarray) -> np.ndarray:
    """``Cruise.j_per_m`` of arrays [J/m]: inf where the vessel makes no way."""
    moving = ground_mps > 0
    return np.where(moving, power_w / np.where(moving, ground_mps, 1.0), np.inf)


NR_TURNING_FLOOR_FRAC = 0.1
"""The yaw damping a turn sees is kept at least this fraction of Nr: a vessel whose Munk moment
outweighs its damping at the cruise is directionally unstable there, and its turns are not the
steady ones ``turning_vessel`` prices."""


def turning_vessel(vessel: VesselParams, speed_mps: float) -> VesselParams:
    """The vessel as a steady turn at surge speed ``speed_mps`` [m/s] sees it: the yaw damping Nr
    less the Munk moment of the sway the turn makes.

    In a steady turn at rate r the sway settles at v = -m11 u r / Yv (the model's sway equation,
    ``seaway.vessel.model``), and the moment -(m22 - m11) u v it makes is proportional to r: the
    yaw equation's damping becomes Nr - (m22 - m11) m11 u^2 / Yv [kg m^2/s]. A vessel longer in
    sway than surge (m22 > m11) turns more easily at speed than Nr alone says, one with m22 < m11
    less (the sway settles within m22 / Yv, a fraction of a second on the vessels here)."""
    p = vessel
    coupling = (p.m22_kg - p.m11_kg) * p.m11_kg * speed_mps * speed_mps / p.yv_kgps
    nr = max(p.nr_kgm2ps - coupling, NR_TURNING_FLOOR_FRAC * p.nr_kgm2ps)
    return p.model_copy(update={"nr_kgm2ps": nr})


def _turn_extra_j(vessel: VesselParams, task_power_w: float, speed_mps: float,
                  delta_psi: np.ndarray, n: float, t_d_min_s: float, t_d_max_s: float) -> np.ndarray:
    """Extra energy of turning by each of ``delta_psi`` [rad] on the way: the least E_d + E_s over
    t_d (paper eq. 15, t_s from the terminal constraint) minus the straight run E_s would be alone
    [J]. All angles at once: one array evaluation per step of the search, not one per angle (the
    NMPC's table is made again at each pricing, since its speed changes, and 91 searches one angle
    at a time would take a large part of a control period, on the control loop, every period near
    the return decision)."""
    psi = np.asarray(delta_psi, dtype=float)
    p_static = costs.surge_power_w(speed_mps, vessel) + task_power_w
    sinc = costs.smooth_sinc(psi, np)

    def extra(t_d: np.ndarray) -> np.ndarray:
        p_dyn = costs.dynamic_power_w(speed_mps, 0.0, psi, t_d, task_power_w, n, vessel)
        return t_d * (p_dyn - p_static * sinc)

    # Golden-section search on [t_d_min, t_d_max] for each angle (extra(t_d) is unimodal: a
    # turning cost falling as 1/t_d against a straight-line cost growing with t_d).
    a, b = np.full(psi.shape, t_d_min_s), np.full(psi.shape, t_d_max_s)
    g = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = extra(c), extra(d)
    for _ in range(60):
        left = fc < fd  # the minimum is in [a, d]: d becomes the upper end, c the new d
        a, b = np.where(left, a, c), np.where(left, d, b)
        x = np.where(left, b - g * (b - a), a + g * (b - a))
        fx = extra(x)
        c, d, fc, fd = (np.where(left, x, d), np.where(left, c, x), np.where(left, fx, fd),
                        np.where(left, fc, fx))
    return np.maximum(0.0, np.minimum(fc, fd))


@lru_cache(maxsize=64)
def _turn_table(vessel: VesselParams, task_power_w: float, speed_mps: float, n: float,
                t_d_min_s: float, t_d_max_s: float) -> tuple[float, ...]:
    """``_turn_extra_j`` at ``TURN_TABLE_POINTS`` angles evenly over [0, pi] [J], with the yaw
    moment of the ``turning_vessel``."""
    angles = np.linspace(0.0, math.pi, TURN_TABLE_POINTS)
    turning = turning_vessel(vessel, speed_mps)
    return tuple(float(j) for j in _turn_extra_j(turning, task_power_w, speed_mps, angles, n,
                                                 t_d_min_s, t_d_max_s))
