"""Issue 14, item 11: bad input gives a clear error naming the field and its allowed range, before
any process starts (no traceback, nothing launched): a vessel file with a negative mass under
``seaway launch --check``, ``seaway bench model --vessel FILE``, a mission at latitude 95 deg or
longitude 200 deg, a task power of 0 or 1e300 W."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

pytestmark = pytest.mark.system
SEAWAY = str(Path(sys.executable).parent / "seaway")


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([SEAWAY, *args], capture_output=True, text=True, timeout=120, cwd=REPO,
                          check=False)


def refused(out: subprocess.CompletedProcess, *texts: str) -> None:
    assert out.returncode == 2, (out.returncode, out.stdout, out.stderr)
    assert "Traceback" not in out.stderr and "valid" not in out.stdout, out.stderr
    for text in texts:
        assert text in out.stderr, out.stderr


@pytest.fixture
def bad_vessel(tmp_path: Path) -> Path:
    good = (REPO / "deploy" / "vessels" / "paper-sim.toml").read_text()
    path = tmp_path / "negative-mass.toml"
    path.write_text(good.replace("m11_kg = 12.84", "m11_kg = -12.84"))
    return path


def scenario_with(tmp_path: Path, vessel: str | None = None, mission: str | None = None) -> Path:
    """paper-c1 with another vessel file, or another ``[mission]`` table (its last table)."""
    lines = (REPO / "deploy" / "scenarios" / "paper-c1.toml").read_text().splitlines()
    if vessel is not None:
        lines = [f'vessel = "{vessel}"' if line.startswith("vessel =") else line for line in lines]
    if mission is not None:
        lines = [*lines[:lines.index("[mission]")], mission]
    path = tmp_path / "scenario.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_launch_check_refuses_a_vessel_file_with_a_negative_mass(tmp_path, bad_vessel) -> None:
    sc = scenario_with(tmp_path, vessel=str(bad_vessel))
    refused(run("launch", "sim-batch", "--scenario", str(sc), "--check"),
            "model vessel file", str(bad_vessel), "m11_kg: Input should be greater than 0")
    # The same scenario with a good vessel file is valid: it is the vessel file that was refused.
    ok = run("launch", "sim-batch", "--scenario", str(scenario_with(tmp_path, vessel="paper-sim")),
             "--check")
    assert ok.returncode == 0 and "valid" in ok.stdout, ok.stderr


def test_bench_model_refuses_a_bad_vessel_file_without_a_traceback(bad_vessel) -> None:
    refused(run("bench", "model", "--vessel", str(bad_vessel)),
            "seaway bench model:", "m11_kg: Input should be greater than 0")
    refused(run("bench", "model", "--vessel", "/nonexistent/vessel.toml"), "cannot read")


@pytest.mark.parametrize(("mission", "text"), [
    ("[mission]\nwaypoints_deg = [[95.0, 8.0], [47.0, 8.0]]\ncoa_radius_m = 1.0\ntask_power_w = 0.49",
     "mission.waypoints_deg.0.0: Value error, 95 deg is outside the allowed range [-90, 90] deg"),
    ("[mission]\nwaypoints_deg = [[47.0, 8.0], [47.0, 200.0]]\ncoa_radius_m = 1.0\ntask_power_w = 0.49",
     "mission.waypoints_deg.1.1: Value error, 200 deg is outside the allowed range [-180, 180] deg"),
    ("[mission]\nwaypoints_m = [[0.0, 0.0], [4.0, 0.0]]\ncoa_radius_m = 1.0\ntask_power_w = 0",
     "mission.task_power_w: Value error, 0 W is outside the allowed range (0, 10000] W"),
])
def test_a_mission_out_of_range_is_refused_by_launch_and_mission(tmp_path, mission, text) -> None:
    sc = scenario_with(tmp_path, mission=mission)
    refused(run("launch", "sim-batch", "--scenario", str(sc), "--check"), text)
    # seaway mission refuses it before it opens a session (no stack needed).
    refused(run("mission", str(sc), "--timeout", "1"), text)


def test_a_task_power_option_out_of_range_is_refused(tmp_path) -> None:
    # Refused by the option's own parser, with the mission model's bound (MAX_TASK_POWER_W).
    refused(run("launch", "sim-batch", "--task-power-w", "1e300", "--check"),
            "--task-power-w", "'1e300': the task power must be finite, in (0, 10000] W")
    refused(run("launch", "sim-batch", "--task-power-w", "0", "--check"),
            "--task-power-w", "'0': the task power must be finite, in (0, 10000] W")
