"""The report's energy section (issue #17 item 5): the controller's energy budget along a mission
against the energy the report integrates, worked out by hand on a boat that uses 21 W.

The boat sails north at 1 m/s from P0 (0, 0) to P1 (10, 0) (r_COA 1 m), so it enters the last
circle at 9 s; the simulator's propulsion integral grows 2 J per 0.1 s period (20 W) and T^w is
1 W: 21 J/s, so finishing takes 21 (9 - t) J from time t. Budgets are constructed here.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    BatteryState,
    EnergyBudget,
    MissionAccepted,
    MissionStatus,
    SimTruth,
    Waypoint,
)
from seaway.vessel.metrics import mission_metrics
from seaway_recorder import attachments, budget, report, report_render
from seaway_recorder.core import RecordingWriter

DT_NS = 100_000_000
WPS = [(0.0, 0.0), (10.0, 0.0)]
POWER_W = 21.0
END_S = 9.0


def truth(k: int) -> SimTruth:
    return SimTruth(stamp_ns=k * DT_NS, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * k, y_m=0.0,
                    psi_rad=0.0, thrust_port_n=1.0, thrust_starboard_n=1.0, energy_j=2.0 * k)


def metrics(periods: int = 120):
    states = [truth(k) for k in range(periods)]
    return mission_metrics(states, WPS, 1.0, 1.0, energy_j=[s.energy_j for s in states],
                           mission_start_ns=0, state_source="sim/truth")


def plan(k: int, factor: float = 1.0, **fields) -> EnergyBudget:
    """The budget at period k, predicting ``factor`` x what finishing takes from there."""
    t = 0.1 * k
    to_go = factor * POWER_W * max(END_S - t, 0.0)
    base = dict(stamp_ns=k * DT_NS, mission_id="m", energy_used_j=POWER_W * t, energy_to_go_j=to_go,
                energy_to_go_low_j=0.8 * to_go, energy_to_go_high_j=1.2 * to_go,
                energy_to_home_j=3.0 * 0.1 * k, home_x_m=0.0, home_y_m=0.0,
                battery_remaining_j=500.0 - POWER_W * t, reserve_j=100.0, policy="warn",
                decision="none")
    return EnergyBudget(**(base | fields))


def test_a_recording_without_a_budget_says_so() -> None:
    section = budget.energy_section([], metrics(), 0)
    assert section.to_json() == {"recorded": False, "note": "no energy budget recorded"}
    assert budget.table_rows(section.to_json()) == [("energy budget", "-", "no energy budget recorded")]


def test_predictions_against_the_energy_actually_used_with_errors_in_percent() -> None:
    # 20 % high at the start, 10 % low from half way on: errors +20 % and -10 %.
    budgets = [plan(k, 1.2 if k < 45 else 0.9) for k in range(90)]
    budgets[60:] = [plan(k, 0.9, decision="warn", decided_ns=60 * DT_NS, reason="why")
                    for k in range(60, 90)]
    s = budget.energy_section(budgets, metrics(), 0).to_json()
    assert s["recorded"] and s["samples"] == 90
    assert s["energy_used_j"] == pytest.approx(POWER_W * END_S)
    start, half = s["prediction"]["start"], s["prediction"]["half"]
    assert start["t_s"] == 0.0 and start["actual_j"] == pytest.approx(POWER_W * END_S)
    assert start["predicted_j"] == pytest.approx(1.2 * POWER_W * END_S)
    assert start["error_pct"] == pytest.approx(20.0)
    assert start["low_j"] == pytest.approx(0.8 * start["predicted_j"])
    assert half["t_s"] == pytest.approx(4.5) and half["error_pct"] == pytest.approx(-10.0)
    assert half["actual_j"] == pytest.approx(POWER_W * 4.5)
    assert s["prediction"]["last_half_max_abs_error_pct"] == pytest.approx(10.0)
    assert s["decision"] == "warn" and s["decided_t_s"] == pytest.approx(6.0) and s["reason"] == "why"
    assert s["battery_remaining_start_j"] == 500.0
    assert s["battery_remaining_end_j"] == pytest.approx(500.0 - POWER_W * 8.9)
    assert s["energy_to_home_end_j"] == pytest.approx(3.0 * 8.9)
    rows = dict((a.strip(), (b, c)) for a, b, c in budget.table_rows(s))
    assert rows["to finish, predicted at start"][0] == "226.8"
    assert "error +20.0 %" in rows["to finish, predicted at start"][1]
    assert "error -10.0 %" in rows["to finish, predicted at half way"][1]
    assert rows["decision"] == ("warn", "at 6.0 s: why")


def test_the_end_is_the_reports_and_later_budgets_are_not_the_missions() -> None:
    # Budgets published after the last circle was entered (and another mission's) are left out.
    budgets = [plan(k) for k in range(120)] + [plan(5, mission_id="other", energy_to_home_j=1e6)]
    mine = budget.mission_budgets(budgets, "m", 0, 95 * DT_NS)
    assert [b.stamp_ns for b in mine] == [k * DT_NS for k in range(96)]
    s = budget.energy_section(mine, metrics(), 0).to_json()
    assert s["energy_to_home_end_j"] == pytest.approx(3.0 * 9.0)  # at 9 s, the report's end
    assert s["prediction"]["start"]["error_pct"] == pytest.approx(0.0, abs=1e-9)


def test_an_unfinished_mission_has_figures_but_no_error() -> None:
    met = metrics(periods=50)  # stopped at 4.9 s, short of the circle
    assert not met.completed
    batteries = [BatteryState(stamp_ns=k * DT_NS, source="sim", remaining_j=400.0 - k)
                 for k in range(0, 50, 10)]
    s = budget.energy_section([plan(k) for k in range(50)], met, 0, batteries).to_json()
    assert s["prediction"] is None and "did not complete" in s["prediction_note"]
    assert s["energy_to_go_start_j"] == pytest.approx(POWER_W * END_S)
    assert s["battery_reported"] == {"source": "vehicle/battery", "remaining_start_j": 400.0,
                                     "remaining_end_j": 360.0}
    rows = dict((a.strip(), (b, c)) for a, b, c in budget.table_rows(s))
    assert "did not complete" in rows["to finish, predicted at start"][1]
    assert rows["decision"][0] == "none"


def test_a_return_home_is_reported_on_both_flights(tmp_path: Path) -> None:
    """The budget decides the return at 5 s (x = 5 m): the controller replaces mission 'm' by
    'm/return' (back to P0) in the same period; the report has an energy section for each flight,
    the decision on both, and the prediction's errors only on the one that completed."""
    w = RecordingWriter(tmp_path / "recording.mcap", attachments=attachments.scenario_attachments("lake")[0],
                        foxglove=False)
    w.open(0)

    def put(spec, msg, k: int) -> None:
        w.write(spec.key("vessel1"), msg.encode(), "", k * DT_NS)

    def accepted(mission_id: str, wps: list[tuple[float, float]], k: int) -> MissionAccepted:
        return MissionAccepted.make(stamp_ns=k * DT_NS, accepted_ns=k * DT_NS, mission_id=mission_id,
                                    coa_radius_m=1.0, task_power_w=1.0, controller="cc-empc",
                                    waypoints=[Waypoint(x_m=x, y_m=y) for x, y in wps],
                                    predict_disturbance=False)

    put(keys.MISSION_ACCEPTED, accepted("m", WPS, 0), 0)
    for k in range(96):
        x = 0.1 * k if k <= 50 else 5.0 - 0.1 * (k - 50)
        put(keys.SIM_TRUTH, truth(k).model_copy(update={"x_m": x}), k)
        back = k >= 50
        if k == 50:
            put(keys.MISSION_ACCEPTED, accepted("m/return", [(5.0, 0.0), (0.0, 0.0)], k), k)
        done = back and x <= 1.0 + 1e-9
        put(keys.MISSION_STATUS, MissionStatus.make(
            stamp_ns=k * DT_NS, state="complete" if done else "active",
            mission_id="m/return" if back else "m", active_leg=1, waypoint_count=2), k)
        decided = dict(decision="return", decided_ns=50 * DT_NS, reason="home + reserve reached")
        if k <= 50:  # the deciding period's budget is the outbound flight's
            put(keys.MISSION_ENERGY, plan(k, **(decided if k == 50 else {})), k)
        if back and not done:
            put(keys.MISSION_ENERGY, plan(k, mission_id="m/return", returning=True,
                                          energy_to_go_j=POWER_W * (x - 1.0), **decided), k)
    w.close(96 * DT_NS)
    res = report.analyse([tmp_path / "recording.mcap"])
    out, back = res["missions"][0]["energy_budget"], res["missions"][1]["energy_budget"]
    assert [m["mission_id"] for m in res["missions"]] == ["m", "m/return"]
    assert out["samples"] == 51 and out["decision"] == "return" and out["decided_t_s"] == 5.0
    assert out["prediction"] is None and "did not complete" in out["prediction_note"]
    assert back["returning"] and back["decision"] == "return" and back["decided_t_s"] == 0.0
    assert res["energy_budget"] == back  # the report is about the last flight
    # Home at 1 m/s, 21 W, ending on P0's circle (x = 1 m) at 9 s: predicted exactly.
    assert back["energy_used_j"] == pytest.approx(POWER_W * 4.0)
    assert back["prediction"]["start"]["error_pct"] == pytest.approx(0.0, abs=1e-9)
    shown = report_render.table(res)
    assert "'m': completed NO" in shown and "energy budget: return at 5.0 s" in shown


