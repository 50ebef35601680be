"""The mission manager: validation, the active leg, waypoint switching, completion, commands.

Pure: no clock, no bus. A mission is the ordered waypoints P_0..P_N (local NED, metres), the circle of
acceptance r_COA, the task power T^w and the controller. The vessel follows the leg P_{i-1} -> P_i;
P_i is passed when the vessel enters its circle of acceptance (paper section III), and entering the
last circle completes the mission.

The start: as QGroundControl and ArduPilot do, the vessel first goes to P_0, on the approach "leg"
from where it was first seen after the start to P_0 (``active`` = 0), then flies P_0 -> P_1 (i = 1).
A vessel first seen inside P_0's circle (the paper's runs, which start at P_0) starts at i = 1 at
once, with no switch counted, as the paper's missions start. ``MissionRequest.join_first_leg`` joins
P_0 -> P_1 from wherever the vessel is instead.

At rest: after the last waypoint, and while the operator pauses, the vessel holds station at a
``hold_point`` (the last waypoint; where it was when paused) unless the mission asked to drift
(``MissionRequest.at_rest``). A pause by the controller itself (``hold``: the vehicle withholds the
thrust, the energy budget's policy) has no hold point: zero thrust.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from seaway.contract import keys
from seaway.contract.messages import (
    MAX_REASON_CHARS,
    MAX_TASK_POWER_W,
    AtRest,
    ControllerName,
    LowEnergyPolicy,
    MissionCommand,
    MissionRequest,
    MissionState,
    Waypoint,
)
from seaway.vessel import path
from seaway.vessel.frames import GeoOrigin

from seaway_controller import controllers

Point = tuple[float, float]


class MissionError(ValueError):
    """A mission request was refused; the text names the problem."""


@dataclass(frozen=True)
class MissionLimits:
    """Operating limits a mission must respect (configurable per deployment)."""

    max_range_m: float = 5_000.0
    """Every waypoint within this distance of the local origin [m]."""
    min_leg_m: float = 0.01
    """Consecutive waypoints closer than this are a zero-length leg [m]."""
    max_waypoints: int = 1_000


@dataclass(frozen=True)
class Mission:
    """A validated mission in local NED metres."""

    mission_id: str
    waypoints_m: tuple[Point, ...]
    coa_radius_m: float
    task_power_w: float
    controller: ControllerName
    speed_hint_mps: float | None = None
    home_m: Point | None = None
    """Where a return goes (the request's home, else P_0) [m]."""
    on_low_energy: LowEnergyPolicy = "return"
    join_first_leg: bool = False
    """Join P_0 -> P_1 from where the vessel is, instead of going to P_0 first."""
    at_rest: AtRest = "hold"

    @property
    def home(self) -> Point:
        return self.home_m if self.home_m is not None else self.waypoints_m[0]


def _waypoint_ned(i: int | str, wp: object, origin: GeoOrigin | None) -> Point:
    x, y = getattr(wp, "x_m", None), getattr(wp, "y_m", None)
    lat, lon = getattr(wp, "lat_deg", None), getattr(wp, "lon_deg", None)
    has_xy = x is not None or y is not None
    has_ll = lat is not None or lon is not None
    if has_xy and has_ll:
        raise MissionError(f"waypoint {i}: give either x_m/y_m or lat_deg/lon_deg, not both")
    if has_xy:
        if x is None or y is None:
            raise MissionError(f"waypoint {i}: needs both x_m and y_m")
        return float(x), float(y)
    if has_ll:
        if lat is None or lon is None:
            raise MissionError(f"waypoint {i}: needs both lat_deg and lon_deg")
        if origin is None:
            raise MissionError(f"waypoint {i}: given in lat/lon but no navigation origin is known yet "
                               f"({keys.NAV_ORIGIN.suffix} not received); send local x_m/y_m or wait "
                               "for the origin")
        north, east, _ = origin.to_ned(math.radians(lat), math.radians(lon), origin.alt_m)
        return north, east
    raise MissionError(f"waypoint {i}: has no position (x_m/y_m or lat_deg/lon_deg)")


def home_ned(wp: Waypoint, origin: GeoOrigin | None, limits: MissionLimits = MissionLimits()
             ) -> Point:
    """A home given as a waypoint (local NED metres, or degrees through ``origin``) in local NED
    metres, within ``limits.max_range_m`` of the origin; MissionError naming what is wrong."""
    home = _waypoint_ned("home", wp, origin)
    if not all(map(math.isfinite, home)) or math.hypot(*home) > limits.max_range_m:
        raise MissionError(f"home at ({home[0]:.1f}, {home[1]:.1f}) m is outside the operating "
                           f"area (max {limits.max_range_m:.0f} m from the origin)")
    return home


def validate_mission(req: MissionRequest, origin: GeoOrigin | None,
                     limits: MissionLimits = MissionLimits()) -> Mission:
    """Check a request and convert it to local NED; raises MissionError naming the problem."""
    n = len(req.waypoints)
    if n < 2:
        raise MissionError(f"a mission needs at least 2 waypoints (P_0 and one more), got {n}")
    if n > limits.max_waypoints:
        raise MissionError(f"too many waypoints: {n} > {limits.max_waypoints}")
    try:
        controllers.get(req.controller)  # registered: shipped, or by a --controller-module
    except ValueError as err:
        raise MissionError(str(err)) from None
    if not (math.isfinite(req.coa_radius_m) and req.coa_radius_m > 0):
        raise MissionError(f"coa_radius_m must be a finite number > 0, got {req.coa_radius_m}")
    if not (math.isfinite(req.task_power_w) and 0 < req.task_power_w <= MAX_TASK_POWER_W):
        raise MissionError(f"task_power_w {req.task_power_w:g} W is outside the allowed range "
                           f"(0, {MAX_TASK_POWER_W:g}] W (seaway.contract.messages.MAX_TASK_POWER_W)")
    points = [_waypoint_ned(i, wp, origin) for i, wp in enumerate(req.waypoints)]
    for i, (x, y) in enumerate(points):
        if not (math.isfinite(x) and math.isfinite(y)):
            raise MissionError(f"waypoint {i}: not finite ({x}, {y})")
        r = math.hypot(x, y)
        if r > limits.max_range_m:
            raise MissionError(f"waypoint {i} at ({x:.1f}, {y:.1f}) m is {r:.0f} m from the origin, "
                               f"outside the operating area (max {limits.max_range_m:.0f} m)")
    for i in range(1, n):
        leg = math.dist(points[i - 1], points[i])
        if leg < limits.min_leg_m:
            raise MissionError(f"leg {i - 1}->{i} has zero length ({leg:.3g} m < "
                               f"{limits.min_leg_m} m): remove the duplicate waypoint")
    home = None if req.home is None else home_ned(req.home, origin, limits)
    return Mission(req.mission_id, tuple(points), float(req.coa_radius_m), float(req.task_power_w),
                   req.controller, req.speed_hint_mps, home, req.on_low_energy, req.join_first_leg,
                   req.at_rest)


PAUSED_PREFIX = "paused by the controller: "
"""How a pause the controller makes because the vehicle withholds the thrust begins its reason."""

class MissionManager:
    """The active mission's state machine: idle -> [waiting ->] active <-> paused -> complete | aborted.

    A mission is paused by the operator (``command``) or by the controller itself (``hold``: the
    vehicle stopped applying the thrust); either way it resumes only on the operator's request.
    A mission accepted while the vehicle cannot fly it ``wait``s, and becomes active by itself
    (``release``) once it can. ``reason`` says why it is in its state when the operator did not ask
    for it ("" otherwise). ``hold_point``: where the vessel holds station now (None: it does not).
    """

    def __init__(self, limits: MissionLimits = MissionLimits()) -> None:
        self.limits = limits
        self.mission: Mission | None = None
        self.state: MissionState = "idle"
        self.reason = ""
        self.active = 0  # index i of the active waypoint P_i (0: on the way to P_0)
        self.switches = 0  # legs changed since the mission started (warm starts re-guess on change)
        self.approach_from: Point | None = None  # where the way to P_0 starts (first seen there)
        self.position: Point | None = None  # the vessel's last position seen (update)
        self.hold_point: Point | None = None

    def start(self, req: MissionRequest, origin: GeoOrigin | None,
              position: Point | None = None) -> Mission:
        """Validate and start ``req`` (replacing any mission); raises MissionError if refused.
        ``position``: where the vessel is now (local NED, m), if known; else where it is first
        seen (``update``) decides whether it goes to P_0 first."""
        mission = validate_mission(req, origin, self.limits)
        self.mission, self.state, self.switches = mission, "active", 0
        self.active = 1 if mission.join_first_leg else 0
        self.approach_from = self.hold_point = None
        self.reason = ""
        if position is not None:
            self._first_seen(*position)
        return mission

    def _first_seen(self, x_m: float, y_m: float) -> bool:
        """On the way to P_0: the first leg once inside P_0's circle (True if so, now)."""
        assert self.mission is not None
        p0 = self.mission.waypoints_m[0]
        if math.hypot(x_m - p0[0], y_m - p0[1]) > self.mission.coa_radius_m:
            if self.approach_from is None:
                self.approach_from = (x_m, y_m)
            return False
        # In P_0's circle: its first leg. Seen there at once, it is the start the paper's runs had
        # (no switch); arrived from outside, a waypoint switch.
        self.switches += self.approach_from is not None
        self.active = 1
        return True

    def wait(self, reason: str) -> None:
        """The mission just started waits for the vehicle (``reason``: for what)."""
        if self.mission is not None and self.state in ("active", "waiting"):
            self.state, self.reason = "waiting", reason[:MAX_REASON_CHARS]

    def release(self) -> bool:
        """A waiting mission becomes active (the vehicle can fly it now); True if it was waiting."""
        if self.state != "waiting":
            return False
        self.state, self.reason = "active", ""
        return True

    def hold(self, reason: str) -> bool:
        """Pause the active mission for ``reason`` (not the operator's request); True if it was
        active. Only ``command(resume)`` makes it active again."""
        if self.mission is None or self.state != "active":
            return False
        self.state, self.reason = "paused", reason[:MAX_REASON_CHARS]
        self.hold_point = None
        return True

    def stop(self, reason: str, hold_point: Point | None) -> bool:
        """Pause a mission that has not ended (active, waiting, or paused already) for ``reason``,
        holding station at ``hold_point`` (local NED [m]; None: zero thrust); True if it had not
        ended. Unlike ``hold``, a waiting mission is paused too: it must not start by itself once
        the vehicle applies the thrust. Only ``command(resume)`` makes it active again."""
        if self.mission is None or self.state not in ("active", "waiting", "paused"):
            return False
        self.state, self.reason = "paused", reason[:MAX_REASON_CHARS]
        self.hold_point = hold_point
        return True

    def restate(self, prefix: str, reason: str) -> bool:
        """Say ``reason`` for a pause the controller made whose reason starts with ``prefix`` (its
        cause became known, or changed, after the pause began); True if the reason changed."""
        reason = reason[:MAX_REASON_CHARS]
        if self.state != "paused" or not self.reason.startswith(prefix) or self.reason == reason:
            return False
        self.reason = reason
        return True

    def drift(self, reason: str) -> None:
        """Stop holding station at rest for ``reason`` (zero thrust from now on)."""
        if self.hold_point is not None:
            self.hold_point, self.reason = None, reason[:MAX_REASON_CHARS]

    def command(self, cmd: MissionCommand) -> str:
        """Apply pause/resume/abort; returns what happened, raises MissionError if refused."""
        c = cmd.command
        if self.mission is None:
            raise MissionError(f"cannot {c}: no mission has been set")
        self._command(c)
        self.reason = ""  # the operator's doing from now on
        held = self.state == "paused" and self.mission.at_rest == "hold"
        self.hold_point = self.position if held else None
        return self.state

    def _command(self, c: str) -> None:
        if c == "pause":
            # A waiting mission is paused too: refused, it would start by itself at the arming
            # the operator wanted it paused through.
            if self.state not in ("active", "waiting"):
                raise MissionError(f"cannot pause: the mission is {self.state}, not active or "
                                   "waiting")
            self.state = "paused"
        elif c == "resume":
            if self.state != "paused":
                raise MissionError(f"cannot resume: the mission is {self.state}, not paused")
            self.state = "active"
        elif c == "abort":
            # A complete mission whose vessel holds station is aborted to stop the hold.
            holding = self.state == "complete" and self.hold_point is not None
            if self.state not in ("active", "paused", "waiting") and not holding:
                raise MissionError(f"cannot abort: the mission is already {self.state}")
            self.state = "aborted"

    def leg(self) -> tuple[Point, Point]:
        """(P_{i-1}, P_i) of the active leg."""
        if self.mission is None:
            raise MissionError("no mission")
        wps = self.mission.waypoints_m
        if self.active == 0:  # on the way to P_0; from P_0 itself until the vessel is seen
            return self.approach_from or wps[0], wps[0]
        return wps[self.active - 1], wps[self.active]

    def update(self, x_m: float, y_m: float) -> Literal["switched", "complete"] | None:
        """Switch on entering P_i's circle of acceptance; complete on the last one."""
        self.position = (x_m, y_m)
        if self.mission is None or self.state != "active":
            return None
        wps = self.mission.waypoints_m
        switched = False
        if self.active == 0:
            seen_before = self.approach_from is not None
            if not self._first_seen(x_m, y_m):
                return None
            switched = seen_before
        # Several circles may be entered at once; the last one keeps its leg active, complete.
        passed = path.advance_leg(self.active, x_m, y_m, wps, self.mission.coa_radius_m)
        if passed == self.active:
            return "switched" if switched else None
        last = len(wps) - 1
        self.switches += min(passed, last) - self.active
        self.active = min(passed, last)
        if passed > last:
            self.state = "complete"
            self.hold_point = wps[last] if self.mission.at_rest == "hold" else None
            return "complete"
        return "switched"

    def inside_any_circle(self, x_m: float, y_m: float) -> bool:
        """True inside any waypoint's circle of acceptance (cross-track samples skip these)."""
        if self.mission is None:
            return False
        return path.inside_any_circle(x_m, y_m, self.mission.waypoints_m, self.mission.coa_radius_m)
