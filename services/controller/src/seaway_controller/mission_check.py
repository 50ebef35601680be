"""The check before a mission, one implementation: the controller on acceptance, ``seaway mission
check``, ``seaway launch --check`` and the ground station's API all ask this.

For a mission request it gives the figures an operator decides on and a verdict:

* the path: its length (from the vessel to P_0 when the vessel's position is known, then every leg)
  [m] and the predicted time at the controller's cruise [s];
* the energy (the energy budget's own model, ``energy.predict``: the controller's cost at its
  economic cruise, under the current disturbance estimate when a live state is given, else calm):
  to fly the mission, to get home from the last waypoint, the battery now and after the mission,
  the reserve [J];
* the operating area's verdict (``seaway.area.route``, naming the run at fault) and home in it;
* bounds that depend on the mission: the circle of acceptance against the legs (a circle as wide
  as half a leg switches on entering two circles at once; one holding the vessel's start completes
  at once), and whether the controller can fly it at all (``acceptance``).

Refused when any bound or the area is broken, or when the mission and the way home from its last
waypoint need more than the battery less its reserve, unless the request is forced
(``MissionRequest.force``: the operator's explicit choice, recorded). Pure: the request, the
vessel and what is known of the vessel now in; a ``MissionCheck`` out.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

from seaway.area.model import OperatingArea
from seaway.area.route import mission_runs, route_verdict
from seaway.contract.messages import MissionRequest, StateEstimate
from seaway.vessel.energy_prediction import known_poor
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.model import VesselParams

from seaway_controller import acceptance, controllers
from seaway_controller.energy import ZERO, Disturbance, EnergyModel, finite_or_none, predict
from seaway_controller.mission import MissionError, MissionLimits, validate_mission

Point = tuple[float, float]
COA_LEG_FRAC = 0.5
"""The circle of acceptance must be under this fraction of the shortest leg: wider, two circles
overlap and the vessel switches past a waypoint it never neared."""


@dataclass
class MissionCheck:
    """The check's figures (None: not known) and its verdict; ``to_dict`` is the ``--json`` form."""

    verdict: Literal["ok", "refused"] = "ok"
    reasons: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    mission_id: str = ""
    path_length_m: float | None = None
    predicted_time_s: float | None = None
    cruise_speed_mps: float | None = None
    energy_mission_j: float | None = None
    energy_home_from_last_j: float | None = None
    battery_j: float | None = None
    reserve_j: float | None = None
    battery_after_j: float | None = None
    area: str = "none"
    """'ok', 'refused' (the reason is among ``reasons``) or 'none' (no area)."""
    forced: bool = False
    live: bool = False
    """Checked against a running vessel's state (position, disturbance estimate)."""

    def refuse(self, why: str) -> None:
        self.verdict = "refused"
        self.reasons.append(why)

    def to_dict(self) -> dict[str, Any]:
        return {k: (None if isinstance(v, float) and not math.isfinite(v) else v)
                for k, v in asdict(self).items()}


