"""The operating area the controller enforces (``seaway.area``): before a mission and in flight.

* Before: a mission whose route, from where the vessel is to P_0 (or P_1 when it joins the first
  leg) and along every leg, leaves the keep-in area or enters a keep-out area is refused, the reply
  naming the run (``seaway.area.route``: ``leg 1->2 leaves the keep-in area at north 30.0 m, ...``).
* In flight: every period of an active mission the course the vessel is committed to is checked:
  the vessel's position, the MPC's predicted horizon x_1..x_H (the plan flown: the new one, or the
  reused one on fallback 1), and past its end the coast with zero thrust along the last predicted
  ground velocity (``coast_m``: the hull's drag alone stops it within ``m11 u / Xu``). When that
  course would leave the area, the mission stops: 'hold' station where the vessel is (the default),
  or 'return' home (``MissionRequest.on_area_breach``), the status saying why.
* The area is published (``area/active``, ``ActiveArea``) when it comes into force and once a
  second of the controller's clock after (simulated time in lockstep), so the recording holds it.

Pure: the area, the vessel, states and plans in; reasons and messages out.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from seaway.area.model import OperatingArea, check_segment, check_trajectory, margin_m
from seaway.area.route import describe, route_breaches
from seaway.contract.messages import ActiveArea, StateEstimate
from seaway.vessel.model import VesselParams

Point = tuple[float, float]

PUBLISH_EVERY_NS = 1_000_000_000
HOLD_MARGIN_M = 2.0
"""How far inside the area a hold point must lie [m]: station keeping wanders about its point (the
hold benchmark's target: 95 % of the time within 2 m), and the guard does not act while the vessel
holds, so a hold point nearer the edge is moved in (``hold_point``)."""
_HOLD_SEARCH_STEP_M = 0.25
_HOLD_SEARCH_M = 10.0
_HOLD_DIRECTIONS = 32
"""``area/active`` is published again this often [ns] (``keys.AREA_ACTIVE``: 1 Hz)."""


def coast_m(vessel: VesselParams, speed_mps: float) -> float:
    """How far the vessel coasts from ``speed_mps`` with zero thrust [m]: the linear surge drag
    ``m11 du/dt = -Xu u`` stops it within ``m11 u / Xu``."""
    return vessel.m11_kg * abs(speed_mps) / vessel.xu_kgps


class AreaGuard:
    """One vessel's operating area as the controller enforces it (see the module docstring)."""

    def __init__(self, vessel: VesselParams, area: OperatingArea | None = None,
                 source: str = "", since_ns: int | None = None) -> None:
        self.vessel = vessel
        self.area: OperatingArea | None = None
        self.source = source
        self.since_ns = since_ns
        self._pending = False
        self._sent_ns: int | None = None
        if area is not None:
            self.set_area(area, source, since_ns)

    def set_area(self, area: OperatingArea | None, source: str, since_ns: int | None = None) -> None:
        """Put ``area`` in force (None: no area) from ``since_ns`` (None: the first message's
        stamp, e.g. lockstep's first period); announced at the next chance."""
        self.area, self.source, self.since_ns = area, source, since_ns
        self._pending = area is not None
        self._sent_ns = None

    @property
    def bounding(self) -> bool:
        return self.area is not None and not self.area.empty

    def hold_point(self, point: Point) -> Point:
        """Where to hold station for ``point`` (the last waypoint, or where a pause began): the
        point itself when it lies ``HOLD_MARGIN_M`` inside the area, else the nearest point that
        does (searched on rings every 0.25 m out to 10 m, 32 directions each), else ``point``."""
        if not self.bounding or margin_m(self.area, point) >= HOLD_MARGIN_M:  # type: ignore[arg-type]
            return point
        assert self.area is not None
        steps = round(_HOLD_SEARCH_M / _HOLD_SEARCH_STEP_M)
        for k in range(1, steps + 1):
            r = k * _HOLD_SEARCH_STEP_M
            ring = [(point[0] + r * math.cos(2 * math.pi * j / _HOLD_DIRECTIONS),
                     point[1] + r * math.sin(2 * math.pi * j / _HOLD_DIRECTIONS))
                    for j in range(_HOLD_DIRECTIONS)]
            ok = [(margin_m(self.area, p), p) for p in ring]
            inside = [(m, p) for m, p in ok if m >= HOLD_MARGIN_M]
            if inside:
                return max(inside)[1]  # of the nearest ring, the one deepest inside
        return point

    # -- before a mission ------------------------------------------------------------------------

    def refusal(self, waypoints_m: Sequence[Point], position_m: Point | None,
                join_first_leg: bool, returning: bool = False) -> str | None:
        """Why the mission's route breaks the area (naming the run), or None. ``returning``: a
        return home, which may start outside the keep-in area (a vessel pushed out comes back in):
        its first run leaving the keep-in where the vessel is does not count."""
        if not self.bounding:
            return None
        assert self.area is not None
        found = route_breaches(self.area, waypoints_m, position_m, join_first_leg)
        if returning and position_m is not None:
            found = [(n, b) for n, b in found if not (
                b.kind == "leaves_keep_in" and b.at_m == tuple(position_m))]
        if not found:
            return None
        why = "; ".join(describe(n, b) for n, b in found)
        return f"its route leaves the operating area ({self.source}): {why}"

    def places(self, home: Point) -> list[tuple[str, Point]]:
        """Where a return may go: home and each rally point of the area, named."""
        rally = self.area.rally_points if self.area is not None else ()
        return [("home", home)] + [(f"rally point {r.name or i}", r.position_m)
                                   for i, r in enumerate(rally)]

    def clear_way(self, here: Point, there: Point) -> bool:
        """True if the straight way from ``here`` to ``there`` stays in the area."""
        if not self.bounding:
            return True
        assert self.area is not None
        return not check_segment(self.area, here, there)

    def return_target(self, here: Point, home: Point,
                      cost: Callable[[Point], float] | None = None) -> Point | None:
        """The nearest of home and the rally points whose straight way from ``here`` stays in the
        area, or None. Nearest by ``cost`` (e.g. the energy budget's energy to get there [J]; a
        place it prices infinite, not reached), else by distance."""
        def key(place: Point) -> float:
            return cost(place) if cost is not None else math.dist(here, place)

        costed = [(key(p), p) for _, p in self.places(home) if self.clear_way(here, p)]
        costed = [(c, p) for c, p in costed if math.isfinite(c)]
        return min(costed)[1] if costed else None

    def home_refusal(self, home: Point) -> str | None:
        """Why ``home`` is not a place in the area (a return there would leave it), or None."""
        if not self.bounding:
            return None
        assert self.area is not None
        why = self.area.why_not_allowed(home)
        return None if why is None else (f"home at north {home[0]:.1f} m, east {home[1]:.1f} m is "
                                         f"{why} ({self.source}); home must be in the area")

    # -- in flight -------------------------------------------------------------------------------

    def course(self, state: StateEstimate, plan_states: np.ndarray | None) -> list[Point]:
        """The course the vessel is committed to (local NED, m): where it is, the predicted
        horizon (rows x_1..x_H of ``plan_states``: u, v, r, x, y, psi), then the coast from its
        last state along its ground velocity."""
        pts: list[Point] = [(state.x_m, state.y_m)]
        last = (state.u_mps, state.v_mps, state.x_m, state.y_m, state.psi_rad)
        if plan_states is not None and len(plan_states) > 1 and np.all(np.isfinite(plan_states)):
            pts += [(float(r[3]), float(r[4])) for r in plan_states[1:]]
            r = plan_states[-1]
            last = (float(r[0]), float(r[1]), float(r[3]), float(r[4]), float(r[5]))
        u, v, x, y, psi = last
        speed = math.hypot(u, v)
        if speed > 0.0:
            c, s = math.cos(psi), math.sin(psi)
            vn, ve = (c * u - s * v) / speed, (s * u + c * v) / speed
            d = coast_m(self.vessel, speed)
            pts.append((x + d * vn, y + d * ve))
        return pts

    def breach(self, state: StateEstimate, plan_states: np.ndarray | None,
               position_only: bool = False) -> str | None:
        """Why the committed course (``course``) would leave the area, or None. ``position_only``:
        the vessel's position alone (a return from the edge: the vessel turns back from a course
        that pointed out, and its route back was checked clear)."""
        if not self.bounding:
            return None
        assert self.area is not None
        pts = [(state.x_m, state.y_m)] if position_only else self.course(state, plan_states)
        first = check_trajectory(self.area, pts).first
        if first is None:
            return None
        verb = ("leaves the keep-in area" if first.kind == "leaves_keep_in"
                else f"enters keep-out area {first.zone}")
        return (f"the vessel's predicted course (the MPC's horizon and its coast) {verb} "
                f"({self.source}) at north {first.at_m[0]:.1f} m, east {first.at_m[1]:.1f} m")

    # -- the message -----------------------------------------------------------------------------

    def message(self, stamp_ns: int) -> ActiveArea | None:
        """The area in force stamped ``stamp_ns``, if it came into force since the last one or was
        last sent ``PUBLISH_EVERY_NS`` ago (or the clock went back); else None."""
        if self.area is None:
            return None
        last = self._sent_ns
        if not self._pending and last is not None and 0 <= stamp_ns - last < PUBLISH_EVERY_NS:
            return None
        self._pending, self._sent_ns = False, stamp_ns
        if self.since_ns is None or self.since_ns > stamp_ns:
            self.since_ns = stamp_ns
        return ActiveArea.of_area(self.area, stamp_ns=stamp_ns, since_ns=self.since_ns,
                                  source=self.source[:200])
