"""``seaway mission check`` as an operator runs it (issue #57 item 3): the real CLI, at the desk."""

from __future__ import annotations

import json
import math
import signal
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


def _plan(path: Path, north_east_m: list[tuple[float, float]], fence_m: list[tuple[float, float]]
          | None = None) -> Path:
    """A QGroundControl plan written by hand (QGC's own layout, not Seaway's writer): the lake
    scenario's origin, NAV_WAYPOINTs with a 2 m acceptance radius, and an inclusion fence."""
    from seaway.vessel.frames import GeoOrigin

    origin = GeoOrigin.from_degrees(28.18, 112.94, 0.0)  # deploy/scenarios/lake.toml [origin]

    def deg(n: float, e: float) -> list[float]:
        lat, lon, _ = origin.to_geodetic(n, e, 0.0)
        return [math.degrees(lat), math.degrees(lon)]

    items = [{"type": "SimpleItem", "command": 16, "frame": 3, "autoContinue": True,
              "doJumpId": i + 1, "params": [0, 2.0, 0, None, *deg(n, e), 0]}
             for i, (n, e) in enumerate(north_east_m)]
    doc = {"fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
           "mission": {"version": 2, "firmwareType": 3, "vehicleType": 11, "cruiseSpeed": 1.0,
                       "hoverSpeed": 1.0, "plannedHomePosition": [*deg(0, 0), 0], "items": items},
           "geoFence": {"version": 2, "circles": [], "polygons": [] if fence_m is None else [
               {"version": 1, "inclusion": True, "polygon": [deg(n, e) for n, e in fence_m]}]},
           "rallyPoints": {"version": 2, "points": []}}
    path.write_text(json.dumps(doc))
    return path


def test_a_qgroundcontrol_plan_is_checked_with_its_own_fence(tmp_path: Path) -> None:
    """A ``.plan`` is read (#57 item 3: "A .plan carries its own operating area"): its waypoints
    through the default scenario's origin, its acceptance radius, its geoFence as the area; the
    task power it does not give is the default scenario's, said in a note."""
    square = [(0.0, 0.0), (22.0, 0.0), (22.0, 18.0), (0.0, 18.0)]
    ok = check(str(_plan(tmp_path / "square.plan", square)), "--json")
    assert ok.returncode == 0, ok.stderr
    out = json.loads(ok.stdout)
    assert out["verdict"] == "ok" and out["path_length_m"] == pytest.approx(62.0, abs=0.05)
    assert out["area_source"] == "scenario lake"  # no fence in the file: the scenario's area
    assert any("task_power_w" in n for n in out["notes"])
    assert not any("own operating area" in n for n in out["notes"])
    # Its own fence, which the second leg leaves: refused naming the leg, the file as the area.
    fenced = _plan(tmp_path / "fenced.plan", square,
                   fence_m=[(-5.0, -5.0), (30.0, -5.0), (30.0, 10.0), (-5.0, 10.0)])
    refused = check(str(fenced), "--json", "--task-power-w", "250")
    assert refused.returncode == 1, refused.stderr
    out = json.loads(refused.stdout)
    assert out["verdict"] == "refused" and out["area"] == "refused"
    assert out["area_source"] == str(fenced)
    # and says that a flight keeps to its run's area, not the file's
    assert any("own operating area" in n for n in out["notes"])
    assert any("leaves the keep-in area" in r for r in out["reasons"])
    assert not any("task_power_w" in n for n in out["notes"])  # given on the command line
    # Unreadable: not JSON, or no waypoints: exit 2 naming the file.
    broken = tmp_path / "broken.plan"
    broken.write_text("{ not json")
    bad = check(str(broken))
    assert bad.returncode == 2 and "broken.plan" in bad.stderr
    assert check(str(fenced), "--task-power-w", "-3").returncode == 2


def test_live_check_against_the_running_vessel(procs, zenoh_env, tmp_path: Path) -> None:
    """``--live`` (#57 item 3: "With a running vessel it checks against that vessel's live state"):
    a real-time lake stack (``seaway launch sim``, no mission); the check takes the vessel's state,
    the area its controller enforces and the stack's model; a far mission is refused by that area,
    and with no stack at all the live check says so (exit 2)."""

    run = tmp_path / "run"
    launcher = procs.launch_ready(zenoh_env, "sim", "--scenario", "lake", "--run-dir", str(run),
                                  "--no-mission", "--no-report")

    def live(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess:
        return subprocess.run([*SEAWAY, "mission", "check", *args, "--live", "--json", "--timeout",
                               str(timeout_s)], capture_output=True, text=True, timeout=120,
                              check=False, cwd=REPO, env=zenoh_env)

    ok = live("deploy/missions/lake-square.toml")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    out = json.loads(ok.stdout)
    assert out["against"] == "vessel vessel1" and out["vessel"] == "paper-boat"
    assert out["area"] == "ok" and out["area_source"]  # the area the controller enforces
    far = tmp_path / "far.toml"
    far.write_text('mission_id = "far"\nwaypoints_m = [[0.0, 0.0], [200.0, 0.0]]\n'
                   'coa_radius_m = 2.0\ntask_power_w = 250.0\n')
    refused = live(str(far))
    assert refused.returncode == 1, refused.stdout + refused.stderr
    assert json.loads(refused.stdout)["area"] == "refused"
    assert procs.stop(launcher, signal.SIGINT, timeout_s=60) < 60
    none = live("deploy/missions/lake-square.toml", "--vessel-file", "paper-boat", timeout_s=3.0)
    assert none.returncode == 2 and "nav/state" in none.stderr, none.stderr
