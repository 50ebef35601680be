"""The run description: resolved from flags or a file, the same defaults everywhere, differences named."""

from __future__ import annotations

import argparse

import pytest
from seaway.contract.config import ConfigError
from seaway.runtime import run as runs
from seaway.runtime.service import base_parser
from seaway.simkit.scenario import load_scenario


def _args(*argv: str) -> argparse.Namespace:
    return base_parser("sim", "test").parse_args(["--vessel", "v1", *argv])


def test_flags_alone_give_the_one_default() -> None:
    run = runs.resolve(_args(), "estimator")
    assert run.model_vessel_file == runs.DEFAULT_VESSEL_FILE
    assert run.control_period_s == runs.CONTROL_PERIOD_S and run.clock == "wall"
    assert run.origin is None and run.plant_vessel_file is None and run.scenario is None


def test_a_scenario_gives_model_plant_origin_and_dead_zone() -> None:
    run = runs.resolve(_args("--scenario", "lake", "--lockstep"), "sim", load_scenario)
    assert (run.model_vessel_file, run.plant_vessel, run.dead_zone, run.clock) == (
        "paper-boat", "paper-boat", True, "lockstep")
    assert run.origin is not None and run.origin.lat_deg == 28.18
    perturbed = runs.resolve(_args("--scenario", "paper-c4-perturbed"), "sim", load_scenario)
    assert (perturbed.model_vessel_file, perturbed.plant_vessel) == ("paper-sim", "paper-sim-perturbed")


def test_flags_override_the_scenario_and_a_plant_equal_to_the_model_is_not_a_second_model() -> None:
    run = runs.resolve(_args("--scenario", "paper-c1", "--control-period-s", "0.2", "--origin", "10,20,3",
                             "--plant-vessel-file", "paper-sim"), "sim", load_scenario)
    assert run.control_period_s == 0.2 and run.control_period_ns == 200_000_000
    assert (run.origin.lat_deg, run.origin.lon_deg, run.origin.alt_m) == (10.0, 20.0, 3.0)
    assert run.plant_vessel_file is None


@pytest.mark.parametrize(("argv", "match"), [
    (["--control-period-s", "2"], "control_period_s"),
    (["--scenario", "no-such-scenario"], "no-such-scenario"),
])
def test_bad_values_are_refused_naming_them(argv: list[str], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        runs.resolve(_args(*argv), "sim", load_scenario)


@pytest.mark.parametrize("origin", ["95,0", "0,200", "1", "a,b"])
def test_bad_origins_are_refused_by_the_parser(origin: str) -> None:
    with pytest.raises(SystemExit):
        _args("--origin", origin)


@pytest.mark.parametrize("period", ["0", "-0.1", "nan", "inf"])
def test_a_control_period_that_is_no_duration_is_refused_by_the_parser(period: str, capsys) -> None:
    with pytest.raises(SystemExit):
        _args("--control-period-s", period)
    err = capsys.readouterr().err
    assert f"argument --control-period-s: {period!r} is not a finite number above 0" in err


def test_a_run_file_says_it_all(tmp_path) -> None:
    path = runs.describe(scenario=load_scenario("paper-c1"), scenario_ref="paper-c1", vessel="v1",
                         run_id="r1", clock="lockstep").write(tmp_path / "run.json")
    run = runs.resolve(_args("--run", str(path)), "controller")
    assert run.run_id == "r1" and run.lockstep and run.scenario == "paper-c1"
    with pytest.raises(ConfigError, match="--lockstep given beside --run"):
        runs.resolve(_args("--run", str(path), "--lockstep"), "controller")
    other = base_parser("sim", "test").parse_args(["--vessel", "v2", "--run", str(path)])
    with pytest.raises(runs.RunMismatchError, match="vessel 'v1'"):
        runs.resolve(other, "controller")


def test_check_peers_names_the_field_both_values_and_the_service() -> None:
    mine = runs.RunDescription(run_id="a", vessel="v1", control_period_s=0.2)
    same = runs.RunDescription(run_id="b", vessel="v1", control_period_s=0.2)
    other = runs.RunDescription(run_id="c", vessel="v1", model_vessel_file="paper-boat")
    runs.check_peers(mine, "sim", [("seaway/v1/run/estimator", same.encode())])  # run ids may differ
    with pytest.raises(runs.RunMismatchError) as err:
        runs.check_peers(mine, "sim", [("seaway/v1/run/controller", other.encode())])
    text = str(err.value)
    assert "controller" in text and "control_period_s: 0.2 here, 0.1 there" in text
    assert "model_vessel_file: 'paper-sim' here, 'paper-boat' there" in text
    with pytest.raises(runs.RunMismatchError, match="unreadable"):
        runs.check_peers(mine, "sim", [("seaway/v1/run/controller", b"{not json")])


def test_a_model_override_keeps_the_scenarios_vessel_as_the_plant() -> None:
    # The simulator integrates the scenario's vessel whatever the services are told to model.
    run = runs.describe(scenario=load_scenario("lake"), vessel="v1", run_id="r",
                        model_vessel_file="paper-sim")
    assert (run.model_vessel_file, run.plant_vessel) == ("paper-sim", "paper-boat")
    assert run.scenario == "lake"  # named by the scenario's own name when no reference is given


@pytest.mark.parametrize("text", ['{"run_id": "r", "vessel": "v1", "control_period_s": NaN}', "{not json",
                                  '{"run_id": "r", "vessel": "v1", "tempo": 2}'])
def test_a_bad_run_file_is_refused_naming_the_problem(tmp_path, text: str) -> None:
    path = tmp_path / "run.json"
    path.write_text(text)
    with pytest.raises(ConfigError, match=r"run\.json"):
        runs.resolve(_args("--run", str(path)), "sim")


def test_a_state_kept_before_the_run_started_is_an_earlier_launchs(tmp_path) -> None:
    run_file = runs.describe(vessel="v1", run_id="r").write(tmp_path / "run.json")
    started = runs.started_ns(run_file)
    assert started == run_file.stat().st_mtime_ns
    assert runs.from_earlier_launch(started - 1, run_file)
    assert not runs.from_earlier_launch(started, run_file)  # kept in this run (by a restart's past)
    assert runs.started_ns(None) is None and not runs.from_earlier_launch(0, None)  # by hand
