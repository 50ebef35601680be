"""When the launcher ends a run: a mission status that says "over", bounded and borne out.

The controller's identity may publish ``mission/status`` and ``mission/energy`` (the access rules
allow no one else), but a compromised or confused process of that identity can still say
"complete" at the start of a mission. So the launcher takes a status as the end of a mission only
when:

* its stamp is within the bounds every service applies (``seaway.runtime.stamps``): in real time at
  most ``MAX_AHEAD_LIVE_S`` ahead of the launcher's wall clock and at most ``MAX_AGE_S`` behind it;
  in lockstep at most ``LOCKSTEP_AHEAD_PERIODS`` periods ahead of the newest navigation state heard
  and at most ``MAX_AGE_S`` of simulated time behind it (the status of a period comes from that
  period's state); the same bounds hold for the energy budget that holds a mission;
* and, for a mission this launcher sent, the vessel was seen where the status says it is: the
  navigation state (``nav/state``, the estimator's: an identity the controller's cannot publish as)
  put it within the circle of acceptance (plus ``ARRIVAL_SLACK_M``) of the last waypoint for
  "complete", or of home for the completed return home (``return_mission_id``), at some look since
  the mission was sent. Where a point is also where the vessel starts (home, a loop's end), being
  there at the start is no arrival: the vessel must be seen leaving it first, except for the return
  home while the newest look puts the vessel at home (a return decided before the vessel left home
  is complete where it stands; a status saying so elsewhere is still refused). A "hold" decided by
  the energy budget needs no position.

A status that fails is not taken: counted and logged (at most once a minute per reason), and the
run goes on. A run with ``--max-mission-s`` also ends when every vessel's mission has had that long
(``timed_out``): in lockstep by the states' simulated time, which the sim's clock holds at the
limit, in real time by the wall clock since the launcher's first look.

``VesselEnd`` is the pure judgement (messages and times in); ``MissionEnd`` reads the launcher's bus
for every vessel. ``MissionsTaken`` says which vessels' controllers took a mission.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

from seaway.contract import keys
from seaway.contract.messages import (
    EnergyBudget,
    MissionAccepted,
    MissionRequest,
    MissionStatus,
    NavOrigin,
    StateEstimate,
    Waypoint,
    mission_over,
    return_mission_id,
)
from seaway.contract.units import NS_PER_S
from seaway.runtime.bus import Bus
from seaway.runtime.bus_typed import Every, Newest
from seaway.runtime.lockstep_clock import last_period_ns
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import StampBounds, StampGate
from seaway.vessel.frames import GeoOrigin

log = logging.getLogger("seaway.launch")

MAX_AGE_S = 5.0
"""How old a status, budget or state may be to end a mission [s]: the controller publishes its
status every control period (0.1 s), so a status this old is not the current one."""
ARRIVAL_SLACK_M = 3.0
"""Added to the circle of acceptance when judging where the vessel was [m]: the launcher looks at
the newest state a few times a second, and a vessel that just completed may have coasted on past
the circle since (at 2 m/s, about 1 m in a look's 0.5 s). Far below any leg a forger could hide in:
a status is refused while the vessel is more than this outside the circle."""
REFUSED_LOG_EVERY_S = 60.0
"""A refused "over" status is logged once, then at most once a minute per reason."""

Point = tuple[float, float]


def _ned(wp: Waypoint, origin: GeoOrigin | None) -> Point | None:
    """A waypoint in local NED metres; None if given in degrees and no origin is known yet."""
    if wp.x_m is not None and wp.y_m is not None:
        return float(wp.x_m), float(wp.y_m)
    if wp.lat_deg is None or wp.lon_deg is None or origin is None:
        return None
    north, east, _ = origin.to_ned(math.radians(wp.lat_deg), math.radians(wp.lon_deg), origin.alt_m)
    return north, east


@dataclass
class VesselEnd:
    """Whether one vessel's mission is over, judged from bounded, consistent messages.

    ``mission``: the mission the launcher sent (None: it sent none; any mission's bounded
    "complete" ends the run, as no waypoint is known to check it against). ``period_ns``: the
    lockstep control period (None: real time)."""

    vessel: str
    mission: MissionRequest | None
    period_ns: int | None = None
    origin: GeoOrigin | None = None
    reached: dict[str, bool] = field(default_factory=dict)
    """'end' (the last waypoint), 'home' -> the vessel was seen arriving within its circle (plus
    slack): inside it, and, for a point within that reach of the first waypoint (home, a loop's
    end), outside it before (where the vessel starts is no arrival)."""
    left: dict[str, bool] = field(default_factory=dict)
    """'end', 'home' -> the vessel was seen outside its circle (plus slack)."""
    rally: tuple[Point, ...] = ()
    """The operating area's rally points (the run's scenario's ``[area]``): the energy budget's
    return goes to the nearest of home and these, so arriving at any of them ends it."""
    at_home: bool = False
    """The newest admitted look put the vessel within home's circle (plus slack)."""
    refused: dict[str, int] = field(default_factory=dict)
    """Reason -> how many "over" statuses were not taken for it."""
    first_ref_ns: int | None = None
    """The reference time (``reference_ns``) at the first look that had one [ns]."""
    last_ref_ns: int | None = None
    """The newest reference time looked at [ns]."""
    gate: StampGate = field(init=False)
    _log: RateLimitedLog = field(init=False)

    def __post_init__(self) -> None:
        self.gate = StampGate(f"launcher ({self.vessel})", log)
        self._log = RateLimitedLog(log, REFUSED_LOG_EVERY_S)

    def bounds(self) -> StampBounds:
        if self.period_ns is None:
            return StampBounds.live(behind_s=MAX_AGE_S)
        return StampBounds(StampBounds.lockstep(self.period_ns).ahead_ns, round(MAX_AGE_S * NS_PER_S))

    def reference_ns(self, wall_ns: int, state: StateEstimate | None) -> int | None:
        """The time stamps are judged against: the wall clock, in lockstep the newest state's."""
        if self.period_ns is None:
            return wall_ns
        return None if state is None else state.stamp_ns

    def note_time(self, ref_ns: int | None) -> None:
        """A look's reference time (``reference_ns``), for how long the mission has run."""
        if ref_ns is None:
            return
        if self.first_ref_ns is None:
            self.first_ref_ns = ref_ns
        if self.period_ns is not None or self.last_ref_ns is None:
            self.last_ref_ns = ref_ns  # lockstep: the newest state's time, even back at a restart
        else:
            self.last_ref_ns = max(self.last_ref_ns, ref_ns)

    def elapsed_s(self) -> float | None:
        """How long the mission has run [s]: in lockstep the newest state's simulated time (the
        clock holds at t_0 until there is a mission to fly, ``seaway.runtime.lockstep``), in real
        time the wall clock since the first look; None before any look had a reference time."""
        if self.first_ref_ns is None or self.last_ref_ns is None:
            return None
        if self.period_ns is not None:
            return self.last_ref_ns / NS_PER_S
        return (self.last_ref_ns - self.first_ref_ns) / NS_PER_S

    def timed_out(self, max_s: float) -> bool:
        """Whether the mission has had its ``max_s`` [s]: in lockstep, reached the last period a
        clock limited to it flies to (``last_period_ns``, where the sim's clock holds); in real
        time, ``max_s`` of the wall clock."""
        elapsed = self.elapsed_s()
        if elapsed is None or self.last_ref_ns is None:
            return False
        if self.period_ns is not None:
            return self.last_ref_ns >= last_period_ns(max_s, self.period_ns)
        return elapsed >= max_s

    def targets(self) -> tuple[Point | None, Point | None]:
        """(last waypoint, home) of the mission sent, in NED metres (None where not known)."""
        if self.mission is None or not self.mission.waypoints:
            return None, None
        wps = self.mission.waypoints
        return _ned(wps[-1], self.origin), _ned(self.mission.home or wps[0], self.origin)

    def on_origin(self, origin: NavOrigin | None) -> None:
        if origin is not None:
            self.origin = GeoOrigin(origin.lat_rad, origin.lon_rad, origin.alt_m)

    def on_state(self, state: StateEstimate | None, ref_ns: int | None) -> None:
        """A look at the newest state: note whether it puts the vessel at the end or at home."""
        if state is None or self.mission is None:
            return
        if self.period_ns is None and not self.gate.admit(
            keys.NAV_STATE.suffix, state.stamp_ns, ref_ns, self.bounds()
        ):
            return
        reach = self.mission.coa_radius_m + ARRIVAL_SLACK_M
        first = _ned(self.mission.waypoints[0], self.origin)
        here = (state.x_m, state.y_m)
        for name, point in zip(("end", "home"), self.targets(), strict=True):
            if point is None:
                continue
            places = [point, *self.rally] if name == "home" else [point]
            near = [p for p in places if math.dist(here, p) <= reach]
            inside = bool(near)
            if name == "home":
                self.at_home = inside
            if not inside:
                self.left[name] = True
            elif self.left.get(name) or (first is not None and all(math.dist(first, p) > reach
                                                                    for p in near)):
                self.reached[name] = True

    def over(self, status: MissionStatus | None, budget: EnergyBudget | None, ref_ns: int | None) -> bool:
        """Whether ``status`` (the newest) ends the mission sent: see the module docstring."""
        sent = None if self.mission is None else self.mission.mission_id
        if not mission_over(status, budget, sent):
            return False
        assert status is not None
        if not self.gate.admit(keys.MISSION_STATUS.suffix, status.stamp_ns, ref_ns, self.bounds()):
            return self._refuse("stamp", "its stamp is out of bounds")
        if status.state != "complete":  # held by the energy budget: its budget must be current too
            assert budget is not None
            if not self.gate.admit(keys.MISSION_ENERGY.suffix, budget.stamp_ns, ref_ns, self.bounds()):
                return self._refuse("stamp", "its energy budget's stamp is out of bounds")
            return True
        if sent is None:
            return True
        end, home = self.targets()
        home_run = status.mission_id == return_mission_id(sent) != sent
        name, target = ("home", home) if home_run else ("end", end)
        # The return home is over wherever the vessel is now at home, also if it never left (the
        # budget decided the return at the start); a loop's end needs the seen arrival.
        if self.reached.get(name) or (home_run and self.at_home):
            return True
        where = "home" if home_run else "the last waypoint"
        if target is None:
            return self._refuse("origin", f"{where} is in degrees and no {keys.NAV_ORIGIN.suffix} was heard")
        reach = self.mission.coa_radius_m + ARRIVAL_SLACK_M  # type: ignore[union-attr]
        return self._refuse(
            "position",
            f"no navigation state has shown the vessel arriving within "
            f"{reach:g} m of {where} ({target[0]:.1f}, {target[1]:.1f}) m",
        )

    def _refuse(self, reason: str, why: str) -> bool:
        self.refused[reason] = n = self.refused.get(reason, 0) + 1
        self._log.warning(
            (self.vessel, reason),
            "launcher (%s): a mission status says the mission "
            "is over, not taken: %s. Not taken so far for this reason: %d (logged at "
            "most once a minute)",
            self.vessel,
            why,
            n,
        )
        return False


class MissionEnd:
    """Every vessel's ``VesselEnd``, fed from the launcher's bus (newest samples, read when asked:
    in lockstep they come hundreds a second)."""

    def __init__(
        self, vessels: list[str], mission: MissionRequest | None, period_ns: int | None = None,
        rally: tuple[Point, ...] = (),
    ) -> None:
        self.vessels = {v: VesselEnd(v, mission, period_ns, rally=rally) for v in vessels}
        self.ended = False
        """``over`` has said so: the missions ended (a profile that runs on after them)."""
        self._newest: dict[
            str, tuple[Newest[MissionStatus], Newest[EnergyBudget], Newest[StateEstimate], Newest[NavOrigin]]
        ] = {}

    def watch(self, bus: Bus) -> None:
        for v in self.vessels:
            self._newest[v] = (
                bus.newest(keys.MISSION_STATUS, vessel=v),
                bus.newest(keys.MISSION_ENERGY, vessel=v),
                bus.newest(keys.NAV_STATE, vessel=v),
                bus.newest(keys.NAV_ORIGIN, vessel=v),
            )

    def over(self, wall_ns: int) -> bool:
        """Whether every vessel's mission is over (``wall_ns``: the wall clock, ``time.time_ns``).
        Call it a few times a second: each call is also a look at where the vessels are."""
        done = True
        for v, end in self.vessels.items():
            status, budget, state, origin = (n.get() for n in self._newest[v])
            end.on_origin(origin)  # type: ignore[arg-type]
            ref = end.reference_ns(wall_ns, state)  # type: ignore[arg-type]
            end.note_time(ref)
            end.on_state(state, ref)  # type: ignore[arg-type]
            done = end.over(status, budget, ref) and done  # type: ignore[arg-type]
        self.ended = self.ended or done
        return done

    def timed_out(self, max_s: float) -> float | None:
        """Once every vessel's mission has had its ``max_s`` [s] (``VesselEnd.timed_out``, from
        the looks ``over`` took) without ending, the least time any has run [s]; else None (also
        once they ended: a profile that runs on after a mission is not held to its time)."""
        ends = list(self.vessels.values())
        if self.ended or not ends or not all(end.timed_out(max_s) for end in ends):
            return None
        return min(end.elapsed_s() or 0.0 for end in ends)


ACCEPTED_BUNDLES = 1024
"""Controller bundles held between two looks for ``mission/accepted``: five seconds of lockstep at
200 periods a second, for a launcher that looks every 0.2 s."""


class MissionsTaken:
    """Which vessels' controllers have taken a mission in this run (the launcher's or another's):
    a vessel whose controller took none gets no report.

    Read when asked (``look``, from the launcher's loop), from every ``mission/accepted`` since
    the last look (``Every``: the transport holds the bytes, no Python runs per sample). Not a
    callback: in lockstep the key comes in the controller's bundles, hundreds a second, and a
    callback would hand each bundle to a Python thread to find the one key in it. Not the newest
    only: lockstep sends the acceptance in one period's bundle, and a launcher slowed by a busy
    machine looked after more bundles than ``Newest`` keeps had come (the vessel then got no
    report)."""

    def __init__(self, vessels: list[str]) -> None:
        self.vessels = list(vessels)
        self.taken: set[str] = set()
        self._accepted: dict[str, Every[MissionAccepted]] = {}

    def watch(self, bus: Bus) -> None:
        self._accepted = {v: Every(bus, keys.MISSION_ACCEPTED, bus.key(keys.MISSION_ACCEPTED, v),
                                   capacity=ACCEPTED_BUNDLES) for v in self.vessels}

    def look(self) -> set[str]:
        """The vessels whose controller has accepted a mission, at this look or an earlier one."""
        for v, accepted in self._accepted.items():
            if accepted.take() and v not in self.taken:
                self.taken.add(v)
        return self.taken
