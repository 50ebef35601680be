"""``seaway mission check`` as an operator runs it (issue #57 item 3): the real CLI, at the desk."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO

pytestmark = pytest.mark.system
SEAWAY = [sys.executable, "-m", "seaway.tools.cli"]


def check(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*SEAWAY, "mission", "check", *args], capture_output=True, text=True,
                          timeout=120, check=False, cwd=REPO)


def test_ok_refused_and_unreadable_by_exit_status_and_json(tmp_path: Path) -> None:
    ok = check("deploy/missions/lake-square.toml", "--json")
    assert ok.returncode == 0, ok.stderr
    out = json.loads(ok.stdout)
    assert out["verdict"] == "ok" and out["reasons"] == [] and out["area"] == "ok"
    assert out["against"] == "scenario lake" and out["path_length_m"] == pytest.approx(90.0)
    assert out["energy_mission_j"] > 0 and out["battery_after_j"] < out["battery_j"]

    # The cases: a 4.5 km leg on 298 kJ, and an acceptance radius of 10 km.
    far = tmp_path / "far.toml"
    far.write_text('mission_id = "far"\nwaypoints_m = [[0.0, 0.0], [4500.0, 0.0]]\n'
                   'coa_radius_m = 2.0\ntask_power_w = 250.0\n')
    refused = check(str(far), "--json", "--battery-j", "298000")
    assert refused.returncode == 1
    out = json.loads(refused.stdout)
    assert out["verdict"] == "refused" and any("reserve" in r for r in out["reasons"])
    # 4.5 km leaves the lake's keep-in area too (the default scenario's area applies).
    assert out["area"] == "refused" and any("leg 0->1 leaves the keep-in area" in r
                                            for r in out["reasons"])
    wide = tmp_path / "wide.toml"
    wide.write_text('waypoints_m = [[0.0, 0.0], [20.0, 0.0]]\ncoa_radius_m = 10000.0\n'
                    'task_power_w = 250.0\n')
    text = check(str(wide))
    assert text.returncode == 1 and "coa_radius_m 10000 m is not under" in text.stdout
    assert "verdict: REFUSED" in text.stdout

    # A mission file's fields are validated, each named.
    bad = tmp_path / "bad.toml"
    bad.write_text('waypoints_m = [[0.0, 0.0], [20.0, 0.0]]\ncoa_radius_m = 2.0\n'
                   'task_power_w = 250.0\nat_rest = "float"\n')
    unreadable = check(str(bad))
    assert unreadable.returncode == 2 and "at_rest" in unreadable.stderr
    assert check(str(tmp_path / "none.toml")).returncode == 2
