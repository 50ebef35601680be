"""The energy budget of one mission (issue #17): when it is priced, and the return decision. Pure:
states, battery reports and the MPC's leg energy in, ``EnergyBudget`` out. The energies it prices
are ``seaway_controller.energy``'s (its prediction, band and point of no return).

The battery's remaining energy now is its last report less the energy the controller counted since
that report's stamp (reports come at ~1 Hz, from an autopilot or the lockstep sim). The margin
is remaining - (energy to home + reserve) [J]. The budget is priced once a second
(``BUDGET_INTERVAL_NS``) and when the active leg changes, and every period once the margin is near
0 (``FINE_PRICING_SECONDS``); the mission's policy acts at the first pricing at which the margin
has reached 0, so at the period it would have acted priced every period: ``warn`` (flag it, fly
on), ``return`` (fly home), ``hold`` (stop). Never early. A crossing the pricings did not see
coming (the margin fell from above three seconds' worth, at the rate it fell since the last
pricing, to 0 within one second without a leg change; no way home at all; short from the first
pricing) acts once it has lasted ``SUDDEN_DECIDE_S``. The decision stays with the mission (a
mission it held that the operator resumes once the margin is above 0 again, after a battery swap,
is decided afresh: ``seaway_controller.core_energy``); its inputs are all on the bus (state,
battery, solve record, mission), so a replay of the recording decides the same at the same period
(``seaway_controller.replay`` is that replay).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from seaway.contract.messages import EnergyBudget, EnergyDecision, LowEnergyPolicy, StateEstimate
from seaway.vessel.energy_prediction import band_factors

from seaway_controller.energy import (
    Disturbance,
    EnergyModel,
    disturbance_sigma_points,
    finite_or_none,
    no_return_point,
    predict,
    predict_many,
)

BUDGET_INTERVAL_NS = 1_000_000_000
"""The budget is priced at the first period of each whole second of the controller's clock (the
states' stamps: simulated time in lockstep, so a replay prices the same periods), and at the period
the active leg changes [ns]. An autopilot reports its battery about as often. Pricing it every
period would put a large share of the controller's CPU on lockstep's critical path for figures
that move a few joules a period."""
SUDDEN_DECIDE_S = 5.0
"""A margin at or below 0 that the budget did not see coming decides the policy only once every
pricing has found it so for this long [s]. Two kinds: no way home at all (the estimated disturbance
stronger than the cruise, so no finite energy home), and a finite margin that fell past 0 from a
pricing that was not yet near it (``Budget.foreseen`` off). One state just after the estimator re-opened
its uncertainty, or re-initialised after a divergence, can swing past anything the vessel can beat
for a second or two, or price the way home at many times its energy; flying the mission's policy
on it is a false return. A margin that fell to 0 as the fine pricing saw it coming
(``FINE_PRICING_SECONDS``) decides at once."""
FINE_PRICING_SECONDS = 3.0
"""Once the margin is no more than this many seconds from 0, falling at the rate it fell since the
last pricing, the budget is priced every period until its decision [s]. A straight-line forecast
between pricings was tried: a margin falling faster and faster (a turn) crossed 0 before the forecast
did (decided late), and a rate taken over a leg change's 0.1 s magnified one battery report's step
(decided 2 s early)."""


@dataclass
class Budget:
    """The energy budget of one mission: ``update`` when ``due``, ``last`` to publish."""

    model: EnergyModel
    waypoints: list[tuple[float, float]]
    home: tuple[float, float]
    policy: LowEnergyPolicy
    mission_id: str = ""
    returning: bool = False
    decision: EnergyDecision = "none"
    decided_ns: int | None = None
    reason: str = ""
    last: EnergyBudget | None = field(default=None, repr=False)
    next_ns: int | None = None  # when the next pricing is due [ns] (None: at the next period)
    priced_leg: int | None = None  # the active leg at the last pricing
    priced_ns: int | None = None  # the stamp of the last pricing [ns]
    priced_margin: tuple[int, float] | None = None  # (stamp [ns], margin [J]) at the last pricing
    fine: bool = False  # priced every period: the margin is near 0 (``FINE_PRICING_SECONDS``)
    foreseen: bool = False  # ``fine`` began at a margin still above 0: a crossing was seen coming
    controller: str = ""  # whose measured error widens the band (``band_factors``; "": not widened)
    sudden_since_ns: int | None = None  # pricings since then found an unforeseen margin <= 0 [ns]

    def due(self, now_ns: int, active: int) -> bool:
        """Whether to price the budget at the period ``now_ns`` with leg ``active`` active: the
        mission's first two periods (the second gives the margin's rate), a new whole second
        (``BUDGET_INTERVAL_NS``), a new leg, any period once the margin is near 0, or a stamp
        before the last pricing's (a wall clock stepped back: else not priced until it caught up)."""
        return (self.next_ns is None or now_ns >= self.next_ns or active != self.priced_leg
                or now_ns < (self.priced_ns or 0))

    def _schedule(self, now_ns: int, margin_j: float | None) -> None:
        """When to price next, after a pricing at ``now_ns`` found ``margin_j`` [J]."""
        whole_ns = (now_ns // BUDGET_INTERVAL_NS + 1) * BUDGET_INTERVAL_NS
        undecided = self.decision == "none" and not self.returning
        if margin_j is None or not math.isfinite(margin_j) or not undecided:
            self.next_ns = whole_ns
            return
        before = self.priced_margin
        if before is not None and now_ns > before[0] and not self.fine:
            fall_j_per_s = (before[1] - margin_j) * 1e9 / (now_ns - before[0])
            self.fine = fall_j_per_s > 0 and margin_j <= FINE_PRICING_SECONDS * fall_j_per_s
            self.foreseen = self.fine and margin_j > 0
        # No rate yet (the budget's first pricing): the next period gives one.
        self.next_ns = now_ns + 1 if self.fine or before is None else whole_ns
        self.priced_margin = (now_ns, margin_j)

    def _judge_crossing(self, now_ns: int, margin_j: float, unreachable: bool) -> None:
        """Whether the margin ``margin_j`` [J] priced at ``now_ns`` is at or below 0 without the
        pricings before having seen it coming (``SUDDEN_DECIDE_S``): ``sudden_since_ns`` is then
        the first pricing of that run, else None. ``foreseen`` is set only at a margin above 0, so
        it cannot turn on within a run; a stamp before the run's start (a wall clock stepped back)
        begins a new one. A sudden run that passes ends the pricing every period it began."""
        if margin_j > 0:
            if self.sudden_since_ns is not None:  # it passed: so does the pricing every period
                self.fine = self.foreseen = False
            self.sudden_since_ns = None
        elif self.foreseen and not unreachable:
            self.sudden_since_ns = None  # seen coming: decides at once
        elif self.sudden_since_ns is None or now_ns < self.sudden_since_ns:
            self.sudden_since_ns = now_ns

    def to_home_j(self, state: StateEstimate, active: int,
                  home: tuple[float, float] | None = None) -> float:
        """The energy to get to ``home`` (local NED [m]; None: this budget's home) from ``state``,
        under the disturbance estimated now: the nominal of ``update``'s pricing [J]; inf: no way
        there. What a return target, a new home and a resume are judged by."""
        dist = Disturbance.from_body((state.tau_d_surge_n, state.tau_d_sway_n, state.tau_d_yaw_nm),
                                     state.psi_rad)
        return predict(self.model, state, self.waypoints, active,
                       self.home if home is None else home, None, dist).to_home_j

    def update(self, now_ns: int, state: StateEstimate, active: int, leg_mpc_j: float | None,
               energy_used_j: float, battery_remaining_j: float | None, battery_stamp_ns: int | None,
               reserve_j: float | None) -> EnergyDecision | None:
        """Price the budget now (``last``; the caller asks ``due`` first); the decision if it was
        taken now, else None."""
        self.priced_leg, self.priced_ns = active, now_ns
        nominal, sigmas = disturbance_sigma_points(state)
        pred, *spread = predict_many(self.model, state, self.waypoints, active, self.home,
                                     leg_mpc_j, [nominal, *sigmas])
        low_factor, high_factor = band_factors(self.controller)
        to_go = [p.to_go_j for p in spread] + [pred.to_go_j]
        to_home = [p.to_home_j for p in spread] + [pred.to_home_j]
        reserve = reserve_j or 0.0
        margin = finish_margin = None
        pnr = None
        taken: EnergyDecision | None = None
        if battery_remaining_j is not None:
            margin = battery_remaining_j - pred.to_home_j - reserve
            finish_margin = battery_remaining_j - pred.to_go_j - reserve
            if not self.returning:
                pnr = no_return_point(self.model, state, self.waypoints, active, self.home,
                                      battery_remaining_j, reserve, nominal)
            unreachable = not math.isfinite(pred.to_home_j)
            self._judge_crossing(now_ns, margin, unreachable)
            persisted = (self.sudden_since_ns is None
                         or now_ns - self.sudden_since_ns >= round(SUDDEN_DECIDE_S * 1e9))
            if margin <= 0 and persisted and self.decision == "none" and not self.returning:
                taken = self.decision = self.policy
                self.decided_ns = now_ns
                if not unreachable:
                    self.reason = (f"energy to get home {pred.to_home_j:.0f} J + reserve "
                                   f"{reserve:.0f} J reached the battery's {battery_remaining_j:.0f} J left")
                else:  # not 'inf J': the vessel makes no way home (MIN_SPEED_FRAC)
                    self.reason = ("the way home cannot be made good at the cruise under the "
                                   f"estimated disturbance (battery {battery_remaining_j:.0f} J left, "
                                   f"reserve {reserve:.0f} J)")
        self._schedule(now_ns, margin)
        self.last = EnergyBudget.make(
            stamp_ns=state.stamp_ns, mission_id=self.mission_id, active_leg=active,
            returning=self.returning, energy_used_j=max(0.0, energy_used_j),
            leg_energy_to_go_j=finite_or_none(leg_mpc_j), energy_to_go_j=finite_or_none(pred.to_go_j),
            energy_to_go_low_j=finite_or_none(min(to_go) * low_factor),
            energy_to_go_high_j=finite_or_none(max(to_go) * high_factor),
            energy_to_home_j=finite_or_none(pred.to_home_j),
            energy_to_home_low_j=finite_or_none(min(to_home)),
            energy_to_home_high_j=finite_or_none(max(to_home)), home_x_m=self.home[0],
            home_y_m=self.home[1], battery_remaining_j=battery_remaining_j,
            battery_stamp_ns=battery_stamp_ns, reserve_j=reserve_j, margin_j=finite_or_none(margin),
            finish_margin_j=finite_or_none(finish_margin),
            no_return_x_m=None if pnr is None else pnr[0],
            no_return_y_m=None if pnr is None else pnr[1],
            no_return_along_m=None if pnr is None else pnr[2], policy=self.policy,
            decision=self.decision, decided_ns=self.decided_ns, reason=self.reason[:300])
        return taken
