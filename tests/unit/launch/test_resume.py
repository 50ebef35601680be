"""After an interruption of the link, a restart (issue 56, item 19) or a loss vehicle_io reported:
the launcher resumes a mission the controller paused when the autopilot is back armed, leaves a
rebooted (disarmed) one to the operator, and ends the mission, saying why, when it is still paused
after the wait. Pure: statuses and times in."""

from __future__ import annotations

from seaway.contract.messages import MissionStatus, VehicleStatus
from seaway.tools.launch.resume import LOSS, RESTART, RETRY_S, LinkResume

PAUSED = MissionStatus(
    stamp_ns=1, state="paused", mission_id="m", reason="paused by the controller: no autopilot link"
)


def vehicle(armed: bool = True, link_ok: bool = True, mode: str = "HOLD") -> VehicleStatus:
    return VehicleStatus(stamp_ns=1, autopilot="px4", link_ok=link_ok, armed=armed, mode=mode)


def test_nothing_happens_without_a_restart_or_for_the_operators_pause() -> None:
    link = LinkResume("m", wait_s=60.0)
    assert link.decide(PAUSED, vehicle(), 0.0) is None  # no restart: a pause of its own
    link.on_interruption(1.0, RESTART)
    operator = PAUSED.model_copy(update={"reason": ""})
    assert link.decide(operator, vehicle(), 2.0) is None
    other = PAUSED.model_copy(update={"mission_id": "another"})
    assert link.decide(other, vehicle(), 2.0) is None


def test_an_armed_autopilot_back_on_the_link_gets_the_mission_resumed() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_interruption(0.0, RESTART)
    active = PAUSED.model_copy(update={"state": "active", "reason": ""})
    assert link.decide(active, vehicle(), 0.5) is None  # not paused yet: the pause follows
    assert link.decide(PAUSED, vehicle(link_ok=False), 1.0) is None  # not back yet
    assert link.decide(PAUSED, vehicle(), 2.0) == "resume"
    assert link.decide(PAUSED, vehicle(), 2.5) is None  # refused meanwhile: asks again later
    assert link.decide(PAUSED, vehicle(), 2.0 + RETRY_S) == "resume"
    assert link.decide(active, vehicle(), 9.0) is None and link.interrupted_s is None
    assert link.decide(PAUSED, vehicle(), 70.0) is None  # a later pause is not the restart's


def test_a_rebooted_autopilot_is_the_operators_and_the_wait_ends_the_mission() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_interruption(0.0, RESTART)
    assert link.decide(PAUSED, vehicle(armed=False), 5.0) is None
    assert link.decide(PAUSED, vehicle(armed=True), 10.0) is None  # armed by someone: theirs
    assert link.decide(PAUSED, vehicle(armed=True), 61.0) == "end"
    why = link.why_not(PAUSED, vehicle(armed=False))
    assert "disarmed" in why and "no autopilot link" in why


def test_a_pause_long_after_the_restart_is_not_the_restarts() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_interruption(0.0, RESTART)
    assert link.decide(PAUSED, vehicle(), 40.0) is None and link.interrupted_s is None


def test_a_link_lost_and_found_with_the_autopilot_still_armed_is_resumed() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_vehicle(vehicle(link_ok=False), 0.0)  # vehicle_io started before the autopilot
    assert link.interrupted_s is None  # a link never up interrupted nothing
    link.on_vehicle(vehicle(), 1.0)
    link.on_vehicle(vehicle(), 2.0)
    assert link.interrupted_s is None
    link.on_vehicle(vehicle(link_ok=False), 10.0)  # the HEARTBEAT stopped for vehicle_io's timeout
    assert link.interrupted_s == 10.0 and link.cause == LOSS
    link.on_vehicle(vehicle(link_ok=False), 10.5)
    assert link.interrupted_s == 10.0  # one loss, however many statuses say so
    assert link.decide(PAUSED, vehicle(link_ok=False), 11.0) is None
    link.on_vehicle(vehicle(), 12.0)
    assert link.decide(PAUSED, vehicle(), 12.0) == "resume"


def test_a_link_found_again_on_a_disarmed_autopilot_ends_the_mission_after_the_wait() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_vehicle(vehicle(), 0.0)
    link.on_vehicle(vehicle(link_ok=False), 5.0)
    link.on_vehicle(vehicle(armed=False), 30.0)  # a reboot
    assert link.decide(PAUSED, vehicle(armed=False), 30.0) is None
    assert link.decide(PAUSED, vehicle(armed=True), 40.0) is None  # armed by someone: theirs
    assert link.decide(PAUSED, vehicle(armed=True), 66.0) == "end"
    assert LOSS in link.why_not(PAUSED, vehicle(armed=False))


def test_a_restarted_vehicle_io_starting_without_its_link_is_the_restarts_interruption() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_vehicle(vehicle(), 0.0)
    link.on_interruption(5.0, RESTART)
    link.on_vehicle(vehicle(link_ok=False), 5.5)  # the new vehicle_io, not yet linked
    assert link.interrupted_s == 5.0 and link.cause == RESTART
