"""The controller core's vehicle part: what the autopilot's status allows a mission to do.

While the autopilot does not apply the commanded thrust (``VehicleStatus.thrust_withheld``:
disarmed, no link, a mode such as HOLD after a failsafe), flying the mission only pretends: the boat
does not move, the energy count rises. So an active mission is paused, with the reason in
``MissionStatus.reason``, and resumes only on the operator's request once the vehicle applies the
thrust again (a rebooted autopilot must not drive off on its own when someone re-arms it). Only
statuses stamped from the mission's start on count: the one before may predate the arming its sender
just did. An autopilot that is not healthy (``thrust_withheld`` 'autopilot_unhealthy': its estimator
not using GNSS, a critical status) keeps a new mission waiting but does not pause one under way (its
own failsafes act on that); and a paused mission is not resumed while the autopilot is latched in a
failsafe (``VehicleStatus.failsafe_latched``).

A mission sent while the latest status says the thrust is withheld is accepted as ``waiting`` (never
"started"), the reply and ``MissionStatus.reason`` saying for what; it becomes active by itself at
the first status stamped from its acceptance on that says the vehicle applies the thrust (the
launcher arms and sets the mode, then sends the mission: the status it last heard may be the one
before the arming). Lockstep has no vehicle_io: no status, no wait.
"""

from __future__ import annotations

import logging

from seaway.contract.messages import HOLD_REASON_TEXT, THRUST_APPLIED_ANYWAY, StateEstimate, VehicleStatus

from seaway_controller.mission import PAUSED_PREFIX, MissionManager

log = logging.getLogger("seaway_controller.core")


def waiting_for(why: str) -> str:
    """A waiting mission's reason: what the vehicle lacks (``why``) and what starts it."""
    return (f"waiting for the vehicle: {why}; the mission starts by itself once the vehicle "
            "applies the thrust (arm it, set its mode)")


def latched_reason(v: VehicleStatus | None) -> str | None:
    """Why a paused mission may not resume although the thrust is applied: the autopilot still
    stands in a failsafe (``VehicleStatus.failsafe_latched``), named; None: it does not."""
    if v is None or v.failsafe_latched is None:
        return None
    return (f"the autopilot is still latched in {HOLD_REASON_TEXT[v.failsafe_latched]} "
            f"({v.failsafe_latched_detail[:120]})")


class VehicleGate:
    """The vehicle part of ``ControllerCore``: the latest status, and the pause or start of the
    mission it calls for."""

    # read from the other parts
    missions: MissionManager
    home: tuple[float, float] | None
    _last_state: StateEstimate | None
    _mission_start_ns: int

    def _init_vehicle(self) -> None:
        self.vehicle: VehicleStatus | None = None  # the latest status heard (None: no vehicle_io)

    def on_vehicle_status(self, status: VehicleStatus) -> str | None:
        """The vehicle's status, in the order vehicle_io published them: pauses an active mission
        while the autopilot does not apply the commanded thrust, starts a waiting one once it does
        (see the module docstring). What it changed now (for a person), else None."""
        was, st = self.vehicle, self._last_state
        # Home is where the vessel was armed. The first status heard (was None) is no arming seen:
        # after a restart the vessel is armed already and its home is the one kept (checkpoint).
        armed_now = not was.armed if was is not None else self.home is None
        if status.armed and armed_now and st is not None:
            self.home = (st.x_m, st.y_m)
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
                self.missions.wait(waiting_for(why))
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
