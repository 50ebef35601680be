"""`seaway sitl px4`: where the firmware is found, where it starts, its links and parameters, and
an instance number no one else holds."""

from __future__ import annotations

import math
import os
import socket
from pathlib import Path

import pytest
from seaway.contract.config import ConfigError, Origin
from seaway.runtime.run import describe
from seaway.simkit.scenario import load_scenario
from seaway_vehicle_io import sitl, sitl_px4
from seaway_vehicle_io.sitl_common import start_pose

from tests.conftest import REPO


def fake_build(root: Path) -> Path:
    """A PX4 SITL folder: bin/px4 with a module link file, etc/init.d-posix/rcS, test_data/."""
    (root / "bin").mkdir(parents=True)
    (root / "bin" / "px4").write_text("#!/bin/sh\n")
    (root / "bin" / "px4-commander").write_text("px4")  # how a copied build's links arrive
    (root / "bin" / "px4-alias.sh").write_text("")
    (root / "etc" / "init.d-posix").mkdir(parents=True)
    (root / "etc" / "init.d-posix" / "rcS").write_text("")
    (root / "test_data").mkdir()
    return root


def test_the_folder_is_the_environments_else_shared_beside_the_checkout(tmp_path: Path) -> None:
    env = {sitl_px4.ENV_FOLDER: "/opt/px4"}
    assert sitl_px4.firmware_folder(env, tmp_path / "repo") == Path("/opt/px4")
    assert sitl_px4.firmware_folder({}, tmp_path / "repo") is None
    (tmp_path / "shared" / "sitl" / "px4").mkdir(parents=True)
    assert sitl_px4.firmware_folder({}, tmp_path / "repo") == tmp_path / "shared" / "sitl" / "px4"


def test_no_firmware_says_how_to_get_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"SEAWAY_PX4_SITL is not set.*README"):
        sitl_px4.find_firmware(None)
    with pytest.raises(ConfigError, match="no PX4 binary bin/px4 in"):
        sitl_px4.find_firmware(tmp_path)
    fake_build(tmp_path)
    (tmp_path / "etc" / "init.d-posix" / "rcS").unlink()
    with pytest.raises(ConfigError, match=r"etc/init\.d-posix/rcS"):
        sitl_px4.find_firmware(tmp_path)


def test_the_bin_folder_has_the_binary_and_a_real_link_per_module(tmp_path: Path) -> None:
    build = sitl_px4.find_firmware(fake_build(tmp_path / "fw"))
    exe = sitl_px4.runnable_bin(build, tmp_path / "bin")
    assert os.access(exe, os.X_OK)
    assert os.readlink(tmp_path / "bin" / "px4-commander") == "px4"
    assert (tmp_path / "bin" / "px4-alias.sh").is_file()
    sitl_px4.runnable_bin(build, tmp_path / "bin")  # again: the links are kept


def test_seaways_parameters_are_set_and_the_links_go_where_vehicle_io_listens() -> None:
    params = {**sitl_px4.read_params(sitl_px4.BOAT_PARAMS), **sitl_px4.read_params(
        sitl_px4.SIM_PARAMS)}
    assert params["RO_ACCEL_LIM"] == 0 and params["RD_YAW_STK_GAIN"] == 1
    assert params["NAV_RCL_ACT"] == 1  # manual-control loss: Hold, the thrusters stop
    script = sitl_px4.links_script(12, 40123, params)
    assert "param set RD_YAW_STK_GAIN 1" in script and "param set SDLOG_BACKEND 0" in script
    assert "mavlink start -x -u 14592 -r 4000000 -f -m onboard -o 40123" in script
    assert "-u 19462 -r 400000 -m custom -o 19422" in script  # the SIH display link
    assert "-u 18582 " in script  # a ground station's, sending to 14550
    assert script.index("param set") < script.index("mavlink start")


