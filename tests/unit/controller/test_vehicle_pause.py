"""Issue 14, item 2: no phantom mission. While the vehicle does not apply the commanded thrust
(disarmed after an autopilot reboot, link lost, HOLD after a failsafe), the controller pauses the
mission, says why in ``mission/status``, stops counting energy, and resumes only on request (and
only once the vehicle applies thrust again). Pure core, injected solver, time passed in."""

from __future__ import annotations

import pytest
from seaway.contract.messages import HOLD_REASON_TEXT, MissionCommand, VehicleStatus

from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state

START_NS = 1_000 * DT_NS


def status(t_ns: int, withheld: str | None, mode: str = "MANUAL") -> VehicleStatus:
    return VehicleStatus(stamp_ns=t_ns, autopilot="px4", link_ok=withheld != "no_link",
                         armed=withheld != "disarmed", mode=mode,
                         thrust_withheld=withheld)  # type: ignore[arg-type]


def resume(core, t_ns: int):
    return core.handle_command(t_ns, MissionCommand.make(stamp_ns=t_ns, command="resume"))


def flying():
    core = make_core(ScriptedSolver())
    assert core.handle_mission(START_NS, mission()).accepted
    core.on_vehicle_status(status(START_NS + 1, None))
    _, _, st = core.step(START_NS + DT_NS, state(1))
    _, _, st = core.step(START_NS + 2 * DT_NS, state(2))
    assert st.state == "active" and st.reason == "" and st.energy_used_j > 0
    return core


def test_a_rebooted_autopilot_pauses_the_mission_with_the_reason() -> None:
    core = flying()
    t = START_NS + 3 * DT_NS
    why = core.on_vehicle_status(status(t, "disarmed"))
    assert why is not None and "disarmed" in why
    cmd, record, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and "the vehicle is disarmed" in st.reason
    assert "resume" in st.reason and record is None
    assert (cmd.thrust_port_n, cmd.thrust_starboard_n) == (0.0, 0.0) and cmd.source == "paused"
    # No energy counted while paused (before: it kept rising with the commanded thrust).
    energy = st.energy_used_j
    for k in range(4, 20):
        _, _, st = core.step(t + k * DT_NS, state(k))
    assert st.state == "paused" and st.energy_used_j == pytest.approx(energy)


def test_it_resumes_only_on_request_and_only_once_thrust_applies_again() -> None:
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(status(t, "no_link"))
    core.on_vehicle_status(status(t + 1, "disarmed"))
    refused = resume(core, t + 2)
    assert not refused.accepted and "cannot resume: the vehicle is disarmed" in refused.reason
    core.on_vehicle_status(status(t + 3, None))  # armed again (by the operator)
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused"  # not by itself
    accepted = resume(core, t + DT_NS + 1)
    assert accepted.accepted
    _, record, st = core.step(t + 2 * DT_NS, state(4))
    assert st.state == "active" and st.reason == "" and record is not None


@pytest.mark.parametrize(("withheld", "mode", "text"), [
    ("mode", "HOLD", "in mode HOLD"),
    ("no_link", "UNKNOWN", "no link to the autopilot"),
    ("autopilot_config", "MANUAL", "configuration blocks thrust"),
])
def test_every_reason_pauses(withheld: str, mode: str, text: str) -> None:
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(status(t, withheld, mode))
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and text in st.reason


def test_a_status_from_before_the_mission_does_not_pause_it() -> None:
    """The launcher arms, then sends the mission: a status published before the arm (disarmed) can
    arrive after the mission; it says nothing about this mission."""
    core = make_core(ScriptedSolver())
    core.handle_mission(START_NS, mission())
    assert core.on_vehicle_status(status(START_NS - 1, "disarmed")) is None
    _, _, st = core.step(START_NS + DT_NS, state(1))
    assert st.state == "active"
    # A newer one that still says disarmed does.
    assert core.on_vehicle_status(status(START_NS + 2, "disarmed"))


def test_the_operators_own_pause_has_no_reason_and_no_vehicle_means_no_pause() -> None:
    core = make_core(ScriptedSolver())  # no vehicle status ever (lockstep: no vehicle_io)
    core.handle_mission(START_NS, mission())
    _, _, st = core.step(START_NS + DT_NS, state(1))
    assert st.state == "active"
    core.handle_command(START_NS, MissionCommand.make(stamp_ns=0, command="pause"))
    _, _, st = core.step(START_NS + 2 * DT_NS, state(2))
    assert st.state == "paused" and st.reason == ""
    assert resume(core, START_NS).accepted


