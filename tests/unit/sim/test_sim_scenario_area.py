"""A scenario's ``[area]`` (seaway.area.files): parsed and validated with the scenario, converted
through its origin, and holding its start; the lake's holds its missions' paths."""

from __future__ import annotations

import math

import pytest
from seaway.area.model import check_path
from seaway.contract.config import ConfigError
from seaway.simkit import scenario as sc

from tests.conftest import REPO


def lake_with(**changes) -> dict:
    doc = sc.load_scenario("lake").model_dump(mode="json", exclude_none=True)
    doc.update(changes)
    return doc


def test_the_lake_has_an_area_holding_its_start_and_its_missions() -> None:
    lake = sc.load_scenario("lake")
    area = lake.operating_area()
    assert area is not None and area.keep_in is not None and area.rally_points
    start = (lake.start.x_m, lake.start.y_m)
    for mission in (lake.mission, sc.load_mission(REPO / "deploy" / "missions" / "lake-square.toml")):
        verdict = check_path(area, mission.waypoints_m, start)
        assert verdict.ok, verdict.reason


def test_a_scenario_without_an_area_has_none() -> None:
    doc = lake_with()
    del doc["area"]
    assert sc.parse_scenario(doc).operating_area() is None


def test_an_area_in_degrees_goes_through_the_scenarios_origin() -> None:
    lat0, lon0 = 28.18, 112.94
    d = 0.0005  # about 55 m north, 49 m east
    ring = [[lat0 - d, lon0 - d], [lat0 + d, lon0 - d], [lat0 + d, lon0 + d], [lat0 - d, lon0 + d]]
    scen = sc.parse_scenario(
        lake_with(
            area={
                "keep_in": {"vertices_deg": ring},
                "keep_out": [{"center_deg": [lat0 + d / 2, lon0], "radius_m": 3.0}],
            }
        )
    )
    area = scen.operating_area()
    north, east = area.keep_in.vertices_m[2]
    assert 50.0 < north < 60.0 and 45.0 < east < 55.0
    assert math.isclose(area.keep_out_circles[0].center_m[1], 0.0, abs_tol=1e-6)


@pytest.mark.parametrize(
    ("area", "named"),
    [
        ({"keep_in": {"vertices_m": [[5.0, 5.0], [10.0, 5.0], [10.0, 10.0]]}}, "start"),
        ({"keep_in": {"vertices_m": [[-9.0, -9.0], [9.0, 9.0], [9.0, -9.0], [-9.0, 9.0]]}}, "cross"),
        ({"keep_out": [{"center_m": [0.0, 1.0], "radius_m": 2.0}]}, "start"),
        (
            {
                "keep_in": {"vertices_m": [[-9.0, -9.0], [9.0, -9.0], [9.0, 9.0]]},
                "rally": [{"position_m": [50.0, 0.0]}],
            },
            "rally_points[0]",
        ),
        ({"keep_in": {"vertices_m": [[-9.0, -9.0], [9.0, -9.0], [math.inf, 9.0]]}}, "finite"),
        ({"keep_out": [{"center_m": [0.0, 50.0]}]}, "radius_m"),
        ({"keep_in": {"vertices_m": [[-9.0, -9.0], [9.0, -9.0], [9.0, 9.0]]}, "keepout": []}, "keepout"),
    ],
)
def test_a_bad_area_is_refused_naming_what(area: dict, named: str) -> None:
    with pytest.raises(ConfigError) as err:
        sc.parse_scenario(lake_with(area=area), "lake.toml")
    assert named in str(err.value) and "lake.toml" in str(err.value)


def test_a_mission_home_outside_the_area_is_refused() -> None:
    doc = lake_with()
    doc["mission"]["home_m"] = [100.0, 0.0]
    with pytest.raises(ConfigError, match=r"mission\.home_m"):
        sc.parse_scenario(doc)
