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

The vehicle (``core_vehicle``): while the autopilot does not apply the commanded thrust, an active
mission is paused and resumes only on the operator's request; a mission sent meanwhile waits.

The vessel does not do what it is told (``motion.py``): while the estimate carries a motion fault
(``StateEstimate.motion_fault``: aground, a thruster stuck), an active mission is paused with the
fault named, and a resume is refused while it lasts.

At rest (after the last waypoint, paused by the operator) the vessel holds station at the mission
manager's ``hold_point`` with the station-keeping law (``hold.py``) unless the mission asked to
drift; the energy it takes is counted to the battery and reported (``MissionStatus.hold_energy_j``),
and the energy budget goes on pricing the way home meanwhile (its policy acts on a hold that drains
the battery as on a mission).

The core is one class in four parts, each a module: the control period and the fallback chain
(here), the requests (``core_requests``: missions, home, commands, restore, the mission as
accepted), the vehicle (``core_vehicle``) and the energy (``core_energy``: counts, battery, budget).

No clock, no bus: time comes in as ``now_ns`` (the state's stamp in lockstep).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable

import numpy as np
from seaway.contract.messages import (
    MissionRequest,
    MissionStatus,
    SolveRecord,
    StateEstimate,
    ThrustCommand,
)
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel import path
from seaway.vessel.envelope import envelope
from seaway.vessel.frames import MAX_RANGE_M, GeoOrigin
from seaway.vessel.guidance import los_thrust
from seaway.vessel.model import VesselParams
from seaway.vessel.thrusters import FULL_THRUST, command_for, given_fractions, loss_of

from seaway_controller import acceptance, motion
from seaway_controller.area_guard import HOLD_MARGIN_M, AreaGuard
from seaway_controller.config import ControllerConfig
from seaway_controller.core_energy import EnergyAccount
from seaway_controller.core_requests import MissionRequests
from seaway_controller.core_vehicle import VehicleGate
from seaway_controller.energy import finite_or_none
from seaway_controller.hold import hold_thrust
from seaway_controller.mission import (
    Mission,
    MissionError,
    MissionManager,
    validate_mission,
)
from seaway_controller.mpc import MpcController, MpcOutcome
from seaway_controller.ocp import CONTROLLER_KINDS, ControllerKind, Ocp
from seaway_controller.solvers import NlpSolver, make_solver

log = logging.getLogger("seaway_controller.core")
ABSURD_STATE = "absurd_state"
"""``ThrustCommand.source`` of the zero thrust given for a state estimate no vessel could be in."""

LEVEL_MPC, LEVEL_PLAN, LEVEL_LOS, LEVEL_STOP = 0, 1, 2, 3

MAX_COVARIANCE_ENTRY = 1e12
"""Largest |entry| of a state estimate's covariance the controller takes: a position std of 1000 km,
a speed std of 10^6 m/s. Past it the filter has diverged, and the energy band's eigendecomposition
of it fails to converge."""


SolverFactory = Callable[[Ocp], NlpSolver]


class ControllerCore(MissionRequests, VehicleGate, EnergyAccount):
    """Missions, the three controllers and the fallback chain; see the module docstring."""

    def __init__(self, vessel: VesselParams, config: ControllerConfig | None = None,
                 solver_factory: SolverFactory | None = None) -> None:
        """``config``: the paper's settings by default (``ControllerConfig()``)."""
        config = config or ControllerConfig()
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
        self._energy_to_go_j: float | None = None
        self._last_state: StateEstimate | None = None  # the latest stepped (a mission is judged on it)
        self._ratelog = RateLimitedLog(log)
        self._envelope = envelope(vessel)
        self.battery_at_start_j: float | None = None
        """The run's battery at its start [J] (its scenario's ``[battery]``, else the full pack):
        what a mission is checked against before the first battery report; None: not known."""
        self.absurd_states = 0
        """State estimates refused as no vessel's (``seaway.vessel.envelope``): zero thrust instead."""
        self._holding: tuple[float, float] | None = None  # the point held at the last step
        self._hold_moved: tuple[tuple[float, float], tuple[float, float], object] | None = None
        """(hold point asked, point held, the area it was worked out in)."""
        self.area = AreaGuard(vessel)  # the operating area enforced (area_guard.py)
        self._area_return = False  # the mission is the return from the area's edge
        self._init_requests()
        self._init_vehicle()
        self._init_energy(vessel)

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

    def _new_flight(self, mission: Mission) -> None:
        """A mission starts (new, resumed, or the budget's return): its controller's warm start,
        the fallback chain and the mission's counts start afresh."""
        self.controller(mission.controller).reset()
        self._mission_serial += 1
        self.fallback_count = self.consecutive_failures = 0
        self.level = LEVEL_MPC
        self.energy_used_j = 0.0
        self._energy_to_go_j = None

    # -- the control period ---------------------------------------------------------------------

    def step(self, now_ns: int, state: StateEstimate, mono_ns: int | None = None
             ) -> tuple[ThrustCommand, SolveRecord | None, MissionStatus]:
        """One period: a command for ``state`` (stamped with its stamp), the solve record (None
        when no solve was needed: no mission, paused, complete, aborted) and the mission status.
        ``now_ns``: the period's time (wall clock in real time, simulated in lockstep); ``mono_ns``
        [ns, monotonic]: real time's clock for the energy counted over the time since the last
        step (None: ``now_ns``'s), which a stepped wall clock must not stretch."""
        why = self._absurd(state)
        if why is not None:
            # No vessel moves like this: an estimator that went unstable. Planning from it threw
            # in the model's rollout and ground the solver for a second a period; nothing is
            # flown on it and it moves no waypoint, but the period still gets its command.
            self.seq += 1
            self.absurd_states += 1
            self._ratelog.warning("absurd_state", "state estimate refused, zero thrust: %s", why)
            cmd = self._command(state.stamp_ns, (0.0, 0.0), ABSURD_STATE)
            return cmd, None, self._status(now_ns, self._last_state or state)
        given = given_fractions(state.thrust_short_side, state.thrust_short_frac)
        return self._period(now_ns, self._explained(state, given), mono_ns, given)

    def _explained(self, state: StateEstimate, given: tuple[float, float]) -> StateEstimate:
        """``state`` with the loss of a thruster it says short taken out of its disturbance.

        The estimate's disturbance is all that the model leaves unexplained, a thruster's loss
        included, at the command the estimator held (this controller's last). This controller
        flies with the loss itself: the MPC's model moves with the thrust given, and the hold and
        the line-of-sight fallback ask the weak side for more (``command_for``). So what prices
        the way home, accepts a mission, holds station or predicts with the disturbance sees the
        rest, not the loss counted twice. ``state`` itself with no loss said (``given``: the
        fraction of its command each thruster gives, as ``state`` says)."""
        if given == FULL_THRUST:
            return state
        surge_n, yaw_nm = loss_of(*self._last_command, given, self.vessel.arm_m)
        return state.model_copy(update={"tau_d_surge_n": state.tau_d_surge_n - surge_n,
                                        "tau_d_yaw_nm": state.tau_d_yaw_nm - yaw_nm})

    def _period(self, now_ns: int, state: StateEstimate, mono_ns: int | None,
                given: tuple[float, float]) -> tuple[ThrustCommand, SolveRecord | None, MissionStatus]:
        """``step`` for a state found sane, its disturbance without a loss the plan models."""
        x0 = np.array([state.u_mps, state.v_mps, state.r_radps, state.x_m, state.y_m,
                       state.psi_rad])
        self._account_energy(now_ns, mono_ns)
        self._last_state = state
        mm = self.missions
        mm.update(state.x_m, state.y_m)
        self.route_seen(now_ns, state)  # a mission accepted before any state: its way from here
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
                thrust = command_for(*hold_thrust(tuple(x0), point, tau, self.vessel,
                                                  self.config.hold), given, self.vessel)
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
                         (self._mission_serial, mm.active), tau_d, given)
        res = out.result
        budget = self.config.solve_budget_s
        late = budget is not None and res.solve_time_s > budget
        if res.success and not late:
            ctrl.accept(out)
            self.consecutive_failures = 0
            thrust = (float(out.plan.thrusts_n[0, 0]), float(out.plan.thrusts_n[0, 1]))
            self._set_level(LEVEL_MPC, res.status)
            source, used = mission.controller, out
            self._energy_to_go_j = finite_or_none(out.costs.energy_to_go_j)
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
                thrust = command_for(*los_thrust(tuple(x0), wp_prev, wp_act, self.vessel,
                                                 self.config.los, mission.speed_hint_mps),
                                     given, self.vessel)
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
            cmd, _, status = self._period(now_ns, state, mono_ns, given)
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

    # -- holding station ------------------------------------------------------------------------

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

    def _absurd(self, state: StateEstimate) -> str | None:
        """Why ``state`` can be no vessel's (None: it can be): body speeds or a disturbance past
        the vessel's envelope, a position past any local frame, a covariance that is not one."""
        env = self._envelope
        why = env.absurd(state.u_mps, state.v_mps, state.r_radps)
        if why is None:
            why = env.absurd_disturbance(state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm)
        if why is None and not (abs(state.x_m) <= MAX_RANGE_M and abs(state.y_m) <= MAX_RANGE_M):
            why = (f"position ({state.x_m:.3g}, {state.y_m:.3g}) m is more than {MAX_RANGE_M:g} m "
                   "from the origin, past any local frame")
        if why is None and state.covariance is not None:
            cov = state.covariance  # row-major 9x9: its diagonal is every 10th entry
            if not max(map(abs, cov)) <= MAX_COVARIANCE_ENTRY or min(cov[::10]) < 0:
                why = (f"the covariance has a negative variance or an entry past "
                       f"{MAX_COVARIANCE_ENTRY:g}")
        return why

    def _command(self, stamp_ns: int, thrust: tuple[float, float], source: str) -> ThrustCommand:
        # Built (and validated: finite) before it is kept: a NaN kept as the last command would
        # poison the hold's energy count and every status after it.
        cmd = ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=thrust[0],
                                 thrust_starboard_n=thrust[1], source=source, seq=self.seq)
        self._last_command = thrust
        return cmd

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
                cost_stage_j=finite_or_none(c.stage_j), cost_dynamic_j=finite_or_none(c.dynamic_j),
                cost_static_j=finite_or_none(c.static_j), cost_track_j=finite_or_none(c.track_j),
                t_d_s=finite_or_none(c.t_d_s), t_s_s=finite_or_none(c.t_s_s),
                leg_energy_to_go_j=finite_or_none(c.energy_to_go_j),
                cross_track_m=finite_or_none(c.cross_track_m))
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
