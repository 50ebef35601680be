"""The controller core's requests: missions, home, mission commands, a checkpoint's restore.

A mission is validated (``seaway_controller.mission``), judged flyable from the latest state under
the disturbance estimated now (``acceptance``), checked against the operating area and the battery
(``mission_check``) and started, replacing the current one; or refused with the reason, nothing
changed (not even the home a mission without one would have taken). A mission accepted before any
state estimate has the way from the vessel to its route checked at the first state
(``route_seen``). A home the mission under way cannot reach on the battery left is refused
(``core_energy._home_shortfall``), and so is the resume of a mission its energy budget held while
the battery is still short (``core_energy._budget_resume``).

The mission accepted (``accepted_due``, ``take_accepted``): every accepted mission becomes a
``MissionAccepted`` (its waypoints in local NED, its controller's settings) for ``mission/accepted``,
so that a recording holds the path actually flown. Lockstep takes it once, into the answer of the
period that follows the acceptance; real time sends it at once and again every
``ACCEPTED_REPUBLISH_NS``, for a recorder or ground station that joins late.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

from seaway.contract.messages import (
    HomeRequest,
    MissionAccepted,
    MissionCommand,
    MissionRequest,
    Reply,
    StateEstimate,
    VehicleStatus,
    Waypoint,
)
from seaway.vessel.frames import GeoOrigin

from seaway_controller import motion
from seaway_controller.area_guard import AreaGuard
from seaway_controller.budget import Budget
from seaway_controller.core_energy import BudgetDecision
from seaway_controller.core_vehicle import latched_reason, waiting_for
from seaway_controller.mission import Mission, MissionError, MissionManager, home_ned, validate_mission
from seaway_controller.mission_check import MissionCheck, check_mission
from seaway_controller.mpc import MpcController

if TYPE_CHECKING:
    from seaway.vessel.model import VesselParams

    from seaway_controller.config import ControllerConfig
    from seaway_controller.ocp import ControllerKind

log = logging.getLogger("seaway_controller.core")

ACCEPTED_REPUBLISH_NS = 1_000_000_000
"""Real time: the current mission's ``MissionAccepted`` is sent again this often [ns], so that a
recorder or ground station that joins late learns it within a second."""


class MissionRequests:
    """The requests part of ``ControllerCore``: owns the mission request, home and the mission as
    accepted."""

    # read from the other parts
    vessel: VesselParams
    config: ControllerConfig
    missions: MissionManager
    origin: GeoOrigin | None
    area: AreaGuard
    vehicle: VehicleStatus | None
    budget: Budget | None
    battery_at_start_j: float | None
    energy_used_j: float
    _last_state: StateEstimate | None
    _area_return: bool
    controller: Callable[[ControllerKind], MpcController]
    withheld_reason: Callable[[], str | None]
    battery_remaining_j: Callable[[], float | None]
    _reserve_j: Callable[[], float | None]
    _not_flyable: Callable[[Mission, MissionRequest], str | None]
    _new_flight: Callable[[Mission], None]
    _new_budget: Callable[[Mission, bool], Budget]
    _shortfall: Callable[[], str]
    _home_shortfall: Callable[[tuple[float, float]], str | None]
    _area_stop: Callable[[int, StateEstimate, str], None]
    _budget_resume: Callable[[], str | None]
    _rearm_budget: Callable[[], None]

    def _init_requests(self) -> None:
        self.mission_request: MissionRequest | None = None
        self._mission_start_ns = 0
        self.accepted: MissionAccepted | None = None  # the current mission, as accepted
        self._accepted_pending = False  # accepted since it was last taken or sent
        self._accepted_sent_ns: int | None = None  # real time: when it was last sent
        # Home, explicit: the operator's (a request's ``home``), else where the vessel was when
        # armed (vehicle_io) or, with no vehicle (lockstep), when the first mission was accepted.
        self.home: tuple[float, float] | None = None
        # The current mission was accepted before any state estimate: the way from the vessel to
        # its route is checked against the operating area at the first state (``route_seen``).
        self._route_unseen = False

    def handle_mission(self, now_ns: int, req: MissionRequest, returning: bool = False,
                       check: bool = True) -> Reply:
        """Validate and start a mission (replacing the current one), or refuse with a reason.
        ``returning``: the return home the energy budget decided (``_return_home``). ``check``: a
        new mission that cannot be flown under the disturbance estimated now is refused
        (``acceptance``); a mission resumed or restarted is not judged again."""
        st = self._last_state
        req, adopt_home = self._with_home(req, st)
        try:
            candidate = validate_mission(req, self.origin, self.missions.limits)
        except MissionError as err:
            return Reply.refuse(now_ns, str(err))
        if check and not returning:
            why = self._not_flyable(candidate, req)
            if why is not None:
                log.warning("mission %r refused: %s", req.mission_id, why)
                return Reply.refuse(now_ns, f"mission {req.mission_id!r} cannot be flown: {why}")
        if check:  # the route against the operating area, from where the vessel is
            why = self.area.refusal(candidate.waypoints_m, (st.x_m, st.y_m) if st else None,
                                    candidate.join_first_leg, returning)
            why = why or self.area.home_refusal(candidate.home)
            if why is None and not returning:  # the check before a mission (mission_check.py)
                verdict = self.check(req)
                why = "; ".join(verdict.reasons) if verdict.verdict == "refused" else None
            if why is not None:
                log.warning("mission %r refused: %s", req.mission_id, why)
                return Reply.refuse(now_ns, f"mission {req.mission_id!r} refused: {why}")
        if adopt_home is not None:  # accepted: where the vessel is becomes its home (not before)
            self.home = adopt_home
        self._route_unseen = check and not returning and st is None
        mission = self.missions.start(req, self.origin, (st.x_m, st.y_m) if st is not None else None)
        self._new_flight(mission)
        self.mission_request = req
        self._area_return = False
        previous = self.budget
        self.budget = self._new_budget(mission, returning)
        if returning and previous is not None:  # the decision stays with the flight
            self.budget.decision, self.budget.decided_ns = previous.decision, previous.decided_ns
            self.budget.reason = previous.reason
        self._mission_start_ns = now_ns
        self.accepted = self._accepted_message(now_ns, mission)
        self._accepted_pending = True
        withheld = self.withheld_reason()
        if withheld is not None:
            self.missions.wait(waiting_for(withheld))
        state = self.missions.state
        log.info("mission %r accepted (%s): %d waypoints, r_COA %.2f m, T^w %.2f W, %s, %s",
                 mission.mission_id, state, len(mission.waypoints_m), mission.coa_radius_m,
                 mission.task_power_w, mission.controller,
                 "predicting the estimated tau_d" if self.predict_disturbance else "tau_d = 0")
        said = "mission started" if state == "active" else f"mission accepted, {self.missions.reason}"
        return Reply.accept(now_ns, said + self._shortfall(), mission_id=mission.mission_id,
                            waypoints_m=[list(p) for p in mission.waypoints_m],
                            controller=mission.controller,
                            predict_disturbance=self.predict_disturbance, state=state)

    def route_seen(self, now_ns: int, state: StateEstimate) -> None:
        """The first state after a mission accepted before any: the way from where the vessel is
        to its route, which the check at acceptance could not see, is checked against the
        operating area now, as a request sent now would be. Breaking it, the mission does not fly
        it: an active one stops as at the area's edge (``_area_stop``: its ``on_area_breach``,
        hold station here or return), a waiting or paused one is paused holding station here
        (so it does not start by itself), the status saying why."""
        if not self._route_unseen:
            return
        self._route_unseen = False
        mm = self.missions
        if mm.mission is None or mm.state not in ("active", "waiting", "paused"):
            return
        here = (state.x_m, state.y_m)
        why = self.area.refusal(mm.mission.waypoints_m, here, mm.mission.join_first_leg)
        if why is None:
            return
        why = (f"mission {mm.mission.mission_id!r} was accepted before any state estimate, and "
               f"from where the vessel was first seen {why}")
        if mm.state == "active":
            self._area_stop(now_ns, state, why)  # says so in the log
        else:
            log.warning("%s: held", why)
            mm.stop(f"held: {why}; send a mission whose route stays in the area from here, or "
                    "abort it", here)

    def check(self, req: MissionRequest) -> MissionCheck:
        """``mission_check.check_mission`` of ``req`` against this vessel now: its latest state,
        the battery left and its reserve, the area in force, its home."""
        battery_j = self.battery_remaining_j()
        if battery_j is None:  # no report heard yet (a batch run's first period): the run's start
            battery_j = self.battery_at_start_j
        return check_mission(req, self.vessel, origin=self.origin, state=self._last_state,
                             battery_j=battery_j, reserve_j=self._reserve_j(),
                             area=self.area.area, home=self.home, limits=self.missions.limits,
                             profile_n=self.config.profile_n)

    def _with_home(self, req: MissionRequest, st: StateEstimate | None
                   ) -> tuple[MissionRequest, tuple[float, float] | None]:
        """``req`` with its home explicit: its own, else the vessel's (``self.home``), else where
        the vessel is now, else P_0 (nothing known yet); and the vessel's home to adopt if the
        mission is accepted (where it is now, when it had none; local NED [m]), else None.

        Adopted only on acceptance: a refused request changes nothing. Taken at once, a request
        refused while the vessel was outside the area left home there, and every later mission
        without a home of its own was refused for it."""
        if req.home is not None:
            return req, None
        home = adopt = None
        if self.home is not None:
            home = self.home
        elif st is not None:
            home = adopt = (st.x_m, st.y_m)
        if home is None:
            return req, None
        return req.model_copy(update={"home": Waypoint(x_m=home[0], y_m=home[1])}), adopt

    @property
    def predict_disturbance(self) -> bool:
        """Whether the current mission predicts with the estimate's tau_d: its request asks for it
        (``MissionRequest.predict_disturbance``), or the process flag makes every mission do so."""
        req = self.mission_request
        return self.config.predict_disturbance or (req is not None and req.predict_disturbance)

    def progress(self) -> tuple[MissionRequest, int, str, float] | None:
        """(request, active leg, state, energy used [J]) of the current mission, or None."""
        mm = self.missions
        if self.mission_request is None or mm.mission is None:
            return None
        return self.mission_request, mm.active, mm.state, self.energy_used_j

    def restore(self, now_ns: int, req: MissionRequest, active_leg: int, state: str,
                energy_used_j: float, decision: BudgetDecision | None = None,
                hold_point: tuple[float, float] | None = None) -> Reply:
        """Resume a checkpointed mission at ``active_leg`` (after a restart), or refuse; with
        the energy budget's ``decision`` as it was (a return home goes on as one: its own policy
        is only 'warn', and a fresh budget would have said 'LOW ENERGY (policy: warn)'), and, at
        rest (paused or complete), station kept at ``hold_point`` (local NED [m]) as before."""
        decision = decision or BudgetDecision()
        # The leg is checked before the mission is taken: refused after, it left the mission set
        # with the state 'idle', which no checkpoint can hold (each save then raised, and a real
        # time step with it: a restart loop on the same file).
        try:
            candidate = validate_mission(req, self.origin, self.missions.limits)
        except MissionError as err:
            return Reply.refuse(now_ns, f"checkpoint's mission: {err}")
        first = 1 if candidate.join_first_leg else 0  # 0: it was on its way to P_0
        if not first <= active_leg < len(candidate.waypoints_m):
            return Reply.refuse(now_ns, f"checkpoint's active leg {active_leg} is not a leg of the "
                                        f"mission ({len(candidate.waypoints_m)} waypoints: legs "
                                        f"{first} to {len(candidate.waypoints_m) - 1})")
        reply = self.handle_mission(now_ns, req, returning=decision.returning, check=False)
        if not reply.accepted:
            return reply
        if self.budget is not None:
            b = self.budget
            b.decision, b.decided_ns, b.reason = decision.decision, decision.decided_ns, decision.reason
        mm = self.missions
        mm.active, mm.state = active_leg, state  # type: ignore[assignment]
        if state in ("paused", "complete"):
            mm.hold_point = hold_point
        if state == "waiting" and not mm.reason:
            mm.wait(waiting_for("no status heard since the restart yet"))
        mm.switches += 1  # the warm start re-guesses t_d and t_s as on a waypoint switch
        self.energy_used_j = energy_used_j
        if self.accepted is not None:  # the same flight going on, not a new one (the report)
            self.accepted = self.accepted.model_copy(update={"resumed": True})
        return Reply.accept(now_ns, f"mission resumed at leg {active_leg} ({state})")

    def _accepted_message(self, now_ns: int, mission: Mission) -> MissionAccepted:
        """``mission`` as accepted: its NED waypoints and the settings its controller flies it with."""
        req = self.mission_request
        spec = self.controller(mission.controller).spec
        settings = {"horizon_steps": float(spec.horizon), "dt_s": spec.dt_s,
                    "profile_n": spec.profile_n, "u_min_mps": spec.u_min_mps}
        if spec.is_empc:  # the decision time t_d's bounds (paper eq. 15)
            settings |= {"t_d_min_s": spec.t_d_min_s, "t_d_max_s": spec.t_d_max_s}
        else:  # the position-tracking NMPC: its cost's weights
            w = spec.nmpc
            settings |= {"q_position_per_m2": w.q_position_per_m2, "q_heading": w.q_heading,
                         "r_thrust_per_n2": w.r_thrust_per_n2}
        return MissionAccepted.make(
            stamp_ns=now_ns, accepted_ns=now_ns, mission_id=mission.mission_id,
            waypoints=[Waypoint(x_m=x, y_m=y) for x, y in mission.waypoints_m],
            coa_radius_m=mission.coa_radius_m, task_power_w=mission.task_power_w,
            controller=mission.controller, predict_disturbance=self.predict_disturbance,
            speed_hint_mps=mission.speed_hint_mps, controller_settings=settings,
            on_low_energy=mission.on_low_energy, home_x_m=mission.home[0],
            home_y_m=mission.home[1], join_first_leg=mission.join_first_leg,
            at_rest=mission.at_rest, on_area_breach=req.on_area_breach if req else "hold",
            forced=bool(req and req.force))

    def take_accepted(self, stamp_ns: int) -> MissionAccepted | None:
        """Lockstep: the mission accepted since the last call, stamped ``stamp_ns`` (the period
        whose answer carries it), once; else None. Its ``accepted_ns`` is that period too: a
        mission accepted before the first period (the scenario's, at start) was accepted on the
        wall clock, which is not the run's clock in lockstep."""
        if not self._accepted_pending or self.accepted is None:
            return None
        self._accepted_pending = False
        self.accepted = self.accepted.model_copy(update={"stamp_ns": stamp_ns, "accepted_ns": stamp_ns})
        return self.accepted

    def accepted_due(self, now_ns: int) -> MissionAccepted | None:
        """Real time: the current mission's ``MissionAccepted`` stamped ``now_ns`` if it was just
        accepted or last sent ``ACCEPTED_REPUBLISH_NS`` ago (or the clock went back), else None."""
        if self.accepted is None:
            return None
        last = self._accepted_sent_ns
        if not self._accepted_pending and last is not None and 0 <= now_ns - last < ACCEPTED_REPUBLISH_NS:
            return None
        self._accepted_pending, self._accepted_sent_ns = False, now_ns
        return self.accepted.model_copy(update={"stamp_ns": now_ns})

    def handle_home(self, now_ns: int, req: HomeRequest) -> Reply:
        """The operator sets the vessel's home (``mission/home``): a point, or where the vessel is
        now. It must lie in the operating area. The mission under way (not a return already flying
        home; a complete one still holding station too) takes it as its home: its energy budget
        prices the way there from now on. Refused, nothing changed, when that budget would act on
        it at once (``_home_shortfall``: the battery does not reach it)."""
        if req.home == "here":
            st = self._last_state
            if st is None:
                return Reply.refuse(now_ns, "home 'here' is not known: no state estimate yet; give "
                                    "a position (x_m/y_m or lat_deg/lon_deg)")
            try:  # the same bound as a home given by its position
                point = home_ned(Waypoint(x_m=st.x_m, y_m=st.y_m), self.origin, self.missions.limits)
            except MissionError as err:
                return Reply.refuse(now_ns, f"home 'here': {err}")
        else:
            try:
                point = home_ned(req.home, self.origin, self.missions.limits)
            except MissionError as err:
                return Reply.refuse(now_ns, str(err))
        why = self.area.home_refusal(point)
        if why is not None:
            return Reply.refuse(now_ns, why)
        mm = self.missions
        mission, req_now, b = mm.mission, self.mission_request, self.budget
        returning = (b is not None and b.returning) or self._area_return
        # A complete mission still holding station keeps its budget priced (its policy may fly
        # home from the hold), so it takes the new home as one under way does.
        under_way = mm.state in ("waiting", "active", "paused") or (
            mm.state == "complete" and mm.hold_point is not None)
        takes = mission is not None and req_now is not None and under_way and not returning
        short = self._home_shortfall(point) if takes else None
        if short is not None:
            return Reply.refuse(now_ns, f"home at north {point[0]:.1f} m, east {point[1]:.1f} m "
                                f"refused: {short}")
        self.home = point
        said = f"home set at north {point[0]:.1f} m, east {point[1]:.1f} m"
        if takes:
            assert mission is not None and req_now is not None
            self.missions.mission = replace(mission, home_m=point)
            self.mission_request = req_now.model_copy(
                update={"home": Waypoint(x_m=point[0], y_m=point[1])})
            if b is not None:
                b.home = point
            if self.accepted is not None:
                self.accepted = self.accepted.model_copy(update={"home_x_m": point[0],
                                                                 "home_y_m": point[1]})
                self._accepted_pending = True
            said += f"; mission {mission.mission_id!r} returns there if it must"
        elif returning:
            said += "; the return under way ends at the home it set out for"
        log.info("%s", said)
        return Reply.accept(now_ns, said, home_x_m=point[0], home_y_m=point[1])

    def handle_command(self, now_ns: int, cmd: MissionCommand) -> Reply:
        withheld = "; and ".join(r for r in (latched_reason(self.vehicle), self.withheld_reason())
                                 if r is not None)
        if cmd.command == "resume" and self.missions.state == "paused" and withheld:
            return Reply.refuse(now_ns, f"cannot resume: {withheld}; the mission stays paused")
        refused = motion.resume_refusal(self._last_state) if cmd.command == "resume" else None
        if refused is not None and self.missions.state == "paused":
            return Reply.refuse(now_ns, refused)
        resuming = cmd.command == "resume" and self.missions.state == "paused"
        refused = self._budget_resume() if resuming else None
        if refused is not None:
            return Reply.refuse(now_ns, refused)
        try:
            state = self.missions.command(cmd)
        except MissionError as err:
            return Reply.refuse(now_ns, str(err))
        if resuming:
            self._rearm_budget()
        return Reply.accept(now_ns, f"mission {state}", state=state)
