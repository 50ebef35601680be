"""The controller's pure core: missions and commands in, replies out; a state in, a command out.

``ControllerCore.step(now_ns, state)`` runs one control period: mission bookkeeping (switch, complete),
one MPC solve for the active leg, and the fallback chain when the solve cannot be used:

====  ==================  ==========================================================================
lvl   source              when
====  ==================  ==========================================================================
0     the MPC             the solve succeeded within the period budget
1     ``plan-reuse``      failed or late: the last good plan's next thrusts, for up to
                          ``plan_reuse_steps`` consecutive failures (and while the plan lasts)
2     ``los``             then line-of-sight guidance along the active leg, ``los_steps`` periods
3     ``stop``            then zero thrust, reported, until a solve succeeds again
====  ==================  ==========================================================================

The MPC is tried every period whatever the level, so the chain unwinds as soon as it recovers.
Every fallback period is counted (``SolveRecord.fallback_count``) and published.

The vehicle (``on_vehicle_status``): while the autopilot does not apply the commanded thrust
(``VehicleStatus.thrust_withheld``: disarmed, no link, a mode such as HOLD after a failsafe), flying
the mission only pretends: the boat does not move, the energy count rises. So an active mission is
paused, with the reason in ``MissionStatus.reason``, and resumes only on the operator's request once
the vehicle applies the thrust again (a rebooted autopilot must not drive off on its own when
someone re-arms it). Only statuses stamped from the mission's start on count: the one before may
predate the arming its sender just did. An autopilot that is not healthy (``thrust_withheld``
'autopilot_unhealthy': its estimator not using GNSS, a critical status) keeps a new mission waiting
but does not pause one under way (its own failsafes act on that); and a paused mission is not
resumed while the autopilot is latched in a failsafe (``VehicleStatus.failsafe_latched``).

The vessel does not do what it is told (``motion.py``): while the estimate carries a motion fault
(``StateEstimate.motion_fault``: aground, a thruster stuck), an active mission is paused with the
fault named, and a resume is refused while it lasts.

A mission sent while the latest status says the thrust is withheld is accepted as ``waiting``
(never "started"), the reply and ``MissionStatus.reason`` saying for what; it becomes active by
itself at the first status stamped from its acceptance on that says the vehicle applies the thrust
(the launcher arms and sets the mode, then sends the mission: the status it last heard may be the
one before the arming). Lockstep has no vehicle_io: no status, no wait.

At rest (after the last waypoint, paused by the operator) the vessel holds station at the mission
manager's ``hold_point`` with the station-keeping law (``hold.py``) unless the mission asked to
drift; the energy it takes is counted to the battery and reported (``MissionStatus.hold_energy_j``),
and the energy budget goes on pricing the way home meanwhile (its policy acts on a hold that drains
the battery as on a mission).

The mission accepted (``accepted_due``, ``take_accepted``): every accepted mission becomes a
``MissionAccepted`` (its waypoints in local NED, its controller's settings) for ``mission/accepted``,
so that a recording holds the path actually flown. Lockstep takes it once, into the answer of the
period that follows the acceptance; real time sends it at once and again every
``ACCEPTED_REPUBLISH_NS``, for a recorder or ground station that joins late.

No clock, no bus: time comes in as ``now_ns`` (the state's stamp in lockstep).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from seaway.contract.messages import (
    HOLD_REASON_TEXT,
    MAX_REASON_CHARS,
    THRUST_APPLIED_ANYWAY,
    BatteryState,
    EnergyBudget,
    EnergyDecision,
    HomeRequest,
    MissionAccepted,
    MissionCommand,
    MissionRequest,
    MissionStatus,
    Reply,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
    VehicleStatus,
    Waypoint,
    return_mission_id,
)
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel import path
from seaway.vessel.envelope import envelope
from seaway.vessel.frames import GeoOrigin
from seaway.vessel.guidance import LosGains, los_thrust
from seaway.vessel.model import VesselParams, propulsion_power_w

from seaway_controller import acceptance, costs, motion
from seaway_controller.area_guard import HOLD_MARGIN_M, AreaGuard
from seaway_controller.battery_estimate import BatteryTrack
from seaway_controller.energy import Budget, Disturbance, EnergyModel, predict
from seaway_controller.hold import HoldGains, hold_thrust
from seaway_controller.mission import (
    PAUSED_PREFIX,
    Mission,
    MissionError,
    MissionLimits,
    MissionManager,
    home_ned,
    validate_mission,
)
from seaway_controller.mission_check import MissionCheck, check_mission
from seaway_controller.mpc import MpcController, MpcOutcome
from seaway_controller.ocp import CONTROLLER_KINDS, ControllerKind, Ocp, OcpSpec
from seaway_controller.solvers import NlpSolver, make_solver

log = logging.getLogger("seaway_controller.core")
ABSURD_STATE = "absurd_state"
"""``ThrustCommand.source`` of the zero thrust given for a state estimate no vessel could be in."""

LEVEL_MPC, LEVEL_PLAN, LEVEL_LOS, LEVEL_STOP = 0, 1, 2, 3
ACCEPTED_REPUBLISH_NS = 1_000_000_000
"""Real time: the current mission's ``MissionAccepted`` is sent again this often [ns], so that a
recorder or ground station that joins late learns it within a second."""


@dataclass(frozen=True)
class ControllerConfig:
    """The controller's settings (paper values by default: H = 10, dt = 0.1 s, n = 2)."""

    horizon: int = 10
    dt_s: float = 0.1
    profile_n: float = 2.0
    solver: str = "generated"
    """'generated' (fast SQP, compiled C) or 'ipopt' (plain IPOPT, the reference)."""
    plan_reuse_steps: int = 3
    los_steps: int = 600
    solve_budget_s: float | None = 0.1
    """A solve slower than this is late and not applied (None: never late, for replayable runs)."""
    predict_disturbance: bool = False
    """Make every mission predict with the estimate's tau_d (beyond the paper, which predicts with
    tau_d = 0), whatever its request says; False leaves it to each mission's ``predict_disturbance``."""
    los: LosGains = field(default_factory=LosGains)
    hold: HoldGains = field(default_factory=HoldGains)
    limits: MissionLimits = field(default_factory=MissionLimits)
    nmpc: costs.NmpcWeights = field(default_factory=costs.NmpcWeights)

    def spec(self, kind: ControllerKind) -> OcpSpec:
        return OcpSpec(kind, self.horizon, self.dt_s, self.profile_n, nmpc=self.nmpc)


