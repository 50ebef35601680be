"""After the vehicle link was interrupted: resume the mission it paused, or end it.

The link to the autopilot is interrupted when vehicle_io or the sim (the simulated autopilot) dies
and the launcher restarts it, and when vehicle_io loses the autopilot's HEARTBEAT for its
``heartbeat_timeout_s`` (a stalled autopilot, a cable or radio dropout) and finds it again. Meanwhile
the thrust did not reach the thrusters, so the controller paused the mission
(``MissionStatus.reason``) and, by design, resumes it only when asked. Nobody asked: the mission
stayed paused for good and the launcher never finished. Now the launcher, which started the mission,
asks (its operator identity, the normal authority path), for a mission paused within
``PAUSE_WITHIN_S`` of an interruption:

* once vehicle_io reports the link up with the autopilot **armed**, it sends the profile's start-up
  mode again (a link-loss failsafe leaves the autopilot in HOLD) and then ``resume``;
* it does not arm a **disarmed** autopilot, nor resume once it heard one since the interruption (a
  rebooted autopilot: whether the vessel may drive off again is the operator's call, ``seaway
  vehicle arm`` then ``seaway mission resume``);
* if the mission is still paused ``wait_s`` after the interruption (``--resume-wait``), the launcher
  ends it: it aborts the mission, says why (the controller's reason, the autopilot's state, the last
  refusal) and stops the run (exit 1).

``LinkResume`` is the pure decision (statuses, interruptions and time in; what to do out); the
launcher's loop (``LinkTender``) notices the interruptions and makes the requests.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

from seaway.contract import keys
from seaway.contract.messages import (
    MissionCommand,
    MissionRequest,
    MissionStatus,
    ModeRequest,
    VehicleStatus,
    return_mission_id,
)
from seaway.runtime.bus import Bus
from seaway.tools.launch.supervisor import Supervisor

LINK_SERVICES = frozenset({"vehicle_io", "sim"})
"""The services whose restart interrupts the link to the autopilot (or is the autopilot)."""
RESTART = "the link restart"
"""The cause of an interruption when the launcher restarted a process of ``LINK_SERVICES``."""
LOSS = "the loss of the autopilot link"
"""The cause when vehicle_io reported the link down after it had been up."""
RESUME_WAIT_S = 120.0
"""Default time a mission paused by a link interruption may wait to be resumed before the run ends
it [s]: an autopilot reboot takes tens of seconds, and an operator must have time to re-arm."""
PAUSE_WITHIN_S = 30.0
"""An interruption of the link paused a mission if the controller paused it within this after the
interruption was noticed [s] (it does within a second of the link's loss); a later pause is not the
interruption's."""
RETRY_S = 5.0
"""Between two resume attempts while they are refused [s]."""

Action = Literal["resume", "end"]


@dataclass
class LinkResume:
    """One vessel's mission after link interruptions (see the module docstring). Times are
    monotonic seconds, passed in."""

    mission_id: str
    wait_s: float = RESUME_WAIT_S
    interrupted_s: float | None = None
    """When the latest interruption of the link was noticed; None: none since the mission was last
    active."""
    cause: str = ""
    """What interrupted the link, for the operator: ``RESTART`` or ``LOSS``."""
    last_try_s: float | None = None
    last_refusal: str = ""
    rebooted: bool = False
    """A disarmed autopilot was heard since the interruption: resuming is the operator's call."""
    paused: bool = False
    """The mission was seen paused by the controller since the interruption."""
    link_up: bool | None = None
    """vehicle_io's newest word on the autopilot link (None: no status yet)."""

    def on_interruption(self, now_s: float, cause: str) -> None:
        """The link was interrupted (``cause``): a restart of a process of ``LINK_SERVICES`` of this
        vessel, or vehicle_io lost the autopilot (``on_vehicle``)."""
        self.interrupted_s = now_s
        self.cause = cause
        self.last_try_s = None
        self.rebooted = False
        self.paused = False

    def on_vehicle(self, status: VehicleStatus, now_s: float) -> None:
        """Each status vehicle_io published, in order: a link that was up and is down is an
        interruption, unless one is pending already (a restarted vehicle_io starts without its
        link: that loss is the restart's). A link not yet up interrupted nothing."""
        if self.link_up and not status.link_ok and self.interrupted_s is None:
            self.on_interruption(now_s, LOSS)
        self.link_up = status.link_ok

    def decide(
        self, status: MissionStatus | None, vehicle: VehicleStatus | None, now_s: float
    ) -> Action | None:
        """What to do now: ``resume`` (mode, then resume), ``end``, or nothing."""
        if self.interrupted_s is None or status is None:
            return None
        if status.mission_id not in (self.mission_id, return_mission_id(self.mission_id)):
            return None
        if status.state != "paused" or not status.reason:
            # Active again, or over, after the pause; or never paused by this interruption: done.
            late = now_s - self.interrupted_s > PAUSE_WITHIN_S
            if status.state != "paused" and (self.paused or late):
                self.interrupted_s = None
            return None  # paused by the operator (no reason): theirs to resume
        if not self.paused and now_s - self.interrupted_s > PAUSE_WITHIN_S:
            self.interrupted_s = None  # paused long after: not the interruption's doing
            return None
        self.paused = True
        if now_s - self.interrupted_s > self.wait_s:
            return "end"
        if vehicle is not None and vehicle.link_ok and not vehicle.armed:
            self.rebooted = True
        ready = vehicle is not None and vehicle.link_ok and vehicle.armed and not self.rebooted
        due = self.last_try_s is None or now_s - self.last_try_s >= RETRY_S
        if ready and due:
            self.last_try_s = now_s
            return "resume"
        return None

    def why_not(self, status: MissionStatus, vehicle: VehicleStatus | None) -> str:
        """Why the mission was not resumed, for the operator."""
        if vehicle is None or not vehicle.link_ok:
            where = "vehicle_io reported no autopilot link"
        elif not vehicle.armed or self.rebooted:
            where = (
                "the autopilot came back disarmed (a reboot: resuming is the operator's call, "
                "'seaway vehicle arm' then 'seaway mission resume')"
            )
        else:
            where = f"the autopilot is armed in {vehicle.mode}"
        refused = f"; the last resume was refused: {self.last_refusal}" if self.last_refusal else ""
        return (
            f"mission {status.mission_id} still paused {self.wait_s:g} s after {self.cause} "
            f"({status.reason}): {where}{refused}"
        )


class LinkTender:
    """The launcher's side, for every vessel: notices the link's interruptions (restarts in its
    supervisor, losses in every status vehicle_io publishes) and makes the requests ``LinkResume``
    decides. ``step`` once per loop of the launcher (a few times a second)."""

    def __init__(
        self,
        bus: Bus,
        sup: Supervisor,
        vessels: list[str],
        mission: MissionRequest,
        mode: str | None,
        wait_s: float = RESUME_WAIT_S,
    ) -> None:
        self.bus, self.sup, self.mode = bus, sup, mode
        self.vessels = {v: LinkResume(mission.mission_id, wait_s) for v in vessels}
        self._newest = {v: bus.newest(keys.MISSION_STATUS, vessel=v) for v in vessels}
        # Every status, not the newest: a loss shorter than a loop's look must still be seen.
        self._vehicle_statuses = {v: bus.every(keys.VEHICLE_STATUS, vessel=v) for v in vessels}
        self._vehicle: dict[str, VehicleStatus | None] = dict.fromkeys(vessels)
        self._restarts = dict.fromkeys(vessels, 0)

    def _link_restarts(self, vessel: str) -> int:
        return sum(
            sp.restarts
            for sp in self.sup.procs.values()
            if sp.spec.service in LINK_SERVICES and sp.vessel == vessel
        )

    def step(self, now_s: float, label: dict[str, str]) -> str | None:
        """Resume what can be; the reason when a vessel's mission had to be ended (None: go on)."""
        for v, link in self.vessels.items():
            n = self._link_restarts(v)
            if n > self._restarts[v]:
                self._restarts[v] = n
                link.on_interruption(now_s, RESTART)
            for heard in self._vehicle_statuses[v].take():
                link.on_vehicle(heard, now_s)
                self._vehicle[v] = heard
            status, vehicle = self._newest[v].get(), self._vehicle[v]
            action = link.decide(status, vehicle, now_s)
            if action == "resume":
                self._resume(v, link, vehicle, label[v])  # type: ignore[arg-type]
            elif action == "end":
                why = link.why_not(status, vehicle)  # type: ignore[arg-type]
                reply = self.bus.request(
                    keys.MISSION_COMMAND,
                    MissionCommand.make(stamp_ns=time.time_ns(), command="abort"),
                    timeout_s=10.0,
                    vessel=v,
                )
                return (
                    f"{label[v]}{why}; the launcher ended it (abort: "
                    f"{'accepted' if reply.accepted else 'REFUSED: ' + reply.reason})"
                )
        return None

    def _resume(self, vessel: str, link: LinkResume, vehicle: VehicleStatus, label: str) -> None:
        if self.mode and vehicle.mode != self.mode:  # a link-loss failsafe's HOLD, say
            reply = self.bus.request(
                keys.VEHICLE_MODE,
                ModeRequest.make(stamp_ns=time.time_ns(), mode=self.mode),
                timeout_s=10.0,
                vessel=vessel,
            )
            print(
                f"{label}after {link.cause}, mode {self.mode}: "
                f"{'accepted' if reply.accepted else 'REFUSED: ' + reply.reason}",
                flush=True,
            )
            if not reply.accepted:
                link.last_refusal = f"mode {self.mode}: {reply.reason}"
                return
        reply = self.bus.request(
            keys.MISSION_COMMAND,
            MissionCommand.make(stamp_ns=time.time_ns(), command="resume"),
            timeout_s=10.0,
            vessel=vessel,
        )
        if reply.accepted:
            print(f"{label}mission resumed after {link.cause}", flush=True)
            link.last_refusal = ""
        else:
            link.last_refusal = reply.reason