# -- one energy used (issue 56 item 13) ---------------------------------------------------------


def test_a_live_mission_started_before_the_first_battery_report_has_a_battery_start() -> None:
    # The first budgets were priced before the autopilot's first report reached the controller.
    budgets = [plan(k, battery_remaining_j=None) if k < 3 else plan(k) for k in range(90)]
    s = budget.energy_section(budgets, metrics(), 0).to_json()
    assert s["battery_remaining_start_j"] == pytest.approx(500.0 - POWER_W * 0.3)
    start_row = dict((a.strip(), b) for a, b, _ in budget.table_rows(s))["battery remaining start / end"]
    assert not start_row.startswith("-")


def test_the_report_gives_one_energy_used_and_the_controllers_count_as_its_check(tmp_path: Path) -> None:
    """Truth, statuses counting 21 J/s (a little late: 0.2 s past the end) and budgets priced once a
    second: one 'energy used' (the report's integral), the controller's count at the same end beside
    it, and neither the budget's stale count nor the status's last one as another energy used."""
    w = RecordingWriter(tmp_path / "recording.mcap", attachments=attachments.scenario_attachments("lake")[0],
                        foxglove=False)
    w.open(0)

    def put(spec, msg, k: int) -> None:
        w.write(spec.key("vessel1"), msg.encode(), "", k * DT_NS)

    put(keys.MISSION_ACCEPTED, MissionAccepted.make(
        stamp_ns=0, accepted_ns=0, mission_id="m", coa_radius_m=1.0, task_power_w=1.0,
        controller="cc-empc", waypoints=[Waypoint(x_m=x, y_m=y) for x, y in WPS],
        predict_disturbance=False), 0)
    for k in range(96):
        put(keys.SIM_TRUTH, truth(k), k)
        done = k >= 92  # the controller's estimate enters the circle 0.2 s after the truth
        put(keys.MISSION_STATUS, MissionStatus.make(
            stamp_ns=k * DT_NS, state="complete" if done else "active", mission_id="m", active_leg=1,
            waypoint_count=2, energy_used_j=POWER_W * 0.1 * min(k, 92)), k)
        if k % 10 == 0:
            put(keys.MISSION_ENERGY, plan(k), k)
    w.close(96 * DT_NS)
    res = report.analyse([tmp_path / "recording.mcap"])
    used = res["energy_used"]
    assert used["j"] == pytest.approx(res["metrics"]["energy_j"]) == pytest.approx(POWER_W * END_S)
    assert used["controller_count_j"] == pytest.approx(POWER_W * END_S)  # at the report's end
    assert used["controller_count_difference_pct"] == pytest.approx(0.0, abs=1e-6)
    assert "controller_energy_used_j" not in res["energy_budget"]
    rows = [line for line in report_render.table(res).splitlines()[3:]]
    named = [line for line in rows if "energy used" in line.lower() or "energy_used" in line]
    assert len(named) == 1 and named[0].startswith("energy used"), rows
    count = next(line for line in rows if line.strip().startswith("controller's count"))
    assert "189.00" in count


