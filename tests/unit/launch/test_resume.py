"""After a link restart (issue 56, item 19): the launcher resumes a mission the controller paused
when the autopilot is back armed, leaves a rebooted (disarmed) one to the operator, and ends the
mission, saying why, when it is still paused after the wait. Pure: statuses and times in."""

from __future__ import annotations

from seaway.contract.messages import MissionStatus, VehicleStatus
from seaway.tools.launch.resume import RETRY_S, LinkResume

PAUSED = MissionStatus(
    stamp_ns=1, state="paused", mission_id="m", reason="paused by the controller: no autopilot link"
)


def vehicle(armed: bool = True, link_ok: bool = True, mode: str = "HOLD") -> VehicleStatus:
    return VehicleStatus(stamp_ns=1, autopilot="px4", link_ok=link_ok, armed=armed, mode=mode)


def test_nothing_happens_without_a_restart_or_for_the_operators_pause() -> None:
    link = LinkResume("m", wait_s=60.0)
    assert link.decide(PAUSED, vehicle(), 0.0) is None  # no restart: a pause of its own
    link.on_restart(1.0)
    operator = PAUSED.model_copy(update={"reason": ""})
    assert link.decide(operator, vehicle(), 2.0) is None
    other = PAUSED.model_copy(update={"mission_id": "another"})
    assert link.decide(other, vehicle(), 2.0) is None


def test_an_armed_autopilot_back_on_the_link_gets_the_mission_resumed() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_restart(0.0)
    active = PAUSED.model_copy(update={"state": "active", "reason": ""})
    assert link.decide(active, vehicle(), 0.5) is None  # not paused yet: the pause follows
    assert link.decide(PAUSED, vehicle(link_ok=False), 1.0) is None  # not back yet
    assert link.decide(PAUSED, vehicle(), 2.0) == "resume"
    assert link.decide(PAUSED, vehicle(), 2.5) is None  # refused meanwhile: asks again later
    assert link.decide(PAUSED, vehicle(), 2.0 + RETRY_S) == "resume"
    assert link.decide(active, vehicle(), 9.0) is None and link.restarted_s is None
    assert link.decide(PAUSED, vehicle(), 70.0) is None  # a later pause is not the restart's


def test_a_rebooted_autopilot_is_the_operators_and_the_wait_ends_the_mission() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_restart(0.0)
    assert link.decide(PAUSED, vehicle(armed=False), 5.0) is None
    assert link.decide(PAUSED, vehicle(armed=True), 10.0) is None  # armed by someone: theirs
    assert link.decide(PAUSED, vehicle(armed=True), 61.0) == "end"
    why = link.why_not(PAUSED, vehicle(armed=False))
    assert "disarmed" in why and "no autopilot link" in why


def test_a_pause_long_after_the_restart_is_not_the_restarts() -> None:
    link = LinkResume("m", wait_s=60.0)
    link.on_restart(0.0)
    assert link.decide(PAUSED, vehicle(), 40.0) is None and link.restarted_s is None
