"""Path geometry of a waypoint mission, written once: legs, cross-track error, circles of acceptance.

A mission is the ordered waypoints P_0..P_N in the world frame (local NED: x north, y east) [m]. The
vessel follows the leg P_{i-1} -> P_i (i starts at 1); P_i is passed when the vessel enters its circle
of acceptance of radius r_COA (paper section III), and entering the last circle ends the mission.
Angles are from north, clockwise [rad].

Used by the controller (its cost, status and fallback guidance), the report's metrics and the
in-process closed loop, so that all of them measure the same path the same way.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from types import ModuleType
from typing import Any

Point = tuple[float, float]


def signed_cross_track_m(x_m: Any, y_m: Any, wp_prev: Sequence[Any], wp_active: Sequence[Any],
                         ops: ModuleType = math) -> Any:
    """Signed distance of (x, y) from the line P_{i-1} -> P_i (reproduction.md item 1) [m].

    ``cross(P_i - P_{i-1}, p - P_{i-1}) / |P_i - P_{i-1}|``: positive to the right of the leg (NED,
    looking from P_{i-1} to P_i), negative to the left. ``ops`` provides ``sqrt``: ``math`` for
    numbers, ``casadi`` for the MPC's expressions (paper eq. 15, the track cost Y).
    """
    lx, ly = wp_active[0] - wp_prev[0], wp_active[1] - wp_prev[1]
    return (lx * (y_m - wp_prev[1]) - ly * (x_m - wp_prev[0])) / ops.sqrt(lx * lx + ly * ly)


def cross_track_m(x_m: float, y_m: float, wp_prev: Sequence[float], wp_active: Sequence[float]) -> float:
    """Distance of (x, y) from the line P_{i-1} -> P_i [m]: |``signed_cross_track_m``|.

    A zero-length leg has no line: the distance from its point is returned instead.
    """
    lx, ly = wp_active[0] - wp_prev[0], wp_active[1] - wp_prev[1]
    if lx * lx + ly * ly == 0.0:
        return math.hypot(x_m - wp_prev[0], y_m - wp_prev[1])
    return abs(signed_cross_track_m(x_m, y_m, wp_prev, wp_active))


def inside_any_circle(x_m: float, y_m: float, waypoints: Sequence[Sequence[float]],
                      radius_m: float) -> bool:
    """True if (x, y) is within ``radius_m`` of any waypoint (on the circle counts as inside)."""
    return any(math.hypot(x_m - wx, y_m - wy) <= radius_m for wx, wy in waypoints)


def advance_leg(active: int, x_m: float, y_m: float, waypoints: Sequence[Sequence[float]],
                radius_m: float) -> int:
    """The active waypoint index i after the vessel is seen at (x, y).

    P_i is passed on entering its circle of acceptance; a vessel may be inside several consecutive
    circles at once, so several may be passed in one call. ``len(waypoints)`` once the last circle is
    entered: the mission is complete.
    """
    while active < len(waypoints) and math.hypot(x_m - waypoints[active][0],
                                                 y_m - waypoints[active][1]) <= radius_m:
        active += 1
    return active


def los_heading_rad(x_m: float, y_m: float, wp_prev: Sequence[float], wp_active: Sequence[float],
                    lookahead_m: float) -> float:
    """Line-of-sight heading: toward the point ``lookahead_m`` ahead of the vessel's projection on
    the leg P_{i-1} -> P_i, never past P_i nor behind P_{i-1} (NED, from north, clockwise) [rad].

    Inside the leg this is the classic LOS law psi_leg - atan2(e, lookahead) with e the signed
    cross-track error (positive right), so the vessel turns back toward the line.
    """
    lx, ly = wp_active[0] - wp_prev[0], wp_active[1] - wp_prev[1]
    length = math.hypot(lx, ly)
    ux, uy = lx / length, ly / length
    along = (x_m - wp_prev[0]) * ux + (y_m - wp_prev[1]) * uy
    target = min(max(along, 0.0) + lookahead_m, length)
    ax, ay = wp_prev[0] + target * ux, wp_prev[1] + target * uy
    if math.hypot(ax - x_m, ay - y_m) < 1e-6:  # on the aim point: head for the waypoint itself
        ax, ay = wp_active[0], wp_active[1]
    return math.atan2(ay - y_m, ax - x_m)
