"""The example configs load, and bad configs fail loudly naming the field."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from seaway.contract.config import ConfigError, load_config, parse_config
from seaway.runtime.run import resolve
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.link import check_url
from seaway_vehicle_io.main import build_parser, load

CONFIGS = sorted((Path(__file__).resolve().parents[3] / "services/vehicle_io/config").glob("*.toml"))


def test_there_are_example_configs():
    assert len(CONFIGS) >= 4


@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
def test_example_configs_load(path):
    cfg = load_config(path, VehicleIoConfig)
    if cfg.mavlink.startswith("/dev/") and importlib.util.find_spec("serial") is None:
        with pytest.raises(ValueError, match="pyserial"):  # refused up front, not in a loop
            check_url(cfg.mavlink)
    else:
        check_url(cfg.mavlink)


@pytest.mark.parametrize(("doc", "field"), [
    ({"thrust_timout_s": 0.3}, "thrust_timout_s"),  # a typo is an error, not a default
    ({"thrust_timeout_s": 0.01}, "thrust_timeout_s"),  # shorter than one stream period
    ({"manual_control_rate_hz": 2.0}, "manual_control_rate_hz"),  # too slow for PX4's 0.5 s
    ({"heartbeat_timeout_s": 0.5}, "heartbeat_timeout_s"),
    ({"autopilot": "inav"}, "autopilot"),
    ({"source_system": 0}, "source_system"),
])
def test_bad_configs_name_the_field(doc, field):
    with pytest.raises(ConfigError, match=field if field != "thrust_timeout_s" else "thrust_timeout"):
        parse_config(doc, VehicleIoConfig, "test")


@pytest.mark.parametrize(("field", "value", "bound"), [
    ("thrust_timeout_s", 300.0, 2.0),  # the last thrust held 5 minutes after the controller went silent
    ("thrust_timeout_s", 1e308, 2.0),  # overflowed at start
    ("heartbeat_timeout_s", 1e308, 30.0),
])
def test_safety_timeouts_have_an_upper_bound(field, value, bound):
    with pytest.raises(ConfigError, match=rf"probe.toml.*\n  {field}: .*less than or equal to {bound:g}"):
        parse_config({field: value}, VehicleIoConfig, "probe.toml")
    assert getattr(parse_config({field: bound}, VehicleIoConfig, "probe.toml"), field) == bound


def test_a_too_long_thrust_timeout_flag_is_refused_naming_the_flag_and_the_bound(capsys):
    from seaway.runtime.config import parse_service_args

    with pytest.raises(SystemExit) as exit_:
        parse_service_args(build_parser(), ["--thrust-timeout", "300"])
    assert exit_.value.code == 2
    assert "argument --thrust-timeout: '300' is not a finite number above 0 and at most 2" in (
        capsys.readouterr().err)


def test_command_line_overrides_and_url_check(tmp_path):
    args = build_parser().parse_args(["--mavlink", "udpin:0.0.0.0:14540", "--thrust-timeout", "0.5",
                                      "--vessel-file", "paper-boat"])
    cfg, limits = load(args, resolve(args, "vehicle_io"))
    assert cfg.mavlink == "udpin:0.0.0.0:14540" and cfg.thrust_timeout_s == 0.5
    assert limits.thrust_max_n == 75.0  # the run's vessel file, paper-boat
    bad = build_parser().parse_args(["--mavlink", "http://boat"])
    with pytest.raises(ConfigError, match="unsupported MAVLink URL"):
        load(bad, resolve(bad, "vehicle_io"))


def test_serial_url_needs_pyserial(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "serial" else real(name, *a))
    with pytest.raises(ValueError, match="pyserial"):
        check_url("/dev/ttyAMA0")
    assert check_url("udpin:0.0.0.0:14540") == "udpin:0.0.0.0:14540"  # others unaffected
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: object())
    assert check_url("/dev/ttyAMA0") == "/dev/ttyAMA0"


def test_vehicle_io_speaks_as_the_onboard_computer_not_as_a_ground_station():
    """255 is every ground station's default system id: a second one must not look like us."""
    cfg = VehicleIoConfig()
    assert cfg.source_component == 191  # MAV_COMP_ID_ONBOARD_COMPUTER
    assert cfg.source_system != 255
