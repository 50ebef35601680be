"""A mission's route against an operating area: each straight run named as the controller and the
mission check name it, and the verdict that names the first run at fault.

The runs, in the order the vessel flies them (local NED metres):

* ``the way from the vessel to P_0``: from where the vessel is to the first waypoint (the default
  start, as QGroundControl and ArduPilot fly it); with ``join_first_leg`` the vessel joins the first
  leg from where it is instead, so the run is ``the way from the vessel to P_1``;
* ``leg i-1->i``: from P_{i-1} to P_i.

Without a position (a plan checked at the desk) the way from the vessel is left out and P_0 itself
must be allowed. Pure.
"""

from __future__ import annotations

from collections.abc import Sequence

from seaway.area.model import Breach, OperatingArea, Point, check_point, check_segment


def mission_runs(waypoints_m: Sequence[Point], position_m: Point | None = None,
                 join_first_leg: bool = False) -> list[tuple[str, Point, Point]]:
    """(name, from, to) of each straight run of the mission, in flight order (see the module)."""
    runs: list[tuple[str, Point, Point]] = []
    if position_m is not None and waypoints_m:
        target = 1 if join_first_leg and len(waypoints_m) > 1 else 0
        runs.append((f"the way from the vessel to P_{target}", position_m, waypoints_m[target]))
    runs += [(f"leg {i - 1}->{i}", waypoints_m[i - 1], waypoints_m[i])
             for i in range(1, len(waypoints_m))]
    return runs


def route_breaches(area: OperatingArea, waypoints_m: Sequence[Point],
                   position_m: Point | None = None, join_first_leg: bool = False
                   ) -> list[tuple[str, Breach]]:
    """Every (run name, breach) of the mission's route, in flight order (empty: it stays in)."""
    found: list[tuple[str, Breach]] = []
    if position_m is None and waypoints_m:
        lone = check_point(area, waypoints_m[0])
        if lone is not None:
            found.append(("P_0", lone))
    for k, (name, a, b) in enumerate(mission_runs(waypoints_m, position_m, join_first_leg)):
        found += [(name, br) for br in check_segment(area, a, b, k)]
    return found


def describe(name: str, breach: Breach) -> str:
    """One breach for a person: ``leg 1->2 leaves the keep-in area at north 30.0 m, east 0.0 m``."""
    verb = ("leaves the keep-in area" if breach.kind == "leaves_keep_in"
            else f"enters keep-out area {breach.zone}")
    if name == "P_0":
        verb = breach.what().replace("outside", "is outside").replace("inside", "is inside")
    return f"{name} {verb} at north {breach.at_m[0]:.1f} m, east {breach.at_m[1]:.1f} m"


def route_verdict(area: OperatingArea | None, waypoints_m: Sequence[Point],
                  position_m: Point | None = None, join_first_leg: bool = False) -> str | None:
    """Why the mission's route breaks ``area`` (each breach, the first run at fault first), or
    None if it stays in it (or there is no area)."""
    if area is None or area.empty:
        return None
    found = route_breaches(area, waypoints_m, position_m, join_first_leg)
    if not found:
        return None
    return "; ".join(describe(n, b) for n, b in found)
