"""The controller core's energy part: the energy counted, the battery, and the mission's budget.

Every period, the energy of the last command over the time since (propulsion, alpha (T1^2 + T2^2),
plus the mission's task power T^w) [J] is counted to the battery always and to the mission while it
is active (``_account_energy``); the time since is measured on the clock ``step`` is given for
intervals (real time: the monotonic clock, so that a wall clock stepped by NTP or GPS time counts
no energy the vessel never used). What
the battery has left is its last report less what was counted
since (``BatteryTrack``). The mission's energy budget (``seaway_controller.budget.Budget``) prices the
way to the end and the way home against it when due, and at the pricing that finds the margin at 0
takes the mission's policy: warn, hold, or return to the cheapest of home and the rally points
(``_update_budget``, ``_return_home``). Priced while the mission is active, paused and while the
vessel holds station at rest after it: the battery goes on falling meanwhile. A mission the budget
held is resumed only once the battery reaches home again, and its budget then decides afresh
(``_budget_resume``, ``_rearm_budget``).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from seaway.contract.messages import (
    MAX_REASON_CHARS,
    BatteryState,
    EnergyBudget,
    EnergyDecision,
    MissionRequest,
    Reply,
    StateEstimate,
    Waypoint,
    return_mission_id,
)
from seaway.vessel.model import VesselParams, propulsion_power_w

from seaway_controller.area_guard import AreaGuard
from seaway_controller.battery_estimate import BatteryTrack
from seaway_controller.budget import Budget
from seaway_controller.energy import (
    Disturbance,
    EnergyModel,
    finite_or_none,
    predict,
)
from seaway_controller.mission import Mission, MissionManager
from seaway_controller.mpc import MpcOutcome

if TYPE_CHECKING:
    from seaway_controller.config import ControllerConfig

MAX_REPORT_OFFSET_NS = 5 * 10**9
"""A battery report stamped further than this from the last step [ns] counts nothing since it:
reports come every second or so, stamped on the same wall clock; further apart, that clock stepped."""

log = logging.getLogger("seaway_controller.core")


@dataclass(frozen=True)
class BudgetDecision:
    """What the energy budget decided for the current mission (kept across a restart)."""

    returning: bool = False
    """The mission is the budget's return home."""
    decision: EnergyDecision = "none"
    decided_ns: int | None = None
    reason: str = ""


