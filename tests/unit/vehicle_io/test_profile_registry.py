"""The autopilot registry: each profile module registers itself; config and command line follow it."""

from __future__ import annotations

import typing

import pytest
from seaway_vehicle_io import ardupilot, profile, px4
from seaway_vehicle_io.config import AUTOPILOT_CHOICES, VehicleIoConfig
from seaway_vehicle_io.main import build_parser


def test_px4_and_ardupilot_register_themselves():
    assert set(profile.names()) == {"px4", "ardupilot"}
    assert profile.by_name("px4") is px4.PROFILE and profile.by_name("ardupilot") is ardupilot.PROFILE
    assert profile.by_mav_autopilot(12) is px4.PROFILE
    assert profile.by_mav_autopilot(3) is ardupilot.PROFILE
    assert profile.by_mav_autopilot(8) is None  # MAV_AUTOPILOT_INVALID: not an autopilot we command
    with pytest.raises(ValueError, match="unknown autopilot 'inav'; known: "):
        profile.by_name("inav")


def test_config_and_command_line_take_their_choices_from_the_registry():
    assert (profile.AUTO, *profile.names()) == AUTOPILOT_CHOICES
    assert typing.get_args(VehicleIoConfig.model_fields["autopilot"].annotation) == AUTOPILOT_CHOICES
    action = next(a for a in build_parser()._actions if a.dest == "autopilot")
    assert tuple(action.choices) == AUTOPILOT_CHOICES
    for name in AUTOPILOT_CHOICES:
        assert VehicleIoConfig(autopilot=name).autopilot == name


class _Clone(px4.Px4Profile):
    name = "px4-clone"


def test_a_name_or_heartbeat_number_is_claimed_once():
    with pytest.raises(ValueError, match="'px4' is taken"):
        profile.register(px4.Px4Profile())
    with pytest.raises(ValueError, match="both claim MAV_AUTOPILOT 12"):
        profile.register(_Clone())
    with pytest.raises(ValueError, match="'auto' is taken"):
        profile.register(type("Auto", (_Clone,), {"name": profile.AUTO, "mav_autopilot": 99})())
    assert set(profile.names()) == {"px4", "ardupilot"}
