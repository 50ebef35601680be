"""Station keeping: the law that holds the vessel at a point against current and wind.

Used after the last waypoint and while the operator pauses a mission (``MissionRequest.at_rest``
``hold``, the default; ``drift`` gives zero thrust instead). Pure: a state, the hold point and the
estimated disturbance in, two thrusts out.

A twin-thruster hull has no sway force: it can push only along its bow (surge, both ways) and turn.
So the law asks for a world-frame force and turns the bow along it (weathervaning into the
disturbance, the attitude that needs the least force and so the least energy):

* ``F = -F_d + k_p e - k_d v``: the estimator's disturbance ``tau_d`` turned into the world frame
  (``energy.Disturbance``: it lumps wind, current and model error, so it is also the law's integral
  action), a spring on the position error ``e = p_hold - p`` and a damper on the ground velocity;
* heading: the bow toward ``F`` through the line-of-sight guidance's critically damped heading
  loop (``m33 rdot + Nr r = N``); the turn is scaled down while ``|F|`` is small, so that on a calm
  day at the point the vessel does not spin after the direction of a vanishing force;
* surge: the projection of ``F`` on the bow (negative: astern), so that it pushes while it turns.

The gains come from the vessel (``HoldGains``): the spring gives a position loop of time constant
``time_constant_s`` against the hull's surge drag, the damper brings it to critical.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from seaway.vessel.frames import wrap_pi
from seaway.vessel.model import VesselParams, thrusts_for_wrench
from seaway.vessel.thrusters import saturate

from seaway_controller.energy import Disturbance


@dataclass(frozen=True)
class HoldGains:
    time_constant_s: float = 4.0
    """Time constant of the position loop [s]."""
    heading_bandwidth_radps: float = 1.0
    """w of the critically damped heading loop [rad/s] (the LOS guidance's)."""
    full_turn_force_n: float = 0.5
    """Below this world force the heading loop is scaled down in proportion [N]."""


def hold_thrust(state: Sequence[float], hold_point: Sequence[float], tau_d: Sequence[float],
                p: VesselParams, gains: HoldGains = HoldGains()) -> tuple[float, float]:
    """(T1 port, T2 starboard) [N] holding ``state`` = (u, v, r, x, y, psi) (body speeds m/s and
    rad/s, local NED m and rad) at ``hold_point`` (local NED, m), with the estimated disturbance
    ``tau_d`` = (surge N, sway N, yaw N m) in the body frame (zeros: none known)."""
    u, v, r, x, y, psi = state[:6]
    c, s = math.cos(psi), math.sin(psi)
    d = Disturbance.from_body(tau_d, psi)
    tau = gains.time_constant_s
    # A mass-spring-damper per axis: drag/tau + mass/tau^2 for the spring, critical damping on
    # what the hull's own drag does not already give.
    k_p = p.xu_kgps / tau + p.m11_kg / tau**2
    k_d = max(0.0, 2.0 * math.sqrt(k_p * p.m11_kg) - p.xu_kgps)
    vn, ve = c * u - s * v, s * u + c * v
    fn = -d.force_ne[0] + k_p * (hold_point[0] - x) - k_d * vn
    fe = -d.force_ne[1] + k_p * (hold_point[1] - y) - k_d * ve
    force = math.hypot(fn, fe)
    surge_n = fn * c + fe * s
    w = gains.heading_bandwidth_radps
    e_psi = wrap_pi(math.atan2(fe, fn) - psi) if force > 0 else 0.0
    scale = min(1.0, force / gains.full_turn_force_n)
    yaw_nm = scale * p.m33_kgm2 * (w * w * e_psi - 2.0 * w * r) + p.nr_kgm2ps * r - d.yaw_nm
    yaw_max = 0.8 * 2.0 * p.arm_m * min(p.thrust_max_n, p.reverse_max_n)  # keep room for surge
    yaw_nm = min(max(yaw_nm, -yaw_max), yaw_max)
    t1, t2 = thrusts_for_wrench(surge_n, yaw_nm, p)
    return saturate(t1, p), saturate(t2, p)