class EnergyAccount:
    """The energy part of ``ControllerCore``: owns the counts, the battery's track and the budget."""

    # read from the other parts
    vessel: VesselParams
    config: ControllerConfig
    missions: MissionManager
    mission_request: MissionRequest | None
    area: AreaGuard
    energy_used_j: float
    _last_state: StateEstimate | None
    _holding: tuple[float, float] | None
    handle_mission: Callable[..., Reply]

    def _init_energy(self, vessel: VesselParams) -> None:
        # The battery's last report, the energy counted since the process started (propulsion +
        # T^w, whatever the mission's state: the battery feeds the task while paused too), the
        # current mission's budget, its last message.
        self.battery = BatteryTrack(vessel.battery)
        self.energy_counted_j = 0.0
        self.budget: Budget | None = None
        self._budget_msg: EnergyBudget | None = None
        self.hold_energy_j = 0.0  # counted since the current hold began
        self._last_step_ns: int | None = None  # the last step's time [ns, wall in real time]
        self._last_step_mono_ns: int | None = None  # the same step on the clock of intervals [ns]
        self._last_command = (0.0, 0.0)

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

    def _home_shortfall(self, home: tuple[float, float]) -> str | None:
        """Why the mission under way may not take ``home`` (local NED [m]) as its home: its energy
        budget would act on it at once (policy 'return' or 'hold', not decided yet), the way
        there from where the vessel is and the battery's reserve needing more than is left, and
        more than the way to its home now (a nearer home is always taken). None otherwise, or
        when it cannot be known (no state, no battery report). Priced as the budget prices it
        (``Budget.update``: the nominal disturbance), so that a home taken does not turn the
        mission into a return, or a stop, that nobody asked for."""
        b, st, left = self.budget, self._last_state, self.battery_remaining_j()
        if (b is None or st is None or left is None or b.returning or b.decision != "none"
                or b.policy == "warn"):
            return None
        active = self.missions.active
        now_j, new_j = b.to_home_j(st, active), b.to_home_j(st, active, home)
        reserve = self._reserve_j() or 0.0
        if left - new_j - reserve > 0 or not new_j > now_j:
            return None
        def needs(j: float) -> str:
            return f"about {j:.0f} J" if math.isfinite(j) else "more than any battery (no way " \
                "there at the cruise under the estimated disturbance)"

        action = "fly home" if b.policy == "return" else "stop"
        return (f"the way there from where the vessel is needs {needs(new_j)} and the battery has "
                f"{left - reserve:.0f} J above its {reserve:.0f} J reserve: the energy budget of "
                f"mission {b.mission_id!r} (policy '{b.policy}') would {action} at once; "
                f"give a home the battery reaches (the current one, at north {b.home[0]:.1f} m, "
                f"east {b.home[1]:.1f} m, needs {needs(now_j)}), or abort the mission first")

    def _budget_resume(self) -> str | None:
        """Before the operator resumes the paused mission: why not, when its energy budget held
        it (policy 'hold') and its margin, as last priced, is still at or below 0 (or not known:
        no way home); None otherwise. Resumed, a held mission flew on with the decision taken, so
        its budget never acted again: to the empty battery. ``MissionCommand`` has no ``force``;
        a mission request does (``MissionRequest.force``), so flying on regardless stays the
        operator's explicit, recorded choice."""
        b, st, left = self.budget, self._last_state, self.battery_remaining_j()
        if b is None or b.decision != "hold" or b.returning:
            return None
        margin = None  # priced now: a battery changed since the last pricing counts at once
        if st is not None and left is not None:
            margin = left - b.to_home_j(st, self.missions.active) - (self._reserve_j() or 0.0)
        if margin is not None and margin > 0:
            return None
        left = "not known" if margin is None or not math.isfinite(margin) else f"{margin:.0f} J"
        return (f"cannot resume: the energy budget held the mission ({b.reason}) and its margin "
                f"over the way home and the reserve is still {left}; send a mission home, or "
                "this one again with force and on_low_energy 'warn' to fly it anyway; the mission "
                "stays paused")

    def _rearm_budget(self) -> None:
        """The operator resumed a mission its energy budget had held, the margin above 0 again
        (a battery changed or charged): the budget decides afresh, so that its policy acts at
        the next crossing as at the first."""
        b = self.budget
        if b is not None and b.decision == "hold" and not b.returning:
            b.decision, b.decided_ns, b.reason = "none", None, ""
            b.sudden_since_ns, b.next_ns = None, None  # priced at the next period

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

    def decision(self) -> BudgetDecision:
        """The current mission's energy budget decision, as a checkpoint keeps it."""
        b = self.budget
        if b is None:
            return BudgetDecision()
        return BudgetDecision(b.returning, b.decision, b.decided_ns, b.reason)

    def on_battery(self, report: BatteryState) -> None:
        """The battery's latest report: what is left is counted down from it until the next."""
        self.battery.report = report
        self.battery.counted_at_report_j = self._counted_at(report.stamp_ns)

    def _counted_at(self, t_ns: int) -> float:
        """The energy counted up to ``t_ns`` [J]: the count at the last step, plus (or minus) the
        last command's power over the time from that step."""
        if self._last_step_ns is None:
            return self.energy_counted_j
        if abs(t_ns - self._last_step_ns) > MAX_REPORT_OFFSET_NS:
            # Not a report of about now: a wall clock stepped between the step and the report's
            # stamp (NTP, GPS time), which an hour's power would turn into a phantom 900 kJ.
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
        leg_j = finite_or_none(used.costs.energy_to_go_j) if used is not None else None
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
            target = self.area.return_target(
                (state.x_m, state.y_m), budget.home,
                lambda p: budget.to_home_j(state, mm.active, p))
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

    def _account_energy(self, now_ns: int, mono_ns: int | None = None) -> None:
        """Energy of the last command over the time since: alpha (T1^2 + T2^2) + T^w [J], to the
        mission's count while it is active and to the battery's count always. The time since is
        measured on ``mono_ns`` [ns, monotonic] when given (real time), else on ``now_ns`` (lockstep:
        simulated time, which never steps)."""
        mm = self.missions
        clock_ns = now_ns if mono_ns is None else mono_ns
        if self._last_step_mono_ns is not None:
            dt = max(0.0, (clock_ns - self._last_step_mono_ns) / 1e9)
            energy = self._power_w() * dt
            self.energy_counted_j += energy
            if mm.state == "active" and mm.mission is not None:
                self.energy_used_j += energy
            elif self._holding is not None:
                self.hold_energy_j += energy
        self._last_step_ns, self._last_step_mono_ns = now_ns, clock_ns

    def take_budget(self) -> EnergyBudget | None:
        """The budget priced at the last step, once (None: none was, or no active mission was
        stepped)."""
        msg, self._budget_msg = self._budget_msg, None
        return msg
