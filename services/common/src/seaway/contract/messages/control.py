"""Control and mission (producer: the controller)."""

from __future__ import annotations

from typing import ClassVar, Literal

from pydantic import Field

from seaway.contract.messages.base import MAX_REASON_CHARS, Message


class ThrustCommand(Message):
    """Thrust per thruster in newtons (paper's T^1 port, T^2 starboard).

    ``stamp_ns`` is the stamp of the state the command was computed from, so latency is measurable.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.ThrustCommand"
    thrust_port_n: float = Field(description="T^1, port thruster, positive ahead [N]")
    thrust_starboard_n: float = Field(description="T^2, starboard thruster, positive ahead [N]")
    source: str = Field(default="", description="who computed it: 'cc-empc', 'los', 'stop', ...")
    seq: int = Field(default=0, ge=0)


SOLVER_NOT_READY = "no solver yet"
"""How a ``SolveRecord.status`` begins for a period with no solver to call yet (its fast solver
being loaded or made, the reference being set up): flown on a fallback, and not a failed solve."""


class SolveRecord(Message):
    """One MPC solve: outcome, timing, prediction and the cost split by term (paper eq. 14)."""

    SCHEMA: ClassVar[str] = "seaway.v1.SolveRecord"
    controller: str
    status: str
    success: bool
    iterations: int = Field(ge=0)
    solve_time_s: float = Field(ge=0)
    fallback_level: int = Field(default=0, ge=0, description="0 solver, 1 shifted plan, 2 LOS, 3 stop")
    fallback_count: int = Field(default=0, ge=0)
    cost_stage_j: float | None = None
    cost_dynamic_j: float | None = Field(default=None, description="E_d = P_d * t_d [J]")
    cost_static_j: float | None = Field(default=None, description="E_s = P_s * t_s [J]")
    cost_track_j: float | None = Field(default=None, description="Y [J]")
    t_d_s: float | None = None
    t_s_s: float | None = None
    leg_energy_to_go_j: float | None = Field(default=None, description="predicted energy to reach "
                                             "the active waypoint: horizon + E_d + E_s [J]")
    cross_track_m: float | None = None
    predicted_x_m: list[float] = Field(default_factory=list)
    predicted_y_m: list[float] = Field(default_factory=list)
    predicted_psi_rad: list[float] = Field(default_factory=list)
    predicted_thrust_port_n: list[float] = Field(default_factory=list)
    predicted_thrust_starboard_n: list[float] = Field(default_factory=list)


MissionState = Literal["idle", "waiting", "active", "paused", "complete", "aborted"]
"""``waiting``: accepted, but the vehicle does not apply the commanded thrust yet (disarmed, a mode
that withholds it, no link); it becomes ``active`` by itself once the vehicle does
(``MissionStatus.reason`` says what it waits for)."""
AtRest = Literal["hold", "drift"]
"""What the vessel does after the last waypoint and while the operator pauses the mission: ``hold``
station at a point (the default) or ``drift`` (zero thrust)."""
"""A mission's state: idle -> active <-> paused -> complete | aborted (the controller's machine)."""


class MissionStatus(Message):
    """Progress of the active mission."""

    SCHEMA: ClassVar[str] = "seaway.v1.MissionStatus"
    state: MissionState
    mission_id: str = ""
    active_leg: int = Field(default=0, ge=0, description="index i of the active waypoint P_i")
    waypoint_count: int = Field(default=0, ge=0)
    distance_to_waypoint_m: float | None = None
    cross_track_m: float | None = None
    energy_used_j: float | None = None
    energy_to_go_j: float | None = Field(default=None, description="predicted energy to finish the "
                                         "mission (``EnergyBudget.energy_to_go_j``) [J]")
    leg_energy_to_go_j: float | None = Field(default=None, description="predicted energy to reach "
                                             "the active waypoint (the MPC's plan) [J]")
    reason: str = Field(default="", max_length=MAX_REASON_CHARS, description="what the operator "
                        "did not ask for but should know about the mission's state: why the "
                        "controller paused it (e.g. the vehicle was disarmed), or how it is flown "
                        "meanwhile; empty otherwise")
    hold_x_m: float | None = Field(default=None, description="holding station at this point, local "
                                   "NED north [m] (after the last waypoint, or paused); None when not")
    hold_y_m: float | None = Field(default=None, description="the hold point, local NED east [m]")
    hold_energy_j: float | None = Field(default=None, description="energy used holding station since "
                                        "the hold began: propulsion + T^w [J]")


LowEnergyPolicy = Literal["warn", "return", "hold"]
AreaBreachPolicy = Literal["hold", "return"]
"""What the controller does when the vessel or the MPC's predicted course would leave the operating
area in flight: 'hold' station where it is, or 'return' home (or to the nearest rally point)."""
"""What a mission does when the energy to get home plus the reserve reaches the battery's remaining
energy: ``warn`` (say so, fly on), ``return`` (fly straight home, the default), ``hold`` (stop)."""
EnergyDecision = Literal["none", "warn", "return", "hold"]


def return_mission_id(mission_id: str) -> str:
    """The id of the return home the energy budget flies in place of ``mission_id`` (64 chars at
    most, the end kept)."""
    return f"{mission_id}/return"[-64:]


BatteryEstimateSource = Literal["count", "autopilot", "voltage"]
"""Where the energy budget's battery figure came from, the lowest of: ``count`` (the first report's
energy less what the controller counted since), ``autopilot`` (the autopilot's latest remaining,
less what was counted since it), ``voltage`` (the pack's voltage on the vessel file's battery
model, ``seaway.vessel.battery``)."""


class EnergyBudget(Message):
    """Will it make it back: the energy to finish and to get home against the battery, at each
    pricing of an active mission's budget (``mission/energy``; ``seaway_controller.budget``: once a
    second, at each new leg, and every control period once the margin is near 0).

    Predictions come from the controller's own model and cost at its economic cruise under the
    estimated disturbance; ``*_low_j``/``*_high_j`` are the band from the estimate's disturbance
    covariance (one standard deviation each way). Frames: local NED [m].
    """

    SCHEMA: ClassVar[str] = "seaway.v1.EnergyBudget"
    mission_id: str = ""
    active_leg: int = Field(default=0, ge=0)
    returning: bool = Field(default=False, description="the mission is the return home")
    energy_used_j: float = Field(ge=0, description="energy used since the mission started [J]")
    leg_energy_to_go_j: float | None = Field(default=None, description="to the active waypoint, "
                                             "from the MPC's plan [J]")
    energy_to_go_j: float | None = Field(default=None, description="to finish the mission [J]")
    energy_to_go_low_j: float | None = None
    energy_to_go_high_j: float | None = None
    energy_to_home_j: float | None = Field(default=None, description="from here straight home [J]")
    energy_to_home_low_j: float | None = None
    energy_to_home_high_j: float | None = None
    home_x_m: float
    home_y_m: float
    battery_remaining_j: float | None = Field(default=None, description="the battery's usable "
                                              "energy left now: its last report less what the "
                                              "controller counted since [J]")
    battery_stamp_ns: int | None = Field(default=None, ge=0, description="stamp of that report")
    reserve_j: float | None = Field(default=None, ge=0)
    margin_j: float | None = Field(default=None, description="remaining - (to home + reserve): the "
                                   "decision is due when it reaches 0 [J]")
    finish_margin_j: float | None = Field(default=None, description="remaining - (to finish + "
                                          "reserve): below 0 the mission cannot end with the "
                                          "reserve left [J]")
    no_return_x_m: float | None = Field(default=None, description="point of no return along the "
                                        "path ahead: where margin_j is predicted to reach 0 [m]")
    no_return_y_m: float | None = None
    no_return_along_m: float | None = Field(default=None, ge=0, description="how far along the "
                                            "path ahead that point is [m]")
    policy: LowEnergyPolicy
    decision: EnergyDecision = Field(description="'none' until the margin reached 0, then what "
                                     "the policy did, from that period on")
    decided_ns: int | None = Field(default=None, ge=0, description="the period it was decided")
    reason: str = Field(default="", max_length=MAX_REASON_CHARS)
    battery_source: BatteryEstimateSource | None = Field(
        default=None,
        description="which estimate battery_remaining_j is, the lowest of them "
                    "(BatteryEstimateSource); None: no battery report yet")


def mission_over(status: MissionStatus | None, budget: EnergyBudget | None,
                 mission_id: str | None = None) -> bool:
    """Whether the newest ``status`` says there is nothing more to fly of ``mission_id`` (None:
    of whatever mission it is): it is complete, or the return home its energy budget decided
    (``return_mission_id``) is, or the budget held it (``budget``: the newest, policy 'hold')."""
    if status is None:
        return False
    if mission_id is not None and status.mission_id not in (mission_id, return_mission_id(mission_id)):
        return False
    held = (status.state == "paused" and budget is not None and budget.decision == "hold"
            and budget.mission_id == status.mission_id)
    return status.state == "complete" or held
