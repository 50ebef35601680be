"""``seaway-sim --start-slot N``: a fleet's simulators start side by side, not on one spot."""

from __future__ import annotations

import pytest
from seaway.contract.config import ConfigError
from seaway.simkit.scenario import load_scenario
from seaway_sim.main import START_SPACING_M, build_parser, in_slot


def test_a_slot_moves_the_start_east_by_the_spacing_and_keeps_the_rest() -> None:
    lake = load_scenario("lake")
    moved = in_slot(lake, 2)
    assert moved.start.y_m == pytest.approx(lake.start.y_m + 2 * START_SPACING_M)
    assert (moved.start.x_m, moved.start.psi_rad) == (lake.start.x_m, lake.start.psi_rad)
    assert moved.origin == lake.origin and moved.disturbances == lake.disturbances
    assert in_slot(lake, 0) is lake


def test_a_slot_outside_the_operating_area_is_refused_naming_the_flag() -> None:
    with pytest.raises(ConfigError, match=r"(?s)--start-slot 30.*keep-in"):
        in_slot(load_scenario("lake"), 30)


def test_the_flag_takes_whole_numbers_only() -> None:
    assert build_parser().parse_args(["--start-slot", "1"]).start_slot == 1
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--start-slot", "-1"])
