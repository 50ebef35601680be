"""Line-of-sight guidance: thrusts that steer the vessel along a leg without any solver.

The controller's fallback when the MPC cannot be trusted (fallback level 2) and the steering of the
estimator's benchmark (``seaway_lab.closed_loop``): one law, model-based and deliberately simple.
It steers toward ``seaway.vessel.path.los_heading_rad``'s look-ahead point on the leg
P_{i-1} -> P_i at a modest speed.

Yaw: m33 rdot + Nr r = N (paper eq. 1 without the small Coriolis term), so the moment
``N = m33 (w^2 e_psi - 2 w r) + Nr r`` gives a critically damped heading loop of bandwidth w [rad/s].
Surge: ``X = Xu u_ref + m11 k_u (u_ref - u)``: the drag at the reference speed plus a proportional
correction. The speed reference shrinks with the heading error so that the vessel turns first.
Both thrusts are saturated (``seaway.vessel.thrusters``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from seaway.vessel.frames import wrap_pi
from seaway.vessel.model import VesselParams, surge_resistance_n, thrusts_for_wrench
from seaway.vessel.path import los_heading_rad
from seaway.vessel.thrusters import saturate


@dataclass(frozen=True)
class LosGains:
    lookahead_m: float = 2.0
    """Look-ahead distance along the leg [m]."""
    speed_mps: float = 0.2
    """Reference speed through the water [m/s] (before the heading-error reduction)."""
    heading_bandwidth_radps: float = 1.0
    """w of the critically damped heading loop [rad/s]."""
    speed_gain_per_s: float = 1.0
    """k_u of the surge correction [1/s]."""


def los_thrust(state: Sequence[float], wp_prev: Sequence[float], wp_active: Sequence[float],
               p: VesselParams, gains: LosGains = LosGains(),
               speed_mps: float | None = None) -> tuple[float, float]:
    """(T1 port, T2 starboard) [N] steering ``state`` = (u, v, r, x, y, psi) along the leg.

    ``speed_mps`` (e.g. a mission's speed hint) replaces ``gains.speed_mps`` when given.
    """
    u, _, r, x, y, psi = state[:6]
    psi_d = los_heading_rad(x, y, wp_prev, wp_active, gains.lookahead_m)
    e_psi = wrap_pi(psi_d - psi)
    w = gains.heading_bandwidth_radps
    yaw_nm = p.m33_kgm2 * (w * w * e_psi - 2.0 * w * r) + p.nr_kgm2ps * r
    yaw_max = 0.8 * 2.0 * p.arm_m * min(p.thrust_max_n, p.reverse_max_n)  # keep room for surge
    yaw_nm = min(max(yaw_nm, -yaw_max), yaw_max)
    u_ref = (speed_mps or gains.speed_mps) * max(0.0, math.cos(e_psi))
    surge_n = surge_resistance_n(u_ref, p) + p.m11_kg * gains.speed_gain_per_s * (u_ref - u)
    t1, t2 = thrusts_for_wrench(surge_n, yaw_nm, p)
    return saturate(t1, p), saturate(t2, p)
