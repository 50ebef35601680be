"""A scenario's disturbances together (``seaway.simkit.scenario.disturbance_sums``): each entry
was bounded, but entries of one kind add, and 200 currents of 5 m/s each (a valid scenario) crashed
the sim at its first GNSS sample over MAVLink (a speed of 1400 m/s over 16 bits), as did 200 world
forces (a NaN heading) and 200 winds. (200 entries are now past the count alone; a few past the sum
show the sum's check.) Past the sum of a kind, or past the count of entries, a world is refused
naming the field, the total and the bound; at the sums, split over several entries, the plant of
the lightest vessel stays finite and its telemetry packs."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mavlink
from seaway.contract.config import ConfigError
from seaway.simkit import scenario as sc
from seaway.vessel.model import load_vessel
from seaway_sim.core import SimCore
from seaway_sim.px4_autopilot import Px4Autopilot, Px4Config
from seaway_sim.world import world_of

from tests.conftest import REPO

SCENARIOS = sorted(p.stem for p in (REPO / "deploy" / "scenarios").glob("*.toml"))
VESSELS = sorted(p.stem for p in (REPO / "deploy" / "vessels").glob("*.toml"))


def lake_with(**changes) -> dict:
    doc = sc.load_scenario("lake").model_dump(mode="json")
    doc.pop("area")
    doc.update(changes)
    return doc


def lightest_vessel() -> str:
    return min(VESSELS, key=lambda v: load_vessel(v).m11_kg)


@pytest.mark.parametrize("name", SCENARIOS)
def test_every_shipped_scenario_is_within_the_sums(name: str) -> None:
    scenario = sc.load_scenario(name)  # its validation holds the sums too
    assert all(total <= bound for _, total, bound, _ in sc.disturbance_sums(scenario.disturbances))


WIND = {"kind": "wind", "speed_mps": sc.MAX_WIND_MPS, "from_rad": 0.0,
        "drag_area_m2": sc.MAX_DRAG_AREA_M2, "gust_std_mps": sc.MAX_GUST_STD_MPS}


@pytest.mark.parametrize(("disturbances", "field", "bound"), [
    ([{"kind": "current", "north_mps": 5.0, "east_mps": 5.0}] * 3, "north_mps", sc.MAX_CURRENT_MPS),
    ([{"kind": "world_constant", "north_n": 50.0, "east_n": 50.0}] * 3, "north_n", sc.MAX_FORCE_N),
    ([{"kind": "world_constant", "east_n": 30.0},
      {"kind": "world_grid", "xs_m": [0, 1], "ys_m": [0, 1], "north_n": [[0, 0], [0, 0]],
       "east_n": [[0, 0], [0, -30.0]]}], "east_n", sc.MAX_FORCE_N),
    ([{"kind": "body_constant", "yaw_nm": 2.0}] * 2, "yaw_nm", sc.MAX_MOMENT_NM),
    ([WIND] * 2, "wind", sc.MAX_WIND_STRENGTH_M4PS2),
])
def test_disturbances_of_one_kind_adding_past_the_bound_are_refused(disturbances, field,
                                                                      bound) -> None:
    with pytest.raises(ConfigError) as err:
        world_of(lake_with(disturbances=disturbances), "scenario request", None)
    text = str(err.value)
    assert field in text and f"{bound:g}" in text and "scenario request" in text, text


def test_too_many_entries_are_refused_naming_the_count_allowed() -> None:
    zero = {"kind": "current", "north_mps": 0.0, "east_mps": 0.0}
    with pytest.raises(ConfigError) as err:
        world_of(lake_with(disturbances=[zero] * (sc.MAX_DISTURBANCES + 1)), "probe", None)
    assert "disturbances" in str(err.value) and str(sc.MAX_DISTURBANCES) in str(err.value)
    bias = {"kind": "heading_bias", "start_s": 1.0, "bias_rad": 0.0}
    with pytest.raises(ConfigError) as err:
        world_of(lake_with(faults=[bias] * (sc.MAX_FAULTS + 1)), "probe", None)
    assert "faults" in str(err.value) and str(sc.MAX_FAULTS) in str(err.value)
    world_of(lake_with(disturbances=[zero] * sc.MAX_DISTURBANCES,
                       faults=[bias] * sc.MAX_FAULTS), "probe", None)  # at the counts: taken


def test_at_the_sums_split_over_entries_the_plant_stays_finite_and_its_telemetry_packs() -> None:
    n = 4
    split = [
        *[{"kind": "current", "north_mps": sc.MAX_CURRENT_MPS / n,
           "east_mps": -sc.MAX_CURRENT_MPS / n}] * n,
        *[{"kind": "world_constant", "north_n": sc.MAX_FORCE_N / n,
           "east_n": sc.MAX_FORCE_N / n}] * n,
        *[{"kind": "body_constant", "surge_n": sc.MAX_FORCE_N / n, "sway_n": -sc.MAX_FORCE_N / n,
           "yaw_nm": sc.MAX_MOMENT_NM / n}] * n,
        # n winds of half the speed (and gust) each: a quarter of the strength each, the sum at it.
        *[{**WIND, "speed_mps": sc.MAX_WIND_MPS / 2, "gust_std_mps": sc.MAX_GUST_STD_MPS / 2,
           "from_rad": 1.0}] * n,
    ]
    scenario, _plant, model = world_of(lake_with(vessel=lightest_vessel(), disturbances=split),
                                       "probe", None)
    core = SimCore(scenario, model)
    ap = Px4Autopilot(Px4Config(thrust_max_n=model.thrust_max_n))
    mav = mavlink.MAVLink(None)
    for k in range(600):  # 60 s, the thrusters hard over one way
        core.advance((model.thrust_max_n, -model.thrust_max_n), 100_000_000)
        samples = core.take_samples()
        truth = core.truth()
        assert all(math.isfinite(v) for v in (truth.x_m, truth.y_m, truth.psi_rad, truth.u_mps)), k
        for msg in ap.sensor_telemetry(samples.gnss, samples.attitude, 0):
            msg.pack(mav)
