"""Fly a recorded mission again through the controller's core: the mission as accepted
(``mission/accepted``), and the states (``nav/state``) and battery reports (``vehicle/battery``) the
controller heard, in the order lockstep gave them (each period's battery before its state). What
comes out is what the controller decides from them: the commands, the energy budgets and the
return decision. A lockstep recording replays to the same decision at the same period
(tests/system/launch/test_energy_return.py); a real-time one only approximately (the order of a
battery report and a state there depends on the wall clock).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    MissionAccepted,
    MissionRequest,
    StateEstimate,
    ThrustCommand,
    Waypoint,
)
from seaway.vessel.model import VesselParams

from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore


@dataclass
class Replayed:
    """What the core decided, period by period."""

    commands: list[ThrustCommand] = field(default_factory=list)
    budgets: list[EnergyBudget] = field(default_factory=list)

    def decision(self) -> tuple[int | None, str]:
        """(period, decision) of the first energy decision, or (None, 'none')."""
        b = next((b for b in self.budgets if b.decision != "none"), None)
        return (b.decided_ns, b.decision) if b is not None else (None, "none")


def request_of(accepted: MissionAccepted) -> MissionRequest:
    """The request an accepted mission was (its NED waypoints, settings and energy policy)."""
    home = (Waypoint(x_m=accepted.home_x_m, y_m=accepted.home_y_m)
            if accepted.home_x_m is not None and accepted.home_y_m is not None else None)
    return MissionRequest.make(
        stamp_ns=accepted.accepted_ns, mission_id=accepted.mission_id, waypoints=accepted.waypoints,
        coa_radius_m=accepted.coa_radius_m, task_power_w=accepted.task_power_w,
        controller=accepted.controller, predict_disturbance=accepted.predict_disturbance,
        speed_hint_mps=accepted.speed_hint_mps, on_low_energy=accepted.on_low_energy, home=home,
        join_first_leg=accepted.join_first_leg, at_rest=accepted.at_rest,
        on_area_breach=accepted.on_area_breach, force=accepted.forced)


def replay(accepted: MissionAccepted, vessel: VesselParams, states: Iterable[StateEstimate],
           batteries: Iterable[BatteryState], config: ControllerConfig | None = None) -> Replayed:
    """Step a fresh core through ``states`` (time order), the mission accepted at the period
    ``accepted.accepted_ns`` (before that period's step, as lockstep does), each battery report
    given before the first state at or after its stamp. ``config``: the controller's horizon and
    profile are taken from the mission's recorded settings; nothing is ever late."""
    cs = accepted.controller_settings
    config = config or ControllerConfig(
        horizon=int(cs.get("horizon_steps", 10)), dt_s=cs.get("dt_s", 0.1),
        profile_n=cs.get("profile_n", 2.0), solve_budget_s=None)
    core = ControllerCore(vessel, config)
    pending = sorted(batteries, key=lambda b: b.stamp_ns)
    out, started, i = Replayed(), False, 0
    for state in states:
        while i < len(pending) and pending[i].stamp_ns <= state.stamp_ns:
            core.on_battery(pending[i])
            i += 1
        if not started and state.stamp_ns >= accepted.accepted_ns:
            reply = core.handle_mission(state.stamp_ns, request_of(accepted))
            if not reply.accepted:
                raise ValueError(f"the recorded mission is refused now: {reply.reason}")
            started = True
        cmd, _, _ = core.step(state.stamp_ns, state)
        out.commands.append(cmd)
        budget = core.take_budget()
        if budget is not None:
            out.budgets.append(budget)
    return out
