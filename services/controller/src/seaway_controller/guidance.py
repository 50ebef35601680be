"""Line-of-sight guidance: the fallback when the MPC cannot be trusted (fallback level 2).

Deliberately simple and model-based, so that it needs no solver: steer toward a point ``lookahead_m``
ahead of the vessel's projection on the active leg P_{i-1} -> P_i (never past P_i), at a modest speed.

Yaw: m33 rdot + Nr r = N (paper eq. 1 without the small Coriolis term), so the moment
``N = m33 (w^2 e_psi - 2 w r) + Nr r`` gives a critically damped heading loop of bandwidth w [rad/s].
Surge: ``X = Xu u_ref + m11 k_u (u_ref - u)``: the drag at the reference speed plus a proportional
correction. The speed reference shrinks with the heading error so that the vessel turns first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from seaway.vessel.frames import wrap_pi
from seaway.vessel.model import VesselParams, thrusts_for_wrench


@dataclass(frozen=True)
class LosGains:
    lookahead_m: float = 2.0
    speed_mps: float = 0.2
    heading_bandwidth_radps: float = 1.0
    speed_gain_per_s: float = 1.0


def los_heading_rad(x_m: float, y_m: float, wp_prev: tuple[float, float],
                    wp_active: tuple[float, float], lookahead_m: float) -> float:
    """Desired heading toward the look-ahead point on the leg (NED, from north, clockwise) [rad]."""
    lx, ly = wp_active[0] - wp_prev[0], wp_active[1] - wp_prev[1]
    length = math.hypot(lx, ly)
    ux, uy = lx / length, ly / length
    along = (x_m - wp_prev[0]) * ux + (y_m - wp_prev[1]) * uy
    target = min(max(along, 0.0) + lookahead_m, length)
    ax, ay = wp_prev[0] + target * ux, wp_prev[1] + target * uy
    if math.hypot(ax - x_m, ay - y_m) < 1e-6:  # on the aim point: head for the waypoint itself
        ax, ay = wp_active
    return math.atan2(ay - y_m, ax - x_m)


def los_thrust(state: tuple[float, ...], wp_prev: tuple[float, float],
               wp_active: tuple[float, float], p: VesselParams, gains: LosGains = LosGains(),
               speed_mps: float | None = None) -> tuple[float, float]:
    """(T1 port, T2 starboard) [N] steering ``state`` = (u, v, r, x, y, psi) along the leg."""
    u, _, r, x, y, psi = state[:6]
    psi_d = los_heading_rad(x, y, wp_prev, wp_active, gains.lookahead_m)
    e_psi = wrap_pi(psi_d - psi)
    w = gains.heading_bandwidth_radps
    yaw_nm = p.m33_kgm2 * (w * w * e_psi - 2.0 * w * r) + p.nr_kgm2ps * r
    yaw_max = 0.8 * 2.0 * p.arm_m * min(p.thrust_max_n, p.reverse_max_n)  # keep room for surge
    yaw_nm = min(max(yaw_nm, -yaw_max), yaw_max)
    u_ref = (speed_mps or gains.speed_mps) * max(0.0, math.cos(e_psi))
    surge_n = p.xu_kgps * u_ref + p.m11_kg * gains.speed_gain_per_s * (u_ref - u)
    t1, t2 = thrusts_for_wrench(surge_n, yaw_nm, p)
    lo, hi = -p.reverse_max_n, p.thrust_max_n
    return min(max(t1, lo), hi), min(max(t2, lo), hi)
