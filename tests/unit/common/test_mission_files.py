"""Mission and scenario files: shipped ones load; bad ones fail naming the problem."""

from __future__ import annotations

from pathlib import Path

import pytest
from seaway.contract.config import ConfigError, deploy_path
from seaway.simkit.scenario import load_mission, load_scenario


def test_every_shipped_scenario_and_mission_loads() -> None:
    for f in sorted(deploy_path("scenarios").glob("*.toml")):
        sc = load_scenario(f)
        assert sc.name == f.stem
    for f in sorted(deploy_path("missions").glob("*.toml")):
        req = load_mission(f).to_request(1)
        assert len(req.waypoints) >= 2


def test_paper_scenarios_follow_reproduction_md() -> None:
    for n in range(1, 6):
        m = load_mission(f"paper-c{n}")
        assert m.waypoints_m == [(0.0, 0.0), (8.0, 0.0), (5.13, 8.57)]
        assert (m.coa_radius_m, m.task_power_w) == (1.0, 0.49)
        assert load_scenario(f"paper-c{n}").vessel == "paper-sim"


def write(tmp: Path, text: str) -> Path:
    p = tmp / "m.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(("text", "problem"), [
    ("coa_radius_m = 1\ntask_power_w = 0.49\n", "exactly one of waypoints_m and waypoints_deg"),
    ("waypoints_m = [[0,0],[1,1]]\nwaypoints_deg = [[1,1],[2,2]]\ncoa_radius_m = 1\ntask_power_w = 0.49\n",
     "exactly one of"),
    ("waypoints_m = [[0,0]]\ncoa_radius_m = 1\ntask_power_w = 0.49\n",
     "waypoints_m: List should have at least 2"),
    ("waypoints_m = [[0,0],[1,1]]\ncoa_radius_m = 0\ntask_power_w = 0.49\n",
     r"coa_radius_m: .*outside the allowed range \(0, 10000\] m"),
    ("waypoints_m = [[0,0],[1,1]]\ncoa_radius_m = 1\ntask_power_w = 0.49\ncontroler = 'nmpc'\n",
     "controler: unknown field"),
    ("waypoints_m = [[0,0],[1,nan]]\ncoa_radius_m = 1\ntask_power_w = 0.49\n", "finite number"),
    ("waypoints_m = [[0,0],[1,1]\n", "not valid TOML"),
    # Out of range: the error names the field and the allowed range (issue 14, item 11).
    ("waypoints_m = [[0,0],[1,1]]\ncoa_radius_m = 1\ntask_power_w = 0\n",
     r"task_power_w: Value error, 0 W is outside the allowed range \(0, 10000\] W"),
    ("waypoints_m = [[0,0],[1,1]]\ncoa_radius_m = 1\ntask_power_w = 1e300\n",
     r"task_power_w: Value error, 1e\+300 W is outside the allowed range \(0, 10000\] W"),
    ("waypoints_deg = [[95,8],[47,8]]\ncoa_radius_m = 1\ntask_power_w = 1\n",
     r"waypoints_deg.0.0: Value error, 95 deg is outside the allowed range \[-90, 90\] deg"),
    ("waypoints_deg = [[47,8],[47,200]]\ncoa_radius_m = 1\ntask_power_w = 1\n",
     r"waypoints_deg.1.1: Value error, 200 deg is outside the allowed range \[-180, 180\] deg"),
])
def test_bad_mission_files(tmp_path: Path, text: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem):
        load_mission(write(tmp_path, text))


def test_bad_scenario_names_the_field(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    p.write_text('name = "x"\nseed = 1\nvessel = "paper-sim"\n[[disturbances]]\nkind = "tornado"\n')
    with pytest.raises(ConfigError, match=r"disturbances\.0: Input tag 'tornado'"):
        load_scenario(p)
    p.write_text('name = "x"\nseed = 1\nvessel = "paper-sim"\n[[disturbances]]\nkind = "world_grid"\n'
                 'file = "missing.json"\n')
    with pytest.raises(ConfigError, match=r"missing\.json"):
        load_scenario(p)
    with pytest.raises(ConfigError, match=r"no scenario .no-such-scenario. .deploy/scenarios/.; there"):
        load_scenario("no-such-scenario")


def test_a_file_of_another_kind_is_named_as_such_not_as_a_missing_scenario(tmp_path: Path) -> None:
    """``seaway mission survey.plan`` said "no scenario 'survey.plan'; ... or give a file's path",
    although a file's path was given."""
    plan = tmp_path / "survey.plan"
    plan.write_text("{}")
    with pytest.raises(ConfigError, match=r"\.toml or \.json file, not \.plan"):
        load_scenario(plan)
    with pytest.raises(ConfigError, match="no scenario"):
        load_scenario("no-such-scenario")
