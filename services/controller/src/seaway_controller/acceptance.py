"""Whether a mission can be flown at all, said before it starts (``ControllerCore.handle_mission``).

An economic controller (CC-EMPC, EO-EMPC) cruises at u*, where the surge power equals the task
power T^w (``costs.cruise_speed_mps``): a small T^w on a large vessel is a slow cruise with little
thrust (paper condition #1's 0.49 W on the lake boat: 0.045 m/s on 1.5 N). A cruise whose thrust a
side is inside the thrusters' dead zone (the vessel file's ``dead_zone_n``: the lake boat's 10 N)
cannot be flown: they would not turn. A disturbance that
thrust cannot beat leaves the vessel no way on some courses: the energy budget prices that leg, or
the way home, as infinite, and its policy turns the mission into a return home at once, a return
that cannot be made either. So a mission is refused when, under the disturbance estimated now (a
world-frame force, ``energy.Disturbance``, as far as the estimate is sure of it:
``confident_disturbance``), the cruise would make good less than ``MIN_SPEED_FRAC`` of u* along one
of its legs or on the way home from where the vessel is or from any waypoint, with the figures that
say why. The NMPC has no economic cruise (it holds no speed of its own): it is not judged here.

Pure: the energy model, a state and the mission's geometry in, a reason or None out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from seaway.contract.messages import StateEstimate
from seaway.vessel import model as vessel_model

from seaway_controller.energy import ZERO, Disturbance, EnergyModel

MIN_SPEED_FRAC = 0.25
"""A course on which the cruise under the estimated disturbance makes good less than this fraction
of u* is not flyable: at a quarter of its speed a vessel is at the mercy of the disturbance's
changes (a gust of a fifth more takes its way; the budget's own bound of no way is 5 %)."""

CONFIDENCE_SIGMAS = 2.0
"""The disturbance judged is the estimate shrunk toward zero by this many of its standard
deviations along its own direction (``confident_disturbance``): an estimate just started, or just
re-opened, is mostly uncertainty (seen on PX4's firmware: 140 N at rest a second after boot, and a
mission refused for it), while a settled one is judged as it is."""

Point = tuple[float, float]


def confident_disturbance(state: StateEstimate) -> Disturbance:
    """The disturbance of ``state`` that its estimate is sure of: the surge/sway force shrunk toward
    zero by ``CONFIDENCE_SIGMAS`` standard deviations along its direction (the whole estimate
    without a covariance); the yaw moment as estimated."""
    surge, sway, yaw = state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm
    magnitude = math.hypot(surge, sway)
    if state.covariance is None or magnitude == 0.0:
        return Disturbance.from_body((surge, sway, yaw), state.psi_rad)
    cov = np.asarray(state.covariance, dtype=float).reshape(9, 9)[6:8, 6:8]
    along = np.array([surge, sway]) / magnitude
    sigma = math.sqrt(max(float(along @ cov @ along), 0.0))
    keep = max(0.0, 1.0 - CONFIDENCE_SIGMAS * sigma / magnitude)
    return Disturbance.from_body((keep * surge, keep * sway, yaw), state.psi_rad)


def runs_of(waypoints: Sequence[Point], home: Point, start: Point | None,
            join_first_leg: bool = True, coa_radius_m: float = 0.0) -> list[tuple[str, Point, Point]]:
    """(name, from, to) of every straight run the mission may fly: the way from ``start`` to P_0
    when it goes there first and starts outside its circle (``coa_radius_m``), its legs (the first
    from ``start`` when given and joined from there), and home from ``start`` and from each
    waypoint after P_0."""
    runs = []
    first = waypoints[0]
    if start is not None and join_first_leg:
        first = start
    elif start is not None and math.dist(start, waypoints[0]) > coa_radius_m:
        runs.append(("the way to P_0 from where the vessel is", start, waypoints[0]))
    runs.append(("leg 0->1", first, waypoints[1]))
    runs += [(f"leg {i - 1}->{i}", waypoints[i - 1], waypoints[i]) for i in range(2, len(waypoints))]
    if start is not None:
        runs.append(("the way home from where the vessel is", start, home))
    runs += [(f"the way home from P_{i}", waypoints[i], home) for i in range(1, len(waypoints))]
    return [r for r in runs if math.dist(r[1], r[2]) > 0.0]


def why_not_flyable(model: EnergyModel, state: StateEstimate | None, waypoints: Sequence[Point],
                    home: Point, join_first_leg: bool = False) -> str | None:
    """Why the mission cannot be flown (the first run it cannot make good), or None if it can."""
    if not model.economic:
        return None
    u_star = model.cruise_speed_mps
    vessel = model.vessel
    thrust_n = vessel_model.sliding_resistance_n(u_star, vessel)
    dead_zone_n = vessel.dead_zone_n
    if thrust_n / 2.0 < dead_zone_n:
        # The cruise's thrust Xu u* + F_c = sqrt(2 T^w / alpha + F_c^2) + F_c (costs.cruise_speed_mps).
        fc = vessel.friction_n
        least_w = vessel.alpha_w_per_n2 / 2.0 * ((2.0 * dead_zone_n - fc) ** 2 - fc * fc)
        return (f"its economic cruise at T^w {model.task_power_w:g} W is {u_star:.3g} m/s on "
                f"{thrust_n / 2.0:.2g} N a side, inside the thrusters' {dead_zone_n:g} N dead zone "
                f"(the vessel file's): they would not turn; a task power of {math.ceil(least_w)} W or more "
                "cruises outside it")
    dist = confident_disturbance(state) if state is not None else ZERO
    start = (state.x_m, state.y_m) if state is not None else None
    runs = runs_of(waypoints, home, start, join_first_leg, model.coa_radius_m)
    if not runs:
        return None
    courses = np.array([math.atan2(b[1] - a[1], b[0] - a[0]) for _, a, b in runs])
    ground = model.cruise_many(courses, u_star, [dist])[0][0]
    slow = np.flatnonzero(~(ground >= MIN_SPEED_FRAC * u_star))
    if slow.size == 0:
        return None
    k = int(slow[0])
    force_n = math.hypot(*dist.force_ne)
    return (f"{runs[k][0]} cannot be made good: the economic cruise at T^w {model.task_power_w:g} W "
            f"is {u_star:.3g} m/s on {thrust_n:.3g} N of thrust, and the disturbance estimated now "
            f"({force_n:.2g} N) leaves it {max(float(ground[k]), 0.0):.2g} m/s on that course (under "
            f"{MIN_SPEED_FRAC:.0%} of the cruise); a larger task power (a faster cruise) or a calmer "
            "day")