def check_mission(req: MissionRequest, vessel: VesselParams, *, origin: GeoOrigin | None = None,
                  state: StateEstimate | None = None, battery_j: float | None = None,
                  reserve_j: float | None = None, area: OperatingArea | None = None,
                  home: Point | None = None, limits: MissionLimits | None = None,
                  profile_n: float = 2.0) -> MissionCheck:
    """Check ``req`` for ``vessel`` (see the module docstring). ``state``: the vessel's live
    state (None: at the desk, the vessel taken at rest at P_0); ``battery_j``: usable energy left
    (None: not known, no energy verdict); ``home``: the vessel's home when the request gives none
    (default P_0)."""
    out = MissionCheck(mission_id=req.mission_id, forced=req.force, live=state is not None)
    try:
        mission = validate_mission(req, origin, limits or MissionLimits())
    except MissionError as err:
        out.refuse(str(err))
        return out
    wps = mission.waypoints_m
    here = (state.x_m, state.y_m) if state is not None else None
    home = mission.home_m or home or wps[0]
    runs = mission_runs(wps, here, mission.join_first_leg)
    out.path_length_m = sum(math.dist(a, b) for _, a, b in runs)

    # Bounds that depend on the mission.
    legs = [math.dist(wps[i - 1], wps[i]) for i in range(1, len(wps))]
    shortest = min(legs)
    if mission.coa_radius_m >= COA_LEG_FRAC * shortest:
        k = legs.index(shortest) + 1
        out.refuse(f"coa_radius_m {mission.coa_radius_m:g} m is not under {COA_LEG_FRAC:g} of the "
                   f"shortest leg ({k - 1}->{k}, {shortest:.3g} m): the circles of acceptance "
                   f"overlap and waypoints are passed without being neared; give coa_radius_m "
                   f"< {COA_LEG_FRAC * shortest:.3g} m")
    if here is not None and not mission.join_first_leg and math.dist(here, wps[-1]) <= \
            mission.coa_radius_m and len(wps) == 2:
        out.refuse(f"the vessel is already within coa_radius_m {mission.coa_radius_m:g} m of the "
                   "last waypoint: the mission would complete at once")

    # The operating area.
    if area is not None and not area.empty:
        why = route_verdict(area, wps, here, mission.join_first_leg)
        home_why = area.why_not_allowed(home)
        if home_why is not None:
            why = "; ".join(w for w in (why, f"home at north {home[0]:.1f} m, east {home[1]:.1f} m "
                                             f"is {home_why}") if w)
        out.area = "ok" if why is None else "refused"
        if why is not None:
            out.refuse(f"the route leaves the operating area: {why}")

    # Can it be flown, and the energy.
    economic = controllers.get(mission.controller).economic  # the registered definition says
    model = EnergyModel(vessel, mission.task_power_w, mission.coa_radius_m, economic,
                        req.predict_disturbance, profile_n)
    flyable = acceptance.why_not_flyable(model, state, wps, home, mission.join_first_leg)
    if flyable is not None:
        out.refuse(f"cannot be flown: {flyable}")
    start = state if state is not None else _at_rest(wps[0], wps[1])
    dist = (Disturbance.from_body((state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm),
                                  state.psi_rad) if state is not None else ZERO)
    active = 1 if mission.join_first_leg or state is None else 0
    if (poor := known_poor(mission.controller)) is not None:
        out.notes.append(poor)  # its energy figures are not to be read as more than they are
    out.cruise_speed_mps = model.speed_mps(state)
    if out.cruise_speed_mps > 0:
        out.predicted_time_s = out.path_length_m / out.cruise_speed_mps
    out.energy_mission_j = finite_or_none(predict(model, start, wps, active, home, None, dist).to_go_j)
    last = _at_rest(wps[-1], (2 * wps[-1][0] - wps[-2][0], 2 * wps[-1][1] - wps[-2][1]))
    out.energy_home_from_last_j = (0.0 if math.dist(wps[-1], home) <= mission.coa_radius_m else
                                   finite_or_none(predict(model, last, [home, home], 0, home, None,
                                                   dist).to_home_j))
    out.battery_j = battery_j
    out.reserve_j = reserve_j if reserve_j is not None else (
        vessel.battery.reserve_energy_j if vessel.battery is not None else None)
    if battery_j is not None:
        need = (out.energy_mission_j if out.energy_mission_j is not None else math.inf) + (
            out.energy_home_from_last_j if out.energy_home_from_last_j is not None else math.inf)
        if out.energy_mission_j is not None:
            out.battery_after_j = battery_j - out.energy_mission_j
        above = battery_j - (out.reserve_j or 0.0)
        if need > above:
            why = (f"the mission ({_j(out.energy_mission_j)}) and the way home from its last "
                   f"waypoint ({_j(out.energy_home_from_last_j)}) need more than the battery's "
                   f"{battery_j:.0f} J less its {out.reserve_j or 0.0:.0f} J reserve "
                   f"({above:.0f} J)")
            if req.force:
                out.notes.append(f"forced: {why}")
            else:
                out.refuse(why + "; send it with force to fly it anyway")
    else:
        out.notes.append("battery not known: no energy verdict")
    return out


def _at_rest(p: Point, toward: Point) -> StateEstimate:
    """A vessel at rest at ``p`` with its bow toward ``toward`` (the desk's start)."""
    psi = math.atan2(toward[1] - p[1], toward[0] - p[0])
    return StateEstimate.make(stamp_ns=0, u_mps=0.0, v_mps=0.0, r_radps=0.0, x_m=p[0], y_m=p[1],
                              psi_rad=psi)


def _j(v: float | None) -> str:
    return "no way at the cruise" if v is None else f"{v:.0f} J"
