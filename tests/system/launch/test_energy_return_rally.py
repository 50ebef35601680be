"""The energy budget's return to the nearest place (issue #57 item 2) through the real processes:
a lockstep ``seaway launch sim-batch`` of the lake with a battery too small for its mission and a
rally point on the far side of its square. The return goes to the cheapest to reach of home and
the rally points whose way stays in the operating area: here the rally point, not home. The
launcher ends the run on arriving there (its rally points come from the scenario's ``[area]``)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import BatteryState, MissionAccepted, MissionStatus, SimTruth
from seaway.recording import reader

from tests.conftest import free_port
from tests.system.launch.test_energy_return import _env, _scenario

pytestmark = pytest.mark.system
BIN = Path(sys.executable).parent
PIER = (22.0, 9.0)  # on the square's second leg, 24 m from home


@pytest.mark.timeout(600)
@pytest.mark.slow  # a lockstep lake run, tens of seconds
def test_a_low_battery_returns_to_the_nearer_rally_point(tmp_path) -> None:
    scenario, reserve = _scenario(tmp_path)
    scenario.write_text(scenario.read_text() + f'\n[[area.rally]]\nname = "pier"\n'
                        f"position_m = [{PIER[0]}, {PIER[1]}]\n")
    run_dir = tmp_path / "run"
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", str(scenario),
                          "--run-dir", str(run_dir)], env=_env(f"tcp/127.0.0.1:{free_port()}"),
                         capture_output=True, text=True, timeout=500, check=False)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]

    dec = reader.decode_vessel(reader.open_paths([run_dir]), None, [
        keys.MISSION_ACCEPTED.suffix, keys.MISSION_STATUS.suffix, keys.SIM_TRUTH.suffix,
        keys.VEHICLE_BATTERY.suffix])
    accepted = [a for a in dec.get(keys.MISSION_ACCEPTED.suffix) if isinstance(a, MissionAccepted)]
    back = accepted[-1]
    assert back.mission_id.endswith("/return")
    end = (back.waypoints[-1].x_m, back.waypoints[-1].y_m)
    assert end == PIER and (back.home_x_m, back.home_y_m) == PIER
    home = (accepted[0].home_x_m, accepted[0].home_y_m)  # where it was (estimated) at the start
    assert math.dist(home, (0.0, 0.0)) <= 1.0 and accepted[0].forced
    truths = [t for t in dec.get(keys.SIM_TRUTH.suffix) if isinstance(t, SimTruth)]
    start = next(i for i, t in enumerate(truths) if t.stamp_ns >= back.accepted_ns)
    # When it turned back, the pier was nearer than home.
    here = (truths[start].x_m, truths[start].y_m)
    assert math.dist(here, PIER) < math.dist(here, home)
    statuses = [s for s in dec.get(keys.MISSION_STATUS.suffix) if isinstance(s, MissionStatus)]
    assert statuses[-1].state == "complete" and statuses[-1].mission_id == back.mission_id
    assert math.dist((truths[-1].x_m, truths[-1].y_m), PIER) <= back.coa_radius_m + 0.5
    batteries = [b for b in dec.get(keys.VEHICLE_BATTERY.suffix) if isinstance(b, BatteryState)]
    assert batteries[-1].remaining_j >= reserve
    print(f"turned back at ({here[0]:.1f}, {here[1]:.1f}) m: pier {math.dist(here, PIER):.1f} m, "
          f"home {math.dist(here, home):.1f} m; {batteries[-1].remaining_j - reserve:.0f} J "
          "above the reserve at the end")


def test_a_batch_mission_the_battery_cannot_fly_is_refused_and_the_run_ends(tmp_path) -> None:
    """Not forced: the controller's mission check refuses it (the reply names the energy), and
    the batch run, whose end is the mission's, ends at once with status 1 instead of waiting."""
    scenario, _ = _scenario(tmp_path)
    scenario.write_text(scenario.read_text().replace("force = true\n", "", 1))
    out = subprocess.run([str(BIN / "seaway"), "launch", "sim-batch", "--scenario", str(scenario),
                          "--run-dir", str(tmp_path / "run"), "--no-report"],
                         env=_env(f"tcp/127.0.0.1:{free_port()}"), capture_output=True, text=True,
                         timeout=180, check=False)
    assert out.returncode == 1, out.stdout[-2000:] + out.stderr[-2000:]
    assert "REFUSED" in out.stdout and "send it with force" in out.stdout
    assert "the mission was refused" in out.stderr
