"""Mode encoding/decoding, arming magic numbers, parameter decoding and the failsafe verdicts."""

from __future__ import annotations

import struct

import pytest
from seaway_vehicle_io import ardupilot, px4
from seaway_vehicle_io.ardupilot import PROFILE as AP
from seaway_vehicle_io.profile import UnknownModeError, decode_param_value
from seaway_vehicle_io.px4 import PROFILE as PX4


@pytest.mark.parametrize(
    ("name", "params", "custom_mode"),
    [
        ("MANUAL", (1.0, 1.0, 0.0), 0x00010000),  # docs/autopilots.md A.4
        ("OFFBOARD", (1.0, 6.0, 0.0), 0x00060000),
        ("HOLD", (1.0, 4.0, 3.0), 0x03040000),  # AUTO.LOITER
        ("MISSION", (1.0, 4.0, 4.0), 0x04040000),
        ("RTL", (1.0, 4.0, 5.0), 0x05040000),
        ("POSCTL", (1.0, 3.0, 0.0), 0x00030000),
        ("ACRO", (1.0, 5.0, 0.0), 0x00050000),
        ("STABILIZED", (1.0, 7.0, 0.0), 0x00070000),
    ],
)
def test_px4_modes(name, params, custom_mode):
    assert PX4.encode_mode(name) == params
    assert PX4.encode_mode(name.lower()) == params
    assert PX4.decode_mode(1, custom_mode) == name


@pytest.mark.parametrize(("base", "custom", "expect"), [
    (1, 0x00040000, "MISSION"),  # AUTO with sub mode 0 runs the mission
    (1, 0x01030000, "POSCTL"),  # POSCTL sub 1 is still position control
    (129, 0x00010000, "MANUAL"),  # armed bit does not matter
    (0, 0x00010000, "UNKNOWN(base_mode=0)"),  # no custom-mode flag: cannot interpret
    (1, 0x00090000, "UNKNOWN(main=9,sub=0)"),
])
def test_px4_decode_edge_cases(base, custom, expect):
    assert PX4.decode_mode(base, custom) == expect


def test_every_mode_round_trips():
    for name in px4.MODES:
        _, main, sub = PX4.encode_mode(name)
        assert PX4.decode_mode(1, int(main) << 16 | int(sub) << 24) == name
    for name, number in ardupilot.MODES.items():
        assert AP.decode_mode(1, number) == name
        if name != "INITIALISING":
            assert AP.encode_mode(name) == (1.0, float(number), 0.0)


@pytest.mark.parametrize(("name", "number"), [("MANUAL", 0), ("HOLD", 4), ("ACRO", 1),
                                              ("AUTO", 10), ("MISSION", 10), ("RTL", 11),
                                              ("GUIDED", 15), ("smart_rtl", 12)])
def test_ardupilot_modes(name, number):
    assert AP.encode_mode(name) == (1.0, float(number), 0.0)


@pytest.mark.parametrize(("profile", "name"), [(PX4, "FLY"), (PX4, ""), (AP, "INITIALISING"),
                                               (AP, "STABILIZED")])
def test_unknown_modes_refused_with_the_list(profile, name):
    with pytest.raises(UnknownModeError, match=r"known: .*MANUAL"):
        profile.encode_mode(name)


def test_ardupilot_unknown_number():
    assert AP.decode_mode(1, 99) == "UNKNOWN(99)"


@pytest.mark.parametrize(("profile", "arm", "force", "expect"), [
    (PX4, True, False, (1.0, 0.0)), (PX4, False, False, (0.0, 0.0)),
    (PX4, True, True, (1.0, 21196.0)), (PX4, False, True, (0.0, 21196.0)),
    (AP, True, False, (1.0, 0.0)), (AP, True, True, (1.0, 2989.0)),
    (AP, False, True, (0.0, 21196.0)),
])
def test_arm_params(profile, arm, force, expect):
    assert profile.arm_params(arm, force) == expect


def bytewise(i: int) -> float:
    return struct.unpack("<f", struct.pack("<i", i))[0]


@pytest.mark.parametrize(("value", "ptype", "expect"), [
    (bytewise(2), 6, 2.0),  # PX4 INT32, bytewise
    (bytewise(0), 6, 0.0),
    (bytewise(-1), 6, -1.0),
    (bytewise(21196), 6, 21196.0),
    (2.0, 6, 2.0),  # ArduPilot INT32, C cast
    (255.0, 4, 255.0),
    (-1.0, 2, -1.0),
    (0.5, 9, 0.5),  # REAL32 as is
    (3.0, 9, 3.0),
])
def test_decode_param_value(value, ptype, expect):
    assert decode_param_value(value, ptype) == expect


PX4_OK = {"COM_RC_IN_MODE": 1, "COM_RC_LOSS_T": 0.5, "NAV_RCL_ACT": 1, "CA_AIRFRAME": 6}


@pytest.mark.parametrize(("changes", "verdict", "warns"), [
    ({}, "stops", 0),
    ({"NAV_RCL_ACT": 6}, "stops", 0),
    ({"NAV_RCL_ACT": 5}, "stops", 0),
    ({"NAV_RCL_ACT": 7}, "stops", 0),  # 1.18: Hold without a failsafe
    ({"NAV_RCL_ACT": 2}, "takes_over", 1),  # PX4 default: Return
    ({"NAV_RCL_ACT": 3}, "takes_over", 1),
    ({"NAV_RCL_ACT": 0}, "none", 0),
    ({"NAV_RCL_ACT": 42}, "unknown", 0),
    ({"COM_RC_IN_MODE": 4}, "none", 0),
    ({"COM_RC_IN_MODE": 3}, "stops", 1),
    ({"COM_RC_IN_MODE": 0}, "stops", 1),
    ({"COM_RC_LOSS_T": 2.0}, "stops", 1),
    ({"CA_AIRFRAME": 0}, "stops", 1),
    ({"NAV_RCL_ACT": None}, "unknown", 0),
])
def test_px4_failsafe_assessment(changes, verdict, warns):
    params = {**PX4_OK, **changes}
    params = {k: float(v) for k, v in params.items() if v is not None}
    a = PX4.assess_failsafe(params, 255)
    assert a.verdict == verdict, a.summary
    assert len(a.warnings) == warns, a.warnings
    assert not a.blocking