def test_a_bad_parameter_line_or_override_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "bad.params"
    bad.write_text("# fine\nNAV_RCL_ACT 1\nRO_ACCEL_LIM\n")
    with pytest.raises(ConfigError, match=r"bad\.params:3: want 'NAME VALUE'"):
        sitl_px4.read_params(bad)
    assert sitl_px4.param_override("nav_rcl_act=6") == ("NAV_RCL_ACT", 6.0)
    with pytest.raises(Exception, match="want NAME=VALUE"):
        sitl_px4.param_override("NAV_RCL_ACT")


def test_the_rover_starts_at_the_runs_origin_facing_north_only(tmp_path: Path) -> None:
    run = describe(vessel="v1", run_id="r", scenario=load_scenario("lake"), scenario_ref="lake")
    env = sitl_px4.environment({"PATH": "/usr/bin"}, start_pose(run), tmp_path / "rt",
                               tmp_path / "rc")
    o = load_scenario("lake").origin
    assert (env["PX4_HOME_LAT"], env["PX4_HOME_LON"], env["PX4_HOME_ALT"]) == (
        f"{o.lat_deg:.7f}", f"{o.lon_deg:.7f}", f"{o.alt_m:g}")
    assert env["PATH"].split(os.pathsep)[0] == str(tmp_path / "rc")  # ahead of PX4's own script
    assert env["PX4_SIM_MODEL"] == "sihsim_rover_differential"
    turned = tmp_path / "turned.toml"
    turned.write_text((REPO / "deploy" / "scenarios" / "lake.toml").read_text()
                      .replace("psi_rad = 0.0", f"psi_rad = {math.pi / 2}"))
    run = describe(vessel="v1", run_id="r", scenario=load_scenario(turned), scenario_ref=str(turned))
    with pytest.raises(ConfigError, match=r"starts facing north.*heading 90 deg"):
        sitl_px4.environment({}, start_pose(run), tmp_path / "rt", tmp_path / "rc")
    with pytest.raises(ConfigError, match="no NED origin"):
        start_pose(describe(vessel="v1", run_id="r"))


def test_an_instance_is_never_handed_out_twice_nor_with_a_port_taken(tmp_path, monkeypatch):
    monkeypatch.setattr(sitl_px4, "LOCK_DIR", tmp_path / "locks")
    first, fd1 = sitl_px4.free_instance(range(70, 75))
    second, fd2 = sitl_px4.free_instance(range(70, 75))  # the first's lock is held
    assert second != first
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        nxt = max(first, second) + 1
        try:
            taken.bind(("127.0.0.1", sitl_px4.SIH_REMOTE + nxt))
        except OSError:
            pytest.skip("the port this test takes is in use")
        third, fd3 = sitl_px4.free_instance(range(70, 75))
        assert third not in (first, second, nxt)
    os.close(fd1)
    again, fd4 = sitl_px4.free_instance(range(70, 75))  # released: free again
    assert again == first
    for fd in (fd2, fd3, fd4):
        os.close(fd)
    _, held = sitl_px4.free_instance(range(70, 71))
    with pytest.raises(ConfigError, match=r"no free PX4 SITL instance in 70\.\.70"):
        sitl_px4.free_instance(range(70, 71))
    os.close(held)


def test_the_cli_prints_the_script_and_command_or_exits_2_saying_why(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv(sitl_px4.ENV_FOLDER, str(tmp_path / "nowhere"))
    run_file = describe(vessel="v1", run_id="r", origin=Origin()).write(tmp_path / "run.json")
    args = ["px4", "--run", str(run_file), "--dir", str(tmp_path / "d"), "--link-port", "40000"]
    assert sitl.main(args) == 2
    assert "no PX4 binary bin/px4" in capsys.readouterr().err
    monkeypatch.setenv(sitl_px4.ENV_FOLDER, str(fake_build(tmp_path / "fw")))
    assert sitl.main([*args, "--param", "NAV_RCL_ACT=6", "--print"]) == 0
    out = capsys.readouterr().out
    assert "param set NAV_RCL_ACT 6" in out and "-o 40000" in out
    assert f"-i {sitl_px4.OWN_INSTANCES.start} " in out and not (tmp_path / "d").exists()
