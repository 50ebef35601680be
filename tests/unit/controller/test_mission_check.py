"""mission_check.py: the check before a mission (issue #57 item 3): the figures, the bounds that
depend on the mission, the area's verdict and the energy refusal unless forced."""

from __future__ import annotations

import pytest
from seaway.area.model import OperatingArea
from seaway.contract.messages import MissionRequest, StateEstimate, Waypoint
from seaway.vessel.model import load_vessel
from seaway_controller.mission_check import check_mission

BOAT = load_vessel("paper-boat")


def request(points, coa_m: float = 2.0, **kw) -> MissionRequest:
    return MissionRequest.make(stamp_ns=0, mission_id="m", coa_radius_m=coa_m, task_power_w=250.0,
                               waypoints=[Waypoint(x_m=x, y_m=y) for x, y in points], **kw)


def test_a_long_leg_the_battery_cannot_fly_is_refused_unless_forced() -> None:
    long_leg = request([(0.0, 0.0), (4500.0, 0.0)])
    out = check_mission(long_leg, BOAT, battery_j=298_000.0)
    assert out.verdict == "refused" and len(out.reasons) == 1
    assert "less its 106560 J reserve" in out.reasons[0] and "force" in out.reasons[0]
    # About 470 J a metre at the lake boat's 1 m/s cruise: some 2 MJ there, as much back.
    assert out.energy_mission_j == pytest.approx(2.1e6, rel=0.2)
    assert out.energy_home_from_last_j == pytest.approx(out.energy_mission_j, rel=0.1)
    assert out.path_length_m == 4500.0 and out.predicted_time_s == pytest.approx(4500 / 1.008, rel=0.01)
    assert out.battery_after_j == pytest.approx(298_000.0 - out.energy_mission_j)
    forced = check_mission(long_leg.model_copy(update={"force": True}), BOAT, battery_j=298_000.0)
    assert forced.verdict == "ok" and forced.forced and forced.notes[0].startswith("forced: ")
    # Enough battery: ok, with the same figures.
    assert check_mission(long_leg, BOAT, battery_j=6e6).verdict == "ok"
    # No battery known: no energy verdict, said.
    unknown = check_mission(long_leg, BOAT)
    assert unknown.verdict == "ok" and "battery not known" in unknown.notes[0]


def test_an_acceptance_radius_wider_than_half_a_leg_is_refused() -> None:
    out = check_mission(request([(0.0, 0.0), (20.0, 0.0), (20.0, 10.0)], coa_m=10_000.0), BOAT)
    assert out.verdict == "refused"
    assert "coa_radius_m 10000 m is not under 0.5 of the shortest leg (1->2, 10 m)" in out.reasons[0]
    assert check_mission(request([(0.0, 0.0), (20.0, 0.0), (20.0, 10.0)], coa_m=4.9),
                         BOAT).verdict == "ok"


def test_the_area_verdict_names_the_leg_and_the_way_from_the_vessel() -> None:
    area = OperatingArea.make(keep_in={"vertices_m": [(-5, -5), (30, -5), (30, 30), (-5, 30)]},
                              keep_out_circles=[{"name": "buoy", "center_m": (10.0, 10.0),
                                                 "radius_m": 2.0}])
    out = check_mission(request([(0.0, 0.0), (20.0, 0.0), (40.0, 0.0)]), BOAT, area=area)
    assert out.area == "refused" and "leg 1->2 leaves the keep-in area at north 30.0 m" in out.reasons[0]
    here = StateEstimate.make(stamp_ns=0, u_mps=0.0, v_mps=0.0, r_radps=0.0, x_m=20.0, y_m=20.0,
                              psi_rad=0.0)
    out = check_mission(request([(0.0, 0.0), (20.0, 0.0)]), BOAT, area=area, state=here)
    assert "the way from the vessel to P_0 enters keep-out area keep_out_circles[0] 'buoy'" in out.reasons[0]
    assert out.live and out.path_length_m == pytest.approx(20.0 * 2 ** 0.5 + 20.0)
    away = request([(0.0, 0.0), (20.0, 0.0)], home=Waypoint(x_m=50.0, y_m=0.0))
    out = check_mission(away, BOAT, area=area)
    assert "home at north 50.0 m, east 0.0 m is outside the keep-in area" in out.reasons[0]


def test_the_json_form_holds_the_verdict_and_the_figures() -> None:
    d = check_mission(request([(0.0, 0.0), (20.0, 0.0)]), BOAT, battery_j=500_000.0).to_dict()
    assert d["verdict"] == "ok" and d["reasons"] == [] and d["area"] == "none"
    for k in ("path_length_m", "predicted_time_s", "energy_mission_j", "battery_after_j",
              "reserve_j", "energy_home_from_last_j"):
        assert isinstance(d[k], float), k