AP_RC = {f"RC{ch}_{f}": v for ch in (1, 3)
         for f, v in {"MIN": 1000, "TRIM": 1500, "MAX": 2000, "DZ": 30, "REVERSED": 0}.items()}
AP_OK = {"FS_THR_ENABLE": 1, "FS_ACTION": 2, "FS_TIMEOUT": 1.5, "FS_GCS_ENABLE": 0,
         "RC_OVERRIDE_TIME": 3.0, "RC_OPTIONS": 0, "PILOT_STEER_TYPE": 1, "SYSID_MYGCS": 255,
         "FRAME_CLASS": 2, "MOT_SLEWRATE": 0, "MOT_THST_ASYM": 1.0, "RCMAP_ROLL": 1,
         "RCMAP_THROTTLE": 3, **AP_RC}
GCS_HOLD = {"FS_THR_ENABLE": 0, "FS_GCS_ENABLE": 1}


@pytest.mark.parametrize(("changes", "receiver", "verdict", "warns", "blocks"), [
    ({}, "absent", "stops", 0, 0),  # radio failsafe 0.5 s after the overrides stop
    ({}, "present", "takes_over", 0, 0),  # held RC_OVERRIDE_TIME, then the sticks
    ({}, "unknown", "unknown", 0, 0),  # the two cases differ: vehicle_io cannot know
    ({"RC_OVERRIDE_TIME": -1}, "present", "none", 0, 0),  # overrides never expire
    (GCS_HOLD, "unknown", "stops", 0, 0),  # GCS failsafe -> Hold either way
    ({**GCS_HOLD, "FS_ACTION": 1}, "absent", "takes_over", 0, 0),  # RTL
    ({**GCS_HOLD, "FS_ACTION": 0}, "absent", "none", 0, 0),
    ({**GCS_HOLD, "FS_ACTION": 6}, "absent", "takes_over", 0, 0),  # 4.7: Loiter drives the boat
    ({**GCS_HOLD, "FS_ACTION": 9}, "absent", "unknown", 0, 0),  # not a value 4.7 defines
    ({"FS_THR_ENABLE": 0}, "absent", "none", 0, 0),  # the last override stays in radio_in
    ({"PILOT_STEER_TYPE": 0}, "absent", "stops", 0, 1),  # our mapping would be wrong
    ({"SYSID_MYGCS": 254}, "absent", "stops", 1, 0),
    ({"RC_OPTIONS": 2}, "absent", "stops", 0, 1),  # overrides ignored: we cannot drive
    ({"RC_OVERRIDE_TIME": 0}, "absent", "stops", 0, 1),  # overrides disabled
    ({"MOT_SLEWRATE": 100}, "absent", "stops", 1, 0),
    ({"MOT_THST_ASYM": 0.7}, "absent", "stops", 1, 0),
    ({"RCMAP_THROTTLE": 2}, "absent", "stops", 1, 0),
    ({"RC3_MIN": None}, "absent", "stops", 1, 0),  # compensation assumes the default
    ({"RC1_DZ": 600}, "absent", "stops", 0, 1),  # a calibration that cannot be inverted
    ({"FS_GCS_ENABLE": None}, "absent", "unknown", 0, 0),
])
def test_ardupilot_failsafe_assessment(changes, receiver, verdict, warns, blocks):
    params = {k: float(v) for k, v in {**AP_OK, **changes}.items() if v is not None}
    a = AP.assess_failsafe(params, 255, receiver)
    assert a.verdict == verdict, a.summary
    assert len(a.warnings) == warns, a.warnings
    assert len(a.blocking) == blocks, a.blocking


def test_ardupilot_failsafe_summary_states_the_timing_with_and_without_a_receiver():
    params = {k: float(v) for k, v in AP_OK.items()}
    absent = AP.assess_failsafe(params, 255, "absent").summary
    assert "held 0.5 s" in absent and "FS_ACTION=Hold" in absent and "FS_TIMEOUT=1.5 s" in absent
    present = AP.assess_failsafe(params, 255, "present").summary
    assert "held for RC_OVERRIDE_TIME=3 s" in present and "sticks" in present
    both = AP.assess_failsafe(params, 255, "unknown").summary
    assert "held 0.5 s" in both and "RC_OVERRIDE_TIME=3 s" in both


def test_every_failsafe_action_the_firmware_defines_is_named():
    """PX4 1.18's NAV_RCL_ACT and ArduPilot 4.7's FS_ACTION values (their parameter metadata), each
    named in the summary rather than shown as a bare number."""
    for act in (1, 2, 3, 5, 6, 7):
        params = {k: float(v) for k, v in {**PX4_OK, "NAV_RCL_ACT": act}.items()}
        assert "not a known action" not in PX4.assess_failsafe(params, 255).summary
    for act in range(7):
        params = {k: float(v) for k, v in {**AP_OK, **GCS_HOLD, "FS_ACTION": act}.items()}
        assert f"FS_ACTION={act} " not in AP.assess_failsafe(params, 255, "absent").summary
