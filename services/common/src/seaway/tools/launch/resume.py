"""After the launcher restarted the vehicle link: resume the mission it interrupted, or end it.

When vehicle_io or the sim (the simulated autopilot) dies, the launcher restarts it; meanwhile the
thrust did not reach the thrusters, so the controller paused the mission (``MissionStatus.reason``)
and, by design, resumes it only when asked. Nobody asked: the mission stayed paused for good and
the launcher never finished. Now the launcher, which started the mission and restarted the link,
asks (its operator identity, the normal authority path), for a mission paused while it restarted a
link process:

* once vehicle_io reports the link up with the autopilot **armed**, it sends the profile's start-up
  mode again (a link-loss failsafe leaves the autopilot in HOLD) and then ``resume``;
* it does not arm a **disarmed** autopilot, nor resume once it heard one since the restart (a
  rebooted autopilot: whether the vessel may drive off again is the operator's call, ``seaway
  vehicle arm`` then ``seaway mission resume``);
* if the mission is still paused ``wait_s`` after the restart (``--resume-wait``), the launcher ends
  it: it aborts the mission, says why (the controller's reason, the autopilot's state, the last
  refusal) and stops the run (exit 1).

``LinkResume`` is the pure decision (statuses, restarts and time in; what to do out); the launcher's
loop does the requests.
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
RESUME_WAIT_S = 120.0
"""Default time a mission paused by a link restart may wait to be resumed before the run ends it
[s]: an autopilot reboot takes tens of seconds, and an operator must have time to re-arm."""
PAUSE_WITHIN_S = 30.0
"""A restart interrupts a mission if the controller pauses it within this after the restart [s]
(it does within a second of the link's loss); a later pause is not the restart's."""
RETRY_S = 5.0
"""Between two resume attempts while they are refused [s]."""

Action = Literal["resume", "end"]


@dataclass
class LinkResume:
    """One vessel's mission after link restarts (see the module docstring). Times are monotonic
    seconds, passed in."""

    mission_id: str
    wait_s: float = RESUME_WAIT_S
    restarted_s: float | None = None
    """When the latest link restart was noticed; None: none since the mission was last active."""
    last_try_s: float | None = None
    last_refusal: str = ""
    rebooted: bool = False
    """A disarmed autopilot was heard since the restart: resuming is the operator's call."""
    paused: bool = False
    """The mission was seen paused by the controller since the restart."""

    def on_restart(self, now_s: float) -> None:
        """The launcher restarted a process of ``LINK_SERVICES`` of this vessel."""
        self.restarted_s = now_s
        self.last_try_s = None
        self.rebooted = False
        self.paused = False

    def decide(
        self, status: MissionStatus | None, vehicle: VehicleStatus | None, now_s: float
    ) -> Action | None:
        """What to do now: ``resume`` (mode, then resume), ``end``, or nothing."""
        if self.restarted_s is None or status is None:
            return None
        if status.mission_id not in (self.mission_id, return_mission_id(self.mission_id)):
            return None
        if status.state != "paused" or not status.reason:
            # Active again, or over, after the pause; or never paused by this restart: done.
            late = now_s - self.restarted_s > PAUSE_WITHIN_S
            if status.state != "paused" and (self.paused or late):
                self.restarted_s = None
            return None  # paused by the operator (no reason): theirs to resume
        if not self.paused and now_s - self.restarted_s > PAUSE_WITHIN_S:
            self.restarted_s = None  # paused long after the restart: not the restart's doing
            return None
        self.paused = True
        if now_s - self.restarted_s > self.wait_s:
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
            f"mission {status.mission_id} still paused {self.wait_s:g} s after the link restart "
            f"({status.reason}): {where}{refused}"
        )


class LinkTender:
    """The launcher's side: notices link restarts in its supervisor, makes the requests ``LinkResume``
    decides, for every vessel. ``step`` once per loop of the launcher (a few times a second)."""

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
        self._newest = {
            v: (bus.newest(keys.MISSION_STATUS, vessel=v), bus.newest(keys.VEHICLE_STATUS, vessel=v))
            for v in vessels
        }
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
                link.on_restart(now_s)
            status, vehicle = (x.get() for x in self._newest[v])
            action = link.decide(status, vehicle, now_s)  # type: ignore[arg-type]
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
                f"{label}after the link restart, mode {self.mode}: "
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
            print(f"{label}mission resumed after the link restart", flush=True)
            link.last_refusal = ""
        else:
            link.last_refusal = reply.reason
