"""The requests a launch makes of the vessels it started: the profile's start-up mode and arming
(``vehicle/mode``, ``vehicle/arm``, once vehicle_io reports its autopilot link), and what it prints
of the controller's reply to the mission it sent. Waits are in seconds of monotonic time.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable

from seaway.contract import keys
from seaway.contract.messages import ArmRequest, MissionRequest, ModeRequest, Reply
from seaway.runtime.bus import Bus
from seaway.tools.launch.profile import Profile
from seaway.vessel.energy_prediction import known_poor

LINK_WAIT_S = 20.0  # how long the start-up requests wait for vehicle_io's autopilot link


def _operator_requests(bus: Bus, profile: Profile, stop: threading.Event, vessel: str,
                       label: str = "", failure: Callable[[], str | None] = lambda: None) -> bool:
    """The profile's start-up mode and arming of ``vessel``, as explicit requests with their
    replies shown (each line begins with ``label``: a fleet's ``<vessel>: ``).

    vehicle_io is ready when it serves requests, which can be before it has heard the autopilot;
    so the requests wait for a VehicleStatus with the link up, as an operator would. ``failure``
    is asked while waiting: a required process that failed meanwhile (the autopilot's SITL, say)
    ends the wait with its reason instead of a timeout.
    """
    if not (profile.mode_on_start or profile.arm_on_start):
        return True
    status = bus.subscribe(keys.VEHICLE_STATUS, mode="latest", vessel=vessel)
    deadline = time.monotonic() + LINK_WAIT_S
    while True:
        msg = status.get(0.5)
        if msg is not None and msg.link_ok:
            break
        if stop.is_set():
            return True  # stopping anyway: not a failure of the start
        failed = failure()
        if failed:
            print(f"\nseaway launch: {failed}", file=sys.stderr, flush=True)
            return False
        if time.monotonic() > deadline:
            print(f"{label}no autopilot link reported by vehicle_io within {LINK_WAIT_S:g} s; "
                  "not sending mode or arming", flush=True)
            return False
    status.undeclare()
    if profile.mode_on_start:
        reply = bus.request(keys.VEHICLE_MODE, ModeRequest.make(stamp_ns=time.time_ns(),
                                                                mode=profile.mode_on_start),
                            timeout_s=10.0, vessel=vessel)
        print(f"{label}mode {profile.mode_on_start}: "
              f"{'accepted' if reply.accepted else 'REFUSED: ' + reply.reason}", flush=True)
        if not reply.accepted:
            return False
    if profile.arm_on_start:
        return _arm(bus, profile.arm_wait_s, stop, vessel, label, failure)
    return True


ARM_RETRY_S = 5.0  # between arming requests while the autopilot refuses (profile.arm_wait_s)


def _arm(bus: Bus, wait_s: float, stop: threading.Event, vessel: str, label: str,
         failure: Callable[[], str | None]) -> bool:
    """Ask to arm; while refused, ask again every ``ARM_RETRY_S`` for up to ``wait_s``, printing each
    new reason once (an autopilot still converging says why, and the reason changes as it does)."""
    t0 = time.monotonic()
    said = ""
    while True:
        reply = bus.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=time.time_ns(), arm=True),
                            timeout_s=10.0, vessel=vessel)
        waited = time.monotonic() - t0
        if reply.accepted:
            print(f"{label}arm: accepted" + (f" after {waited:.0f} s" if said else ""), flush=True)
            return True
        if stop.is_set() or waited + ARM_RETRY_S > wait_s:
            print(f"{label}arm: REFUSED: {reply.reason}"
                  + (f" (asked for {waited:.0f} s)" if wait_s else ""), flush=True)
            return stop.is_set()
        failed = failure()
        if failed:
            print(f"\nseaway launch: {failed}", file=sys.stderr, flush=True)
            return False
        if reply.reason != said:
            print(f"{label}arm: not yet ({reply.reason}); asking again every {ARM_RETRY_S:g} s for "
                  f"up to {wait_s:g} s", flush=True)
            said = reply.reason
        if stop.wait(ARM_RETRY_S):
            return True


def mission_reply_lines(mission: MissionRequest, reply: Reply) -> list[str]:
    """What the launcher prints of the controller's reply to the mission it sent; a warning below
    an acceptance when the controller's energy prediction is known to be poor, so that the 'to
    finish' and 'to home' on the status line are not read as more than they are."""
    # An acceptance can carry news too (its solver is still being made, say).
    said = ("accepted" + ("" if reply.reason in ("", "mission started") else f" ({reply.reason})")
            if reply.accepted else "REFUSED: " + reply.reason)
    lines = [f"mission {mission.mission_id}: {said} ({_describe_mission(mission)})"]
    if reply.accepted and (poor := known_poor(mission.controller)):
        lines.append(f"WARNING: {poor}")
    return lines


def _describe_mission(mission: MissionRequest) -> str:
    """What the mission options chose, e.g. ``nmpc, predicting the estimated tau_d, T^w 1 W``."""
    return (f"{mission.controller}, "
            + ("predicting the estimated tau_d" if mission.predict_disturbance else "tau_d = 0")
            + f", T^w {mission.task_power_w:g} W")
