"""The estimator takes its model vessel, dead zone and NED origin from the run, nothing else."""

import pytest
from seaway.contract.config import ConfigError, Origin
from seaway.runtime import run as runs
from seaway.simkit.scenario import load_scenario
from seaway_estimator.config import EstimatorConfig, load_estimator_config
from seaway_estimator.main import with_run


def _run(scenario: str) -> runs.RunDescription:
    return runs.describe(scenario=load_scenario(scenario), scenario_ref=scenario, vessel="v1", run_id="t")


def test_run_sets_vessel_dead_zone_and_origin_only() -> None:
    base = load_estimator_config(None)
    cfg = with_run(base, _run("lake"))
    assert (cfg.vessel, cfg.apply_dead_zone) == ("paper-boat", True)
    assert cfg.origin is not None and (cfg.origin.lat_deg, cfg.origin.lon_deg) == (28.18, 112.94)
    assert cfg.gnss_std_m == base.gnss_std_m and cfg.publish_rate_hz == base.publish_rate_hz
    paper = with_run(base, _run("paper-c1"))
    assert (paper.vessel, paper.apply_dead_zone) == ("paper-sim", False)


def test_a_boat_run_has_no_origin_so_the_first_fix_is_used() -> None:
    boat = runs.RunDescription(run_id="b", vessel="v1", model_vessel_file="paper-boat")
    cfg = with_run(load_estimator_config(None), boat)
    assert cfg.origin is None and cfg.vessel == "paper-boat"


@pytest.mark.parametrize("field", ["vessel", "apply_dead_zone", "origin"])
def test_a_config_file_may_not_set_run_wide_fields(field: str) -> None:
    value = {"vessel": "paper-boat", "apply_dead_zone": True,
             "origin": Origin(lat_deg=1.0, lon_deg=2.0)}[field]
    cfg = EstimatorConfig(**{field: value})
    with pytest.raises(ConfigError, match=field):
        with_run(cfg, _run("paper-c1"))


def test_a_shipped_config_is_found_by_its_name_and_an_unknown_name_lists_them() -> None:
    from seaway.contract.config import ConfigError
    from seaway_estimator.config import EstimatorConfig, load_estimator_config

    cfg = load_estimator_config("px4-sitl")
    assert cfg.accel_surge_std_per_sqrt_s > EstimatorConfig().accel_surge_std_per_sqrt_s
    with pytest.raises(ConfigError, match=r"no estimator config 'nope'.*px4-sitl"):
        load_estimator_config("nope")