def test_a_stamp_cannot_pin_an_old_status() -> None:
    """Statuses count in the order they come (one publisher, in order): one stamped absurdly far
    ahead must not hide every later one (the service also drops it: ``seaway.runtime.stamps``)."""
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(status(2**62, None))
    assert core.on_vehicle_status(status(t, "disarmed")) is not None
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused"


def test_the_autopilots_fence_breach_is_named_in_the_missions_reason_and_the_refused_resume() -> None:
    """Issue 63: a fence breach reaches the mission state with its cause, not as a bare HOLD."""
    core = flying()
    t = START_NS + 3 * DT_NS
    breach = VehicleStatus(stamp_ns=t, autopilot="ardupilot", link_ok=True, armed=True,
                           mode="HOLD", thrust_withheld="mode", hold_reason="fence",
                           hold_reason_detail="SYS_STATUS: fence unhealthy (mode MANUAL -> HOLD)")
    core.on_vehicle_status(breach)
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused"
    assert HOLD_REASON_TEXT["fence"] in st.reason
    assert "SYS_STATUS: fence unhealthy" in st.reason
    refused = resume(core, t + DT_NS + 1)
    assert not refused.accepted and HOLD_REASON_TEXT["fence"] in refused.reason


def held(t_ns: int, hold_reason: str | None, detail: str = "") -> VehicleStatus:
    return VehicleStatus(stamp_ns=t_ns, autopilot="ardupilot", link_ok=True, armed=True,
                         mode="HOLD", thrust_withheld="mode", hold_reason=hold_reason,  # type: ignore[arg-type]
                         hold_reason_detail=detail)


@pytest.mark.parametrize(("cause", "detail", "words"), [
    ("gcs_mode_change", "", "a mode change Seaway did not ask for"),
    ("gcs_link_loss", "GCS Failsafe", "ground-station link failsafe "
                                      "(GCS Failsafe)"),
    ("radio_loss", "Radio Failsafe", "radio (RC) failsafe (Radio Failsafe)"),
])
def test_the_autopilots_cause_reaches_the_operator(cause: str, detail: str, words: str) -> None:
    """Issue 63: the cause vehicle_io decoded (``hold_reason``, the autopilot's own words) is in
    ``mission/status``'s reason, not only in ``vehicle/status``."""
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(held(t, cause, detail))
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and "in mode HOLD" in st.reason and words in st.reason, st.reason


def test_a_cause_named_after_the_pause_replaces_the_reason_while_paused() -> None:
    """ArduPilot's "GCS Failsafe" text may follow its mode change: the pause began without a
    cause, and the operator is told it once vehicle_io names it; a pause the operator made is not
    touched."""
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(held(t, None))
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and "why:" not in st.reason
    why = core.on_vehicle_status(held(t + DT_NS + 1, "gcs_link_loss", "GCS Failsafe"))
    assert why is not None and "GCS Failsafe" in why
    _, _, st = core.step(t + 2 * DT_NS, state(4))
    assert st.state == "paused" and "ground-station link failsafe" in st.reason, st.reason
    assert "GCS Failsafe" in st.reason
    # The operator's own pause keeps its (empty) reason.
    core = flying()
    assert core.handle_command(t, MissionCommand.make(stamp_ns=t, command="pause")).accepted
    assert core.on_vehicle_status(held(t + 1, "battery", "Battery 1 is low")) is None
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and st.reason == "", st.reason


def test_the_budget_goes_on_while_paused_and_drifting() -> None:
    """Paused with zero thrust (the vehicle disarmed: nothing to hold with), the pack still
    drains, and the budget published says so: before, it was priced only while flying or holding
    station, and the operator saw the battery of the moment the pause began (seen on PX4's firmware:
    a motion-fault pause, then PX4's battery failsafe, with the budget frozen at 444 kJ)."""
    from seaway.contract.messages import BatteryState

    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(status(t, "disarmed"))
    seen = []
    for k in range(4, 40):
        if k % 10 == 0:
            core.on_battery(BatteryState.make(stamp_ns=t + k * DT_NS, source="sim",
                                              remaining_j=100_000.0 - 1_000.0 * k, reserve_j=0.0))
        _, _, st = core.step(t + k * DT_NS, state(k))
        assert st.state == "paused" and core._holding is None  # drifting, not holding
        if (b := core.take_budget()) is not None and b.battery_remaining_j is not None:
            seen.append(b.battery_remaining_j)
    assert len(seen) >= 3 and seen[-1] < seen[0], seen
