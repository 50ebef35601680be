"""`seaway sitl ardupilot`: where the firmware is found, the command it runs, the errors it gives."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest
from seaway.contract.config import ConfigError, Origin
from seaway.runtime.run import describe
from seaway.simkit.scenario import load_scenario
from seaway_vehicle_io import sitl
from seaway_vehicle_io.config import config_path

from tests.conftest import REPO


def fake_tree(root: Path, flat: bool = True) -> Path:
    """An ArduPilot SITL folder: an executable ardurover and the default parameter files."""
    binary = root / "ardurover" if flat else root / "build" / "sitl" / "bin" / "ardurover"
    binary.parent.mkdir(parents=True, exist_ok=True)
    binary.write_text("#!/bin/sh\n")
    binary.chmod(0o755)
    params = root if flat else root / "Tools" / "autotest" / "default_params"
    params.mkdir(parents=True, exist_ok=True)
    for name in sitl.DEFAULT_PARAMS:
        (params / name).write_text("")
    return root


def test_the_folder_is_the_environments_else_shared_beside_the_checkout(tmp_path: Path) -> None:
    assert sitl.default_folder({sitl.ENV_FOLDER: "/opt/ap"}, tmp_path / "repo") == Path("/opt/ap")
    assert sitl.default_folder({}, tmp_path / "repo") is None
    (tmp_path / "shared" / "sitl" / "ardupilot").mkdir(parents=True)
    assert sitl.default_folder({}, tmp_path / "repo") == tmp_path / "shared" / "sitl" / "ardupilot"


@pytest.mark.parametrize("flat", [True, False])
def test_a_flat_folder_or_an_ardupilot_build_tree_is_found(tmp_path: Path, flat: bool) -> None:
    fw = sitl.find_firmware(fake_tree(tmp_path, flat))
    assert fw.binary.name == "ardurover" and os.access(fw.binary, os.X_OK)
    assert [p.name for p in fw.defaults] == list(sitl.DEFAULT_PARAMS)


def test_no_firmware_says_how_to_get_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"SEAWAY_ARDUPILOT_SITL is not set.*build ArduPilot"):
        sitl.find_firmware(None)
    with pytest.raises(ConfigError, match="no executable ardurover in"):
        sitl.find_firmware(tmp_path)
    fake_tree(tmp_path)
    (tmp_path / "motorboat.parm").unlink()
    with pytest.raises(ConfigError, match=r"motorboat\.parm is missing"):
        sitl.find_firmware(tmp_path)


def test_the_command_starts_the_skid_motorboat_at_the_runs_origin_with_seaways_boat_params(
        tmp_path: Path) -> None:
    run = describe(vessel="v1", run_id="r", scenario=load_scenario("lake"), scenario_ref="lake")
    home = sitl.home_text(run)
    o = load_scenario("lake").origin
    assert home == f"{o.lat_deg:.7f},{o.lon_deg:.7f},{o.alt_m:g},0"
    argv = sitl.command(sitl.find_firmware(fake_tree(tmp_path)), home, 3)
    assert argv[argv.index("--model") + 1] == "motorboat-skid" and "-I3" in argv
    assert argv[argv.index("--speedup") + 1] == "1"  # real time: the stack runs on the wall clock
    defaults = argv[argv.index("--defaults") + 1].split(",")
    assert [Path(d).name for d in defaults] == [*sitl.DEFAULT_PARAMS, "ardupilot-boat.parm",
                                                "ardupilot-sitl.parm"]
    assert "SIM_WIND_SPD 0" in Path(defaults[-1]).read_text()
    assert Path(defaults[-1]).is_file()
    assert sitl.serial0_url(3) == "tcp:127.0.0.1:5790"


def test_the_start_heading_is_the_scenarios_and_a_start_away_from_the_origin_is_refused(
        tmp_path: Path) -> None:
    path = tmp_path / "turned.toml"  # the lake, heading west at the start
    path.write_text((REPO / "deploy" / "scenarios" / "lake.toml").read_text()
                    .replace("psi_rad = 0.0", f"psi_rad = {-math.pi / 2}"))
    run = describe(vessel="v1", run_id="r", scenario=load_scenario(path), scenario_ref=str(path))
    assert sitl.home_text(run).endswith(",270")
    path.write_text(path.read_text().replace("x_m = 0.0", "x_m = 5.0"))
    run = describe(vessel="v1", run_id="r", scenario=load_scenario(path), scenario_ref=str(path))
    with pytest.raises(ConfigError, match="starts at x 5 m"):
        sitl.home_text(run)


def test_a_run_without_an_origin_and_a_bad_instance_are_refused(tmp_path: Path) -> None:
    run = describe(vessel="v1", run_id="r")
    assert run.origin is None
    with pytest.raises(ConfigError, match="no NED origin"):
        sitl.home_text(run)
    fw = sitl.find_firmware(fake_tree(tmp_path))
    with pytest.raises(ConfigError, match="instance 100 out of range: 0 to 99"):
        sitl.command(fw, "0,0,0,0", 100)
    with_origin = describe(vessel="v1", run_id="r", origin=Origin(lat_deg=1.0, lon_deg=2.0))
    assert sitl.home_text(with_origin) == "1.0000000,2.0000000,0,0"


def test_the_cli_exits_2_with_the_reason_when_there_is_no_firmware(tmp_path: Path, capsys,
                                                                     monkeypatch) -> None:
    monkeypatch.setenv(sitl.ENV_FOLDER, str(tmp_path / "nowhere"))
    run_file = describe(vessel="v1", run_id="r", origin=Origin()).write(tmp_path / "run.json")
    assert sitl.main(["ardupilot", "--run", str(run_file), "--dir", str(tmp_path / "d")]) == 2
    assert "no executable ardurover" in capsys.readouterr().err


def test_the_cli_prints_the_command_it_would_run(tmp_path: Path, capsys, monkeypatch) -> None:
    monkeypatch.setenv(sitl.ENV_FOLDER, str(fake_tree(tmp_path / "fw")))
    run_file = describe(vessel="v1", run_id="r", origin=Origin()).write(tmp_path / "run.json")
    assert sitl.main(["ardupilot", "--run", str(run_file), "--dir", str(tmp_path / "d"),
                      "--instance", "2", "--print"]) == 0
    out = capsys.readouterr().out
    assert "--model motorboat-skid" in out and "-I2" in out


def test_vehicle_io_configs_are_named_or_given_by_path(tmp_path: Path) -> None:
    assert config_path("ardupilot-sitl").name == "ardupilot-sitl.toml"
    assert config_path(str(tmp_path / "mine.toml")) == tmp_path / "mine.toml"
    with pytest.raises(ConfigError, match=r"no vehicle_io config 'no-such-config' "
                       r"\(services/vehicle_io/config/\); there are: .*ardupilot-sitl"):
        config_path("no-such-config")