def test_the_band_says_whether_it_held_the_actual_its_coverage_and_a_poor_prediction_is_flagged() -> None:
    budgets = [plan(k, 1.2 if k < 45 else 1.0) for k in range(90)]  # band 0.8..1.2 x predicted
    cc = budget.energy_section(budgets, metrics(), 0, controller="cc-empc").to_json()
    assert cc["prediction"]["start"]["in_band"] is True  # actual = predicted / 1.2 >= 0.8 x
    assert cc["prediction_warning"] is None
    assert cc["band_coverage"]["derived"] == 1.0 and 0.0 < cc["band_coverage"]["unseen"] <= 1.0
    rows = dict((a.strip(), (b, c)) for a, b, c in budget.table_rows(cc))
    assert "band's measured coverage" in rows and "WARNING" not in rows
    assert "inside" in rows["to finish, predicted at start"][1]
    wide = [plan(k, 1.5) for k in range(90)]  # actual = predicted / 1.5, below 0.8 x predicted
    nmpc = budget.energy_section(wide, metrics(), 0, controller="nmpc").to_json()
    assert nmpc["prediction"]["start"]["in_band"] is False
    assert nmpc["prediction_warning"] and "nmpc" in nmpc["prediction_warning"]
    rows = dict((a.strip(), (b, c)) for a, b, c in budget.table_rows(nmpc))
    assert "nmpc" in rows["WARNING"][1] and "OUTSIDE" in rows["to finish, predicted at start"][1]
    unknown = budget.energy_section(budgets, metrics(), 0).to_json()  # controller not recorded
    assert unknown["band_coverage"] is None and unknown["prediction_warning"] is None
