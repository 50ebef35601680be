"""``seaway mission check`` on mission files whose coordinates are odd but real: a path across
the antimeridian is measured as the short way it is and checked against the scenario's keep-out
area; one across the globe is refused by its distance from the origin."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from seaway import mission_export
from seaway import mission_files as plans
from seaway.simkit.scenario import load_scenario
from seaway.tools.mission_check_cli import check_request, foreign_request

SCENARIO = """name = "dateline"
seed = 1
vessel = "paper-boat"
[origin]
lat_deg = 10.0
lon_deg = 179.9999
alt_m = 0.0
[mission]
waypoints_m = [[0.0, -30.0], [0.0, 30.0]]
coa_radius_m = 2.0
task_power_w = 250.0
[area.keep_in]
name = "lake"
vertices_m = [[-100.0, -100.0], [100.0, -100.0], [100.0, 100.0], [-100.0, 100.0]]
[[area.keep_out]]
name = "rock"
vertices_m = [[-5.0, 5.0], [5.0, 5.0], [5.0, 15.0], [-5.0, 15.0]]
"""


@pytest.mark.parametrize("north_m, verdict", [(0.0, "refused"), (30.0, "ok")])
def test_a_plan_across_the_antimeridian_is_checked_the_short_way(tmp_path: Path, north_m: float,
                                                                 verdict: str) -> None:
    (tmp_path / "dateline.toml").write_text(SCENARIO)
    scenario = load_scenario(tmp_path / "dateline.toml")
    east_deg = 30.0 / (111_320.0 * math.cos(math.radians(10.0)))  # 30 m each side of the origin
    north_deg = north_m / 110_600.0
    lon_w, lon_e = 179.9999 - east_deg, 179.9999 + east_deg - 360.0  # the east one is past 180
    doc = json.loads(json.dumps(mission_export.to_plan([(10.0 + north_deg, lon_w),
                                                         (10.0 + north_deg, lon_e)])))
    req, _ = foreign_request(tmp_path / "m.plan", plans.parse_plan(doc), scenario, None, None)
    out = check_request(req, scenario)
    assert out["path_length_m"] == pytest.approx(60.0, abs=0.5)
    assert out["verdict"] == verdict
    if verdict == "refused":  # the leg crosses the rock, 5 to 15 m east of the origin
        assert any("rock" in r for r in out["reasons"])


def test_a_plan_across_the_globe_is_refused_by_its_distance_from_the_origin(tmp_path: Path) -> None:
    (tmp_path / "dateline.toml").write_text(SCENARIO)
    scenario = load_scenario(tmp_path / "dateline.toml")
    doc = json.loads(json.dumps(mission_export.to_plan([(90.0, 0.0), (-90.0, 180.0)])))
    req, _ = foreign_request(tmp_path / "m.plan", plans.parse_plan(doc), scenario, None, None)
    out = check_request(req, scenario)
    assert out["verdict"] == "refused" and out["path_length_m"] is None
    assert any("from the origin" in r for r in out["reasons"])
