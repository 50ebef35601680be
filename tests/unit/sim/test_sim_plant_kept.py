"""The simulated vessel keeps its state across a sim restart (issue 56, item 19): a restarted
real-time sim put the vessel back at its start with a full battery, as no real boat would. Pure:
the core, a state file in a temporary folder."""

from __future__ import annotations

import math
import time

import pytest
from seaway.simkit.scenario import load_scenario
from seaway.vessel.model import load_vessel
from seaway_sim import plant_kept
from seaway_sim.core import SimCore

S = 1_000_000_000


def core() -> SimCore:
    sc = load_scenario("lake")
    return SimCore(sc, load_vessel(sc.plant_vessel_file), epoch_ns=time.time_ns())


def test_a_new_core_resumes_the_kept_plant_and_pack(tmp_path) -> None:
    a = core()
    for _ in range(300):  # 30 s at full thrust ahead
        a.advance((20.0, 20.0), S // 10)
    path = plant_kept.plant_path(tmp_path / "sim-state.json")
    keeper = plant_kept.PlantKeeper(path)
    keeper.close(a)
    kept = plant_kept.load(path)
    assert kept is not None and plant_kept.resumable(kept, a, None) is None

    b = core()  # the restarted sim: its scenario's start, a full pack
    assert b.plant.state.x != a.plant.state.x
    plant_kept.restore(b, kept)
    assert b.plant.state.x == pytest.approx(a.plant.state.x)
    assert b.pack_reading().remaining_j == pytest.approx(a.pack_reading().remaining_j)
    assert b.truth().energy_j == pytest.approx(a.truth().energy_j)
    start = core().truth()
    assert math.hypot(a.plant.state.x[3] - start.x_m, a.plant.state.x[4] - start.y_m) > 10.0
    b.advance((0.0, 0.0), S)  # the next fixes describe the kept state, not the start
    fixes = [g for g in b.take_samples().gnss if g is not None]
    assert fixes
    for g in fixes:
        north, east, _ = b.origin.to_ned(g.lat_rad, g.lon_rad)
        assert math.hypot(north - b.plant.state.x[3], east - b.plant.state.x[4]) < 5.0


def test_what_is_not_this_sims_to_resume_is_said(tmp_path) -> None:
    a = core()
    kept = plant_kept.snapshot(a, time.time_ns())
    other = kept.model_copy(update={"scenario": "paper-c1"})
    assert "paper-c1" in (plant_kept.resumable(other, a, None) or "")
    assert plant_kept.resumable(kept.model_copy(update={"seed": kept.seed + 1}), a, None)
    assert plant_kept.resumable(None, a, None) is None


def test_a_broken_file_is_an_error_naming_it(tmp_path) -> None:
    path = tmp_path / "sim-state.plant.json"
    path.write_text('{"scenario": "lake"}')
    with pytest.raises(plant_kept.PlantKeptError, match=str(path.name)):
        plant_kept.load(path)
    assert plant_kept.load(tmp_path / "none.json") is None