SolverFactory = Callable[[Ocp], NlpSolver]


@dataclass(frozen=True)
class BudgetDecision:
    """What the energy budget decided for the current mission (kept across a restart)."""

    returning: bool = False
    """The mission is the budget's return home."""
    decision: EnergyDecision = "none"
    decided_ns: int | None = None
    reason: str = ""


def _waiting_for(why: str) -> str:
    """A waiting mission's reason: what the vehicle lacks (``why``) and what starts it."""
    return (f"waiting for the vehicle: {why}; the mission starts by itself once the vehicle "
            "applies the thrust (arm it, set its mode)")


def _latched_reason(v: VehicleStatus | None) -> str | None:
    """Why a paused mission may not resume although the thrust is applied: the autopilot still
    stands in a failsafe (``VehicleStatus.failsafe_latched``), named; None: it does not."""
    if v is None or v.failsafe_latched is None:
        return None
    return (f"the autopilot is still latched in {HOLD_REASON_TEXT[v.failsafe_latched]} "
            f"({v.failsafe_latched_detail[:120]})")


def _finite_or_none(v: float | None) -> float | None:
    return v if v is not None and math.isfinite(v) else None


class ControllerCore:
    """Missions, the three controllers and the fallback chain; see the module docstring."""

    def __init__(self, vessel: VesselParams, config: ControllerConfig = ControllerConfig(),
                 solver_factory: SolverFactory | None = None) -> None:
        self.vessel, self.config = vessel, config
        self.missions = MissionManager(config.limits)
        self.origin: GeoOrigin | None = None
        self._factory = solver_factory or (lambda ocp: make_solver(ocp, config.solver))
        self._controllers: dict[str, MpcController] = {}
        self._mission_serial = 0
        self.seq = 0
        self.fallback_count = 0
        self.consecutive_failures = 0
        self.level = LEVEL_MPC
        self.energy_used_j = 0.0
        self._last_step_ns: int | None = None
        self._last_command = (0.0, 0.0)
        self._energy_to_go_j: float | None = None
        self.mission_request: MissionRequest | None = None
        self.vehicle: VehicleStatus | None = None  # the latest status heard (None: no vehicle_io)
        self._last_state: StateEstimate | None = None  # the latest stepped (a mission is judged on it)
        self._ratelog = RateLimitedLog(log)
        self._envelope = envelope(vessel)
        self.battery_at_start_j: float | None = None
        """The run's battery at its start [J] (its scenario's ``[battery]``, else the full pack):
        what a mission is checked against before the first battery report; None: not known."""
        self.absurd_states = 0
        """State estimates refused as no vessel's (``seaway.vessel.envelope``): zero thrust instead."""
        self._mission_start_ns = 0
        self.accepted: MissionAccepted | None = None  # the current mission, as accepted
        self._accepted_pending = False  # accepted since it was last taken or sent
        self._accepted_sent_ns: int | None = None  # real time: when it was last sent
        # The energy budget (seaway_controller.energy): the battery's last report, the energy
        # counted since the process started (propulsion + T^w, whatever the mission's state: the
        # battery feeds the task while paused too), the current mission's budget, its last message.
        self.battery = BatteryTrack(vessel.battery)
        self.energy_counted_j = 0.0
        self.budget: Budget | None = None
        self._budget_msg: EnergyBudget | None = None
        self.hold_energy_j = 0.0  # counted since the current hold began
        self._holding: tuple[float, float] | None = None  # the point held at the last step
        self._hold_moved: tuple[tuple[float, float], tuple[float, float], object] | None = None
        """(hold point asked, point held, the area it was worked out in)."""
        self.area = AreaGuard(vessel)  # the operating area enforced (area_guard.py)
        self._area_return = False  # the mission is the return from the area's edge
        # Home, explicit: the operator's (a request's ``home``), else where the vessel was when
        # armed (vehicle_io) or, with no vehicle (lockstep), when the first mission was accepted.
        self.home: tuple[float, float] | None = None

    # -- set-up ---------------------------------------------------------------------------------

    def controller(self, kind: ControllerKind) -> MpcController:
        """The MPC of ``kind``, built (and its solver compiled or loaded) on first use."""
        if kind not in self._controllers:
            ocp = Ocp(self.config.spec(kind), self.vessel)
            self._controllers[kind] = MpcController(ocp, self._factory(ocp))
        return self._controllers[kind]

    def prepare(self, kinds: tuple[ControllerKind, ...] = CONTROLLER_KINDS) -> None:
        """Build every controller now, so that no mission waits for a compile."""
        for k in kinds:
            self.controller(k)

    def prepare_for(self, req: MissionRequest) -> ControllerKind | None:
        """The controller ``req`` would be flown with, built now (its solver asked for), so that
        the caller can wait for its solver before the mission starts; None if ``req`` would be
        refused (``handle_mission`` then says why)."""
        try:
            mission = validate_mission(req, self.origin, self.missions.limits)
        except MissionError:
            return None
        if self._not_flyable(mission, req) is not None:
            return None
        self.controller(mission.controller)
        return mission.controller

    def _not_flyable(self, mission: Mission, req: MissionRequest) -> str | None:
        """Why ``mission`` cannot be flown from the latest state (``acceptance``), or None."""
        return acceptance.why_not_flyable(self._energy_model(mission, req), self._last_state,
                                          mission.waypoints_m, mission.home,
                                          join_first_leg=mission.join_first_leg)

    def set_origin(self, origin: GeoOrigin) -> None:
        self.origin = origin

    # -- requests -------------------------------------------------------------------------------

    def handle_mission(self, now_ns: int, req: MissionRequest, returning: bool = False,
                       check: bool = True) -> Reply:
        """Validate and start a mission (replacing the current one), or refuse with a reason.
        ``returning``: the return home the energy budget decided (``_return_home``). ``check``: a
        new mission that cannot be flown under the disturbance estimated now is refused
        (``acceptance``); a mission resumed or restarted is not judged again."""
        st = self._last_state
        req = self._with_home(req, st)
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
        mission = self.missions.start(req, self.origin, (st.x_m, st.y_m) if st is not None else None)
        ctrl = self.controller(mission.controller)
        ctrl.reset()
        self._mission_serial += 1
        self.fallback_count = self.consecutive_failures = 0
        self.level = LEVEL_MPC
        self.energy_used_j = 0.0
        self._energy_to_go_j = None
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
            self.missions.wait(_waiting_for(withheld))
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

    def _with_home(self, req: MissionRequest, st: StateEstimate | None) -> MissionRequest:
        """``req`` with its home explicit: its own, else the vessel's (``self.home``), else where
        the vessel is now (which becomes the vessel's home), else P_0 (nothing known yet)."""
        if req.home is not None:
            return req
        if self.home is None and st is not None:
            self.home = (st.x_m, st.y_m)
        if self.home is None:
            return req
        return req.model_copy(update={"home": Waypoint(x_m=self.home[0], y_m=self.home[1])})

    def _shortfall(self) -> str:
        """'' or, for the mission just started, that the battery is short of the energy predicted
        to finish it (from the latest state, under the disturbance estimated now) and what the
        mission's policy will do about it."""
        b, st, left = self.budget, self._last_state, self.battery_remaining_j()
        if b is None or st is None or left is None or b.returning:
            return ""
        pred = predict(b.model, st, b.waypoints, self.missions.active, b.home, None,
                       Disturbance.from_body((st.tau_d_surge_n, st.tau_d_sway_n, st.tau_d_yaw_nm),
                                             st.psi_rad))
        above = left - (self._reserve_j() or 0.0)
        if not math.isfinite(pred.to_go_j) or pred.to_go_j <= above:
            return ""
        return (f"; it needs about {pred.to_go_j:.0f} J and the battery has {above:.0f} J above its "
                f"reserve: the energy budget's policy '{b.policy}' acts when the way home reaches "
                "what is left")

    def _energy_model(self, mission: Mission, req: MissionRequest) -> EnergyModel:
        """What the energy budget prices ``mission`` (requested as ``req``) with."""
        spec = self.config.spec(mission.controller)
        return EnergyModel(
            self.vessel, mission.task_power_w, mission.coa_radius_m, spec.is_empc,
            self.config.predict_disturbance or req.predict_disturbance,
            spec.profile_n, spec.t_d_min_s, spec.t_d_max_s)

    def _new_budget(self, mission: Mission, returning: bool) -> Budget:
        assert self.mission_request is not None
        model = self._energy_model(mission, self.mission_request)
        return Budget(model, list(mission.waypoints_m), mission.home, mission.on_low_energy,
                      mission.mission_id, returning, controller=mission.controller)

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

    def decision(self) -> BudgetDecision:
        """The current mission's energy budget decision, as a checkpoint keeps it."""
        b = self.budget
        if b is None:
            return BudgetDecision()
        return BudgetDecision(b.returning, b.decision, b.decided_ns, b.reason)

    def restore(self, now_ns: int, req: MissionRequest, active_leg: int, state: str,
                energy_used_j: float, decision: BudgetDecision | None = None,
                hold_point: tuple[float, float] | None = None) -> Reply:
        """Resume a checkpointed mission at ``active_leg`` (after a restart), or refuse; with
        the energy budget's ``decision`` as it was (a return home goes on as one: its own policy
        is only 'warn', and a fresh budget would have said 'LOW ENERGY (policy: warn)'), and, at
        rest (paused or complete), station kept at ``hold_point`` (local NED [m]) as before."""
        decision = decision or BudgetDecision()
        reply = self.handle_mission(now_ns, req, returning=decision.returning, check=False)
        if not reply.accepted:
            return reply
        if self.budget is not None:
            b = self.budget
            b.decision, b.decided_ns, b.reason = decision.decision, decision.decided_ns, decision.reason
        mm = self.missions
        assert mm.mission is not None
        first = 1 if mm.mission.join_first_leg else 0  # 0: it was on its way to P_0
        if not first <= active_leg < len(mm.mission.waypoints_m):
            mm.state = "idle"
            self.accepted, self._accepted_pending = None, False  # not flown after all
            return Reply.refuse(now_ns, f"checkpoint's active leg {active_leg} is not a leg of the "
                                        f"mission ({len(mm.mission.waypoints_m)} waypoints)")
        mm.active, mm.state = active_leg, state  # type: ignore[assignment]
        if state in ("paused", "complete"):
            mm.hold_point = hold_point
        if state == "waiting" and not mm.reason:
            mm.wait(_waiting_for("no status heard since the restart yet"))
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
        home) takes it as its home: its energy budget prices the way there from now on."""
        if req.home == "here":
            st = self._last_state
            if st is None:
                return Reply.refuse(now_ns, "home 'here' is not known: no state estimate yet; give "
                                    "a position (x_m/y_m or lat_deg/lon_deg)")
            point = (st.x_m, st.y_m)
        else:
            try:
                point = home_ned(req.home, self.origin, self.missions.limits)
            except MissionError as err:
                return Reply.refuse(now_ns, str(err))
        why = self.area.home_refusal(point)
        if why is not None:
            return Reply.refuse(now_ns, why)
        self.home = point
        said = f"home set at north {point[0]:.1f} m, east {point[1]:.1f} m"
        mission, req_now, b = self.missions.mission, self.mission_request, self.budget
        returning = (b is not None and b.returning) or self._area_return
        if mission is not None and req_now is not None and self.missions.state in (
                "waiting", "active", "paused") and not returning:
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
        withheld = "; and ".join(r for r in (_latched_reason(self.vehicle), self.withheld_reason())
                                 if r is not None)
        if cmd.command == "resume" and self.missions.state == "paused" and withheld:
            return Reply.refuse(now_ns, f"cannot resume: {withheld}; the mission stays paused")
        refused = motion.resume_refusal(self._last_state) if cmd.command == "resume" else None
        if refused is not None and self.missions.state == "paused":
            return Reply.refuse(now_ns, refused)
        try:
            state = self.missions.command(cmd)
        except MissionError as err:
            return Reply.refuse(now_ns, str(err))
        return Reply.accept(now_ns, f"mission {state}", state=state)

    # -- the vehicle ----------------------------------------------------------------------------

    def on_vehicle_status(self, status: VehicleStatus) -> str | None:
        """The vehicle's status, in the order vehicle_io published them: pauses an active mission
        while the autopilot does not apply the commanded thrust, starts a waiting one once it does
        (see the module docstring). What it changed now (for a person), else None."""
        was, st = self.vehicle, self._last_state
        if status.armed and (was is None or not was.armed) and st is not None:
            self.home = (st.x_m, st.y_m)  # home is where the vessel was armed
        self.vehicle = status  # the latest, whatever its stamp says (a stamp cannot pin an old one)
        if status.stamp_ns < self._mission_start_ns:
            return None  # from before this mission: perhaps before the arming that preceded it
        why = self.withheld_reason()
        if self.missions.state == "waiting":
            if why is None and self.missions.release():
                log.info("mission %r started: the vehicle applies the thrust",
                         self.missions.mission.mission_id if self.missions.mission else "")
                return "started: the vehicle applies the thrust"
            if why is not None:
                self.missions.wait(_waiting_for(why))
            return None
        if status.thrust_withheld in THRUST_APPLIED_ANYWAY:
            return None  # starts wait for it; under way, the autopilot's own failsafes act on it
        if why is None:
            return None
        reason = (f"{PAUSED_PREFIX}{why}; resume with 'seaway mission resume' once it "
                  "applies it again")
        if not self.missions.hold(reason):
            # The cause may be named after the pause began (the autopilot's text follows its mode
            # change): the operator is told the newest, while the pause is still the controller's.
            if self.missions.restate(PAUSED_PREFIX, reason):
                log.warning("mission %r paused: %s", self.missions.mission.mission_id
                            if self.missions.mission else "", why)
                return self.missions.reason
            return None
        log.warning("mission %r paused: %s (resumes only on request)",
                    self.missions.mission.mission_id if self.missions.mission else "", why)
        return self.missions.reason

    def withheld_reason(self) -> str | None:
        """Why the vehicle does not apply the commanded thrust now, for a person (None: it does,
        or no vehicle status was heard)."""
        v = self.vehicle
        if v is None or v.thrust_withheld is None:
            return None
        cause = "" if v.hold_reason is None else (
            f"; why: {HOLD_REASON_TEXT[v.hold_reason]}"
            + (f" ({v.hold_reason_detail})" if v.hold_reason_detail else ""))
        return {
            "no_link": "vehicle_io has no link to the autopilot (lost, or the autopilot rebooted)",
            "disarmed": "the vehicle is disarmed (the autopilot rebooted, or was disarmed)",
            "mode": f"the autopilot is in mode {v.mode}, in which it does not apply the commanded "
                    "thrust" + ("" if cause else " (a failsafe, or another mode was set)"),
            "autopilot_unhealthy": v.autopilot_unhealthy_detail or "the autopilot is not healthy",
            "autopilot_config": "vehicle_io sends neutral only: the autopilot's configuration "
                                "blocks thrust (see vehicle_io's log)",
        }[v.thrust_withheld] + cause

    # -- the control period ---------------------------------------------------------------------

    def step(self, now_ns: int, state: StateEstimate
             ) -> tuple[ThrustCommand, SolveRecord | None, MissionStatus]:
        """One period: a command for ``state`` (stamped with its stamp), the solve record (None
        when no solve was needed: no mission, paused, complete, aborted) and the mission status."""
        why = self._envelope.absurd(state.u_mps, state.v_mps, state.r_radps)
        if why is not None:
            # No vessel moves like this: an estimator that went unstable. Planning from it threw
            # in the model's rollout and ground the solver for a second a period; nothing is
            # flown on it and it moves no waypoint, but the period still gets its command.
            self.seq += 1
            self.absurd_states += 1
            self._ratelog.warning("absurd_state", "state estimate refused, zero thrust: %s", why)
            cmd = self._command(state.stamp_ns, (0.0, 0.0), ABSURD_STATE)
            return cmd, None, self._status(now_ns, self._last_state or state)
        x0 = np.array([state.u_mps, state.v_mps, state.r_radps, state.x_m, state.y_m,
                       state.psi_rad])
        self._account_energy(now_ns)
        self._last_state = state
        mm = self.missions
        mm.update(state.x_m, state.y_m)
        self.seq += 1
        if (paused := motion.pause_on_motion_fault(mm, state)) is not None:  # seaway_controller.motion
            log.warning("mission %r %s", mm.mission.mission_id if mm.mission else "", paused)
        if mm.state != "active" or mm.mission is None:
            point = mm.hold_point if self.withheld_reason() is None else None
            if point is not None:
                point = self._hold_at(point)
            if point is not None and self._holding != point:
                self.hold_energy_j = 0.0  # a new hold
            self._holding = point
            if point is None:
                cmd = self._command(state.stamp_ns, (0.0, 0.0), mm.state)
            else:
                tau = (state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm)
                thrust = hold_thrust(tuple(x0), point, tau, self.vessel, self.config.hold)
                cmd = self._command(state.stamp_ns, thrust, "hold")
            # Held or drifting, the pack drains (the hold, the task's load, the autopilot's own
            # figure falling): the budget goes on telling the truth about it.
            self._update_budget(now_ns, state, None)
            return cmd, None, self._status(now_ns, state)
        self._holding = None
        mission = mm.mission
        wp_prev, wp_act = mm.leg()
        ctrl = self.controller(mission.controller)
        tau_d = ((state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm)
                 if self.predict_disturbance else (0.0, 0.0, 0.0))
        plan_age = ctrl.plan_age(now_ns)
        reusable = ctrl.last_good if plan_age is not None else None
        out = ctrl.solve(now_ns, x0, wp_prev, wp_act, mission.coa_radius_m, mission.task_power_w,
                         (self._mission_serial, mm.active), tau_d)
        res = out.result
        budget = self.config.solve_budget_s
        late = budget is not None and res.solve_time_s > budget
        if res.success and not late:
            ctrl.accept(out)
            self.consecutive_failures = 0
            thrust = (float(out.plan.thrusts_n[0, 0]), float(out.plan.thrusts_n[0, 1]))
            self._set_level(LEVEL_MPC, res.status)
            source, used = mission.controller, out
            self._energy_to_go_j = _finite_or_none(out.costs.energy_to_go_j)
        else:
            self.consecutive_failures += 1
            self.fallback_count += 1
            used = None
            reason = "late" if res.success else res.status
            if (reusable is not None and plan_age is not None
                    and self.consecutive_failures <= self.config.plan_reuse_steps):
                row = reusable.thrusts_n[plan_age]
                thrust, source = (float(row[0]), float(row[1])), "plan-reuse"
                self._set_level(LEVEL_PLAN, reason)
            elif self.consecutive_failures <= self.config.plan_reuse_steps + self.config.los_steps:
                thrust = los_thrust(tuple(x0), wp_prev, wp_act, self.vessel, self.config.los,
                                    mission.speed_hint_mps)
                source = "los"
                self._set_level(LEVEL_LOS, reason)
            else:
                thrust, source = (0.0, 0.0), "stop"
                self._set_level(LEVEL_STOP, reason)
        cmd = self._command(state.stamp_ns, thrust, source)
        flown = reusable if self.level == LEVEL_PLAN else None
        record = self._record(state.stamp_ns, mission.controller, out, late, used, flown)
        plan = used.plan if used is not None else flown
        breach = self.area.breach(state, plan.states if plan is not None else None,
                                  position_only=self._area_return)
        if breach is not None:  # stop short of the area's edge: this period's command is the stop's
            self._area_stop(now_ns, state, breach)
            cmd, _, status = self.step(now_ns, state)
            return cmd, record, status
        self._update_budget(now_ns, state, used)
        return cmd, record, self._status(now_ns, state)

    def _area_stop(self, now_ns: int, state: StateEstimate, why: str) -> None:
        """The course would leave the operating area: per the mission's ``on_area_breach``, return
        to the nearest clear one of home and the rally points, else hold station where it is."""
        req, mm = self.mission_request, self.missions
        here = (state.x_m, state.y_m)
        if req is not None and req.on_area_breach == "return" and mm.mission is not None:
            target = self.area.return_target(here, mm.mission.home)
            if target is not None and self._return_home(now_ns, state, target,
                                                        f"returning: {why}") == "active":
                self._area_return = True
                log.warning("operating area: %s; returning to (%.1f, %.1f) m", why, *target)
                return
        if mm.hold(f"held at the operating area's edge: {why}; holding station here"):
            mm.hold_point = here
        log.warning("operating area: %s; mission %r held", why, mm.mission.mission_id
                    if mm.mission else "")

    # -- the energy budget (seaway_controller.energy) -------------------------------------------

    def on_battery(self, report: BatteryState) -> None:
        """The battery's latest report: what is left is counted down from it until the next."""
        self.battery.report = report
        self.battery.counted_at_report_j = self._counted_at(report.stamp_ns)

    def _counted_at(self, t_ns: int) -> float:
        """The energy counted up to ``t_ns`` [J]: the count at the last step, plus (or minus) the
        last command's power over the time from that step."""
        if self._last_step_ns is None:
            return self.energy_counted_j
        # The same expression as _account_energy's, so that a report stamped at the next step
        # counts exactly nothing since (lockstep: the decision is bit-for-bit replayable).
        return self.energy_counted_j + self._power_w() * ((t_ns - self._last_step_ns) / 1e9)

    def _power_w(self) -> float:
        """What the battery feeds now by the controller's count: the last command and T^w [W]."""
        m = self.missions.mission
        return propulsion_power_w(self._last_command, self.vessel) + (m.task_power_w if m else 0.0)

    def battery_remaining_j(self) -> float | None:
        """The battery's usable energy left now: its last report less what was counted since [J]."""
        return self.battery.remaining_j(self.energy_counted_j)

    def _reserve_j(self) -> float | None:
        r = self.battery.report
        if r is not None and r.reserve_j is not None:
            return r.reserve_j
        return self.vessel.battery.reserve_energy_j if self.vessel.battery is not None else None

    def _update_budget(self, now_ns: int, state: StateEstimate, used: MpcOutcome | None) -> None:
        """The budget, when due (``Budget.due``: once a second, at a new leg, every period once
        the margin is near 0), and the policy's action at the pricing that finds the margin at 0.
        Priced while the mission is active, paused (holding station or drifting: the battery
        goes on falling, and the way home is priced against what is left) and while the vessel
        holds station at rest after it."""
        budget, mm = self.budget, self.missions
        priced = mm.state in ("active", "paused") or self._holding is not None
        if budget is None or mm.mission is None or not priced or not budget.due(now_ns, mm.active):
            return
        leg_j = _finite_or_none(used.costs.energy_to_go_j) if used is not None else None
        report = self.battery.report
        taken = budget.update(now_ns, state, mm.active, leg_j, self.energy_used_j,
                              self.battery_remaining_j(),
                              report.stamp_ns if report is not None else None, self._reserve_j())
        if budget.last is not None and self.battery.source is not None:
            budget.last = budget.last.model_copy(update={"battery_source": self.battery.source})
        self._budget_msg = budget.last
        if taken is None:
            return
        log.warning("energy budget: %s; the mission's policy: %s", budget.reason, taken)
        if taken == "hold" and not mm.hold(f"held by the energy budget: {budget.reason}"):
            mm.drift(f"drifting: the energy budget's policy 'hold' stopped the station keeping: "
                     f"{budget.reason}")
        elif taken == "return":  # to the cheapest to reach of home and the rally points
            dist = Disturbance.from_body((state.tau_d_surge_n, state.tau_d_sway_n,
                                          state.tau_d_yaw_nm), state.psi_rad)
            target = self.area.return_target(
                (state.x_m, state.y_m), budget.home,
                lambda p: predict(budget.model, state, budget.waypoints, mm.active, p, None,
                                  dist).to_home_j)
            self._return_home(now_ns, state, target)

    def _return_home(self, now_ns: int, state: StateEstimate, home: tuple[float, float] | None = None,
                     reason: str = "") -> str:
        """Replace the mission by the straight run to ``home`` (default the mission's; the energy
        budget's nearest reachable of home and the rally points), flown the same way (same
        controller, T^w, r_COA); its own budget only warns. The mission manager's state after."""
        req, mission = self.mission_request, self.missions.mission
        assert req is not None and mission is not None
        home = home if home is not None else mission.home
        if math.dist((state.x_m, state.y_m), home) <= mission.coa_radius_m:
            self.missions.hold("home reached on the energy budget's return")
            return self.missions.state
        back = req.model_copy(update={
            "mission_id": return_mission_id(mission.mission_id),
            "waypoints": [Waypoint(x_m=state.x_m, y_m=state.y_m),
                          Waypoint(x_m=home[0], y_m=home[1])],
            "home": Waypoint(x_m=home[0], y_m=home[1]), "on_low_energy": "warn",
            "on_area_breach": "hold",
            "join_first_leg": True})
        reply = self.handle_mission(now_ns, back, returning=True)
        if not reply.accepted:  # its way crosses the area: stop rather than fly on
            self.missions.hold(f"the return home was refused: {reply.reason}")
        elif reason:
            self.missions.reason = reason[:MAX_REASON_CHARS]
        return self.missions.state

    def _hold_at(self, point: tuple[float, float]) -> tuple[float, float]:
        """The point held for ``point`` (``AreaGuard.hold_point``: moved in from the area's edge),
        worked out once per hold point."""
        cached = self._hold_moved
        if cached is None or cached[0] != point or cached[2] is not self.area.area:
            moved = self.area.hold_point(point)
            if moved != point:
                log.info("holding station %.1f m inside the area's edge at north %.1f m, east "
                         "%.1f m, not at north %.1f m, east %.1f m (%.1f m from it)",
                         HOLD_MARGIN_M, moved[0], moved[1], point[0], point[1],
                         math.dist(moved, point))
            self._hold_moved = cached = (point, moved, self.area.area)
        return cached[1]

    def take_budget(self) -> EnergyBudget | None:
        """The budget priced at the last step, once (None: none was, or no active mission was
        stepped)."""
        msg, self._budget_msg = self._budget_msg, None
        return msg

    def zero_command(self, stamp_ns: int, source: str) -> ThrustCommand:
        """A zero-thrust command outside the control period (e.g. the state went stale)."""
        self.seq += 1
        return self._command(stamp_ns, (0.0, 0.0), source)

    # -- helpers --------------------------------------------------------------------------------

    def _set_level(self, level: int, reason: str) -> None:
        if level != self.level:
            if level == LEVEL_MPC:
                log.info("solver recovered; back to the MPC")
            else:
                names = {LEVEL_PLAN: "reusing the last plan", LEVEL_LOS: "line-of-sight guidance",
                         LEVEL_STOP: "STOPPED (zero thrust)"}
                # A solver failing every other period flips levels 5 times a second: rate-limited.
                self._ratelog.warning(("fallback", level), "fallback level %d (%s): %s", level,
                                      names[level], reason)
        self.level = level

    def _account_energy(self, now_ns: int) -> None:
        """Energy of the last command over the time since: alpha (T1^2 + T2^2) + T^w [J], to the
        mission's count while it is active and to the battery's count always."""
        mm = self.missions
        if self._last_step_ns is not None:
            dt = max(0.0, (now_ns - self._last_step_ns) / 1e9)
            energy = self._power_w() * dt
            self.energy_counted_j += energy
            if mm.state == "active" and mm.mission is not None:
                self.energy_used_j += energy
            elif self._holding is not None:
                self.hold_energy_j += energy
        self._last_step_ns = now_ns

    def _command(self, stamp_ns: int, thrust: tuple[float, float], source: str) -> ThrustCommand:
        self._last_command = thrust
        return ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=thrust[0],
                                  thrust_starboard_n=thrust[1], source=source, seq=self.seq)

    def _record(self, stamp_ns: int, kind: str, out: MpcOutcome, late: bool,
                used: MpcOutcome | None, reused) -> SolveRecord:
        res = out.result
        c = used.costs if used is not None else None
        plan = used.plan if used is not None else reused
        fields: dict = {}
        if plan is not None and np.isfinite(plan.states).all():  # the method: no dispatch layers
            fields = {"predicted_x_m": plan.states[:, 3].tolist(),
                      "predicted_y_m": plan.states[:, 4].tolist(),
                      "predicted_psi_rad": plan.states[:, 5].tolist(),
                      "predicted_thrust_port_n": plan.thrusts_n[:, 0].tolist(),
                      "predicted_thrust_starboard_n": plan.thrusts_n[:, 1].tolist()}
        if c is not None:
            fields.update(
                cost_stage_j=_finite_or_none(c.stage_j), cost_dynamic_j=_finite_or_none(c.dynamic_j),
                cost_static_j=_finite_or_none(c.static_j), cost_track_j=_finite_or_none(c.track_j),
                t_d_s=_finite_or_none(c.t_d_s), t_s_s=_finite_or_none(c.t_s_s),
                leg_energy_to_go_j=_finite_or_none(c.energy_to_go_j),
                cross_track_m=_finite_or_none(c.cross_track_m))
        status = res.status + (f" (late: {res.solve_time_s * 1e3:.1f} ms)" if late else "")
        return SolveRecord.make(stamp_ns=stamp_ns, controller=kind, status=status,
                                success=res.success and not late, iterations=res.iterations,
                                solve_time_s=max(res.solve_time_s, 0.0), fallback_level=self.level,
                                fallback_count=self.fallback_count, **fields)

    def _status(self, now_ns: int, state: StateEstimate) -> MissionStatus:
        mm = self.missions
        if mm.mission is None:
            return MissionStatus.make(stamp_ns=state.stamp_ns, state="idle")
        m = mm.mission
        wp_prev, wp_act = mm.leg()
        xte = (path.signed_cross_track_m(state.x_m, state.y_m, wp_prev, wp_act)
               if wp_prev != wp_act else math.dist((state.x_m, state.y_m), wp_act))
        return MissionStatus.make(
            stamp_ns=state.stamp_ns, state=mm.state, mission_id=m.mission_id, active_leg=mm.active,
            waypoint_count=len(m.waypoints_m),
            distance_to_waypoint_m=math.dist((state.x_m, state.y_m), wp_act),
            cross_track_m=abs(xte), energy_used_j=self.energy_used_j,
            energy_to_go_j=(self.budget.last.energy_to_go_j if mm.state == "active" and self.budget
                            and self.budget.last else None),
            leg_energy_to_go_j=self._energy_to_go_j if mm.state == "active" else None,
            reason=mm.reason, hold_x_m=self._holding[0] if self._holding else None,
            hold_y_m=self._holding[1] if self._holding else None,
            hold_energy_j=self.hold_energy_j if self._holding else None)
