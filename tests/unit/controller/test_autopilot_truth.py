"""Issue 63 in the controller's pure core: the pause names the autopilot's failsafe, resume is
refused while it is latched in one, an unhealthy autopilot keeps a new mission waiting (and does not
pause one under way), and the energy budget takes the lowest battery estimate, saying which."""

from __future__ import annotations

import logging

import pytest
from seaway.contract.messages import HOLD_REASON_TEXT, BatteryState, VehicleStatus
from seaway.vessel.battery import BatteryParams
from seaway_controller.battery_estimate import BatteryTrack, voltage_energy_j

from tests.unit.controller.test_core import DT_NS, ScriptedSolver, make_core, mission, state
from tests.unit.controller.test_vehicle_pause import START_NS, flying, resume


def vs(t_ns: int, **kw) -> VehicleStatus:
    fields = dict(stamp_ns=t_ns, autopilot="ardupilot", link_ok=True, armed=True, mode="MANUAL")
    return VehicleStatus(**(fields | kw))


def test_the_pause_names_the_failsafe_and_resume_is_refused_while_it_is_latched() -> None:
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(vs(t, mode="HOLD", thrust_withheld="mode", hold_reason="battery",
                              hold_reason_detail="Battery 1 is low 11.00V used 5 mAh",
                              failsafe_latched="battery",
                              failsafe_latched_detail="Battery 1 is low 11.00V used 5 mAh"))
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and HOLD_REASON_TEXT["battery"] in st.reason, st.reason
    assert "Battery 1 is low" in st.reason
    # The operator takes the vessel back (MANUAL): thrust applies, the failsafe is still latched.
    core.on_vehicle_status(vs(t + 2, failsafe_latched="battery",
                              failsafe_latched_detail="SYS_STATUS: battery still unhealthy"))
    refused = resume(core, t + 3)
    assert not refused.accepted
    assert "still latched" in refused.reason and HOLD_REASON_TEXT["battery"] in refused.reason, refused.reason
    core.on_vehicle_status(vs(t + 4))  # rebooted with a new pack: nothing latched
    assert resume(core, t + 5).accepted


def test_an_unhealthy_autopilot_keeps_a_new_mission_waiting_saying_what_it_lacks() -> None:
    core = make_core(ScriptedSolver())
    why = "the autopilot is not healthy: its estimator not using GNSS yet (EKF_STATUS_REPORT flags 0x0)"
    core.on_vehicle_status(vs(START_NS - 1, thrust_withheld="autopilot_unhealthy",
                              autopilot_unhealthy_detail=why))
    reply = core.handle_mission(START_NS, mission())
    assert reply.accepted and reply.detail["state"] == "waiting"
    assert "not using GNSS" in reply.reason, reply.reason
    core.on_vehicle_status(vs(START_NS + 1, thrust_withheld="autopilot_unhealthy",
                              autopilot_unhealthy_detail=why))
    _, record, st = core.step(START_NS + DT_NS, state(1))
    assert st.state == "waiting" and record is None
    core.on_vehicle_status(vs(START_NS + 2))
    _, record, st = core.step(START_NS + 2 * DT_NS, state(2))
    assert st.state == "active" and record is not None
    # Under way, health news does not pause it: the autopilot's own failsafes act on that.
    core.on_vehicle_status(vs(START_NS + 3, thrust_withheld="autopilot_unhealthy",
                              autopilot_unhealthy_detail="the autopilot is not healthy: status CRITICAL"))
    _, _, st = core.step(START_NS + 3 * DT_NS, state(3))
    assert st.state == "active"


PACK = BatteryParams(capacity_ah=10, nominal_voltage_v=11.1, full_voltage_v=12.6,
                     empty_voltage_v=9.9)


def report(remaining_frac: float, volts: float, source: str = "autopilot") -> BatteryState:
    return BatteryState(stamp_ns=1, source=source, voltage_v=volts, remaining_frac=remaining_frac,
                        remaining_j=remaining_frac * PACK.energy_j, capacity_j=PACK.energy_j)


def test_the_budget_takes_the_lowest_estimate_and_says_which(caplog) -> None:
    track = BatteryTrack(PACK)
    track.report, track.counted_at_report_j = report(0.98, 12.6), 0.0
    assert track.remaining_j(0.0) == pytest.approx(0.98 * PACK.energy_j)
    assert track.source == "autopilot"
    # 11.0 V with the autopilot's count still at 98 %: the voltage says 41 %.
    with caplog.at_level(logging.INFO, logger="seaway_controller.battery"):
        track.report, track.counted_at_report_j = report(0.98, 11.0), 1000.0
        left = track.remaining_j(1500.0)
    assert track.source == "voltage"
    assert left == pytest.approx((11.0 - 9.9) / 2.7 * PACK.energy_j - 500.0)
    assert sum("takes the voltage estimate" in r.message for r in caplog.records) == 1
    track.remaining_j(1600.0)  # the same source: not said again
    assert sum("takes the voltage estimate" in r.message for r in caplog.records) == 1
    # The controller counted more than the autopilot's fraction fell: its own count is lower.
    track.report, track.counted_at_report_j = report(0.97, 12.5), 0.2 * PACK.energy_j
    track.remaining_j(0.2 * PACK.energy_j)
    assert track.source == "count"


def test_a_voltage_outside_the_vessel_files_pack_is_not_an_empty_battery() -> None:
    assert voltage_energy_j(16.0, PACK) is None and voltage_energy_j(9.0, PACK) is None
    assert voltage_energy_j(9.8, PACK) == 0.0 and voltage_energy_j(12.6, PACK) == PACK.energy_j
    track = BatteryTrack(PACK)
    track.report = report(0.9, 16.8)
    assert track.remaining_j(0.0) == pytest.approx(0.9 * PACK.energy_j)
    assert track.source == "autopilot"


def test_the_lockstep_simulators_report_is_taken_as_it_is() -> None:
    track = BatteryTrack(PACK)
    track.report = report(0.9, 10.0, source="sim")
    assert track.remaining_j(0.0) == pytest.approx(0.9 * PACK.energy_j)
    assert track.source == "autopilot"


def test_the_budget_message_says_the_source() -> None:
    core = flying()
    core.on_battery(report(0.98, 13.6).model_copy(update={"stamp_ns": START_NS + 2 * DT_NS}))
    for k in range(3, 25):
        core.step(START_NS + k * DT_NS, state(k))
    budget = core.take_budget() or core.budget.last
    assert budget is not None and budget.battery_source == "voltage"


def test_the_pause_takes_the_cause_the_autopilot_names_after_its_mode_change() -> None:
    core = flying()
    t = START_NS + 3 * DT_NS
    core.on_vehicle_status(vs(t, mode="HOLD", thrust_withheld="mode", hold_reason="gcs_mode_change",
                              hold_reason_detail="mode MANUAL -> HOLD, not asked by Seaway"))
    _, _, st = core.step(t + DT_NS, state(3))
    assert st.state == "paused" and HOLD_REASON_TEXT["gcs_mode_change"] in st.reason
    said = core.on_vehicle_status(vs(t + 2, mode="HOLD", thrust_withheld="mode",
                                     hold_reason="battery", hold_reason_detail="Battery 1 is low"))
    assert said is not None and HOLD_REASON_TEXT["battery"] in said and "Battery 1 is low" in said
    _, _, st = core.step(t + 2 * DT_NS, state(4))
    assert st.state == "paused" and HOLD_REASON_TEXT["battery"] in st.reason, st.reason
    assert "Battery 1 is low" in st.reason
