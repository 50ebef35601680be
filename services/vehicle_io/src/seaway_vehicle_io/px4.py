"""PX4 profile: differential rover / boat in Manual mode (docs/autopilots.md, part A).

MANUAL_CONTROL mapping (inverse of ``DifferentialActControl::computeInverseKinematics``, where
``control[0]`` = right = thr - d and ``control[1]`` = left = thr + d; PX4 decodes ``y/1000`` as roll
and ``z/500 - 1`` as throttle in ``MavlinkReceiver::handle_message_manual_control``, and the
differential Manual mode makes the speed difference ``d = roll * RD_YAW_STK_GAIN``)::

    y = round(500 * (L - R) / g)      in [-1000, 1000], g = RD_YAW_STK_GAIN (read at connection)
    z = round(500 + 250 * (L + R))    in [0, 1000], 500 = stop
    x = 0, r = 0                      (ignored by the rover's Manual mode)

Measured on PX4 1.18 SITL (airframe 10046, whose RD_YAW_STK_GAIN is 0.6): the motors are
``thr -/+ 0.6 roll`` exactly, and PX4 cuts the throttle by ``|thr| + |d| - 1`` when that is positive
(never for |L|, |R| <= 1). With g < 1 a difference |L - R| above 2 g is out of reach: y saturates and
the difference is cut to 2 g, the sum kept (``assess_failsafe`` warns; px4-boat.params sets g = 1).
Slew: with RO_ACCEL_LIM, RO_DECEL_LIM and RO_MAX_THR_SPEED all > 0 PX4 ramps the throttle part;
px4-boat.params turns it off. Neither Manual-mode axis has a dead zone or expo on this path.

Reconstruction error of L or R after rounding: 0.5/1000 g (y) + 0.5/500 (z) <= 0.0015; the guard adds
margin to 0.002.

Modes: ``custom_mode = main << 16 | sub << 24`` (``px4_custom_mode.h``); DO_SET_MODE takes
param1 = 1 (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), param2 = main, param3 = sub.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from seaway_vehicle_io.profile import (
    FailsafeAssessment,
    ManualControlAxes,
    Profile,
    RcReceiver,
    UnknownModeError,
    Verdict,
    clamp_int,
    register,
)

MAV_AUTOPILOT_PX4 = 12
CUSTOM_MODE_ENABLED = 1
YAW_STICK_GAIN = "RD_YAW_STK_GAIN"
"""rover_differential's Manual-mode scale from the roll stick to the speed difference [-]."""
YAW_STICK_GAIN_DEFAULT = 1.0
"""Its value when the firmware does not report it (PX4's own default; older firmware scaled no roll)."""

# Seaway name -> (main mode, sub mode). HOLD is PX4's AUTO.LOITER, which the rover implements as
# a stop (docs/autopilots.md A.3).
MODES: dict[str, tuple[int, int]] = {
    "MANUAL": (1, 0),
    "ALTCTL": (2, 0),
    "POSCTL": (3, 0),
    "READY": (4, 1),
    "TAKEOFF": (4, 2),
    "HOLD": (4, 3),
    "MISSION": (4, 4),
    "RTL": (4, 5),
    "LAND": (4, 6),
    "FOLLOW_TARGET": (4, 8),
    "PRECLAND": (4, 9),
    "ACRO": (5, 0),
    "OFFBOARD": (6, 0),
    "STABILIZED": (7, 0),
}
_DECODE = {v: k for k, v in MODES.items()}
# Main modes whose sub mode does not change the name (POSCTL sub 1 is plain position control).
_MAIN_ONLY = {1: "MANUAL", 2: "ALTCTL", 3: "POSCTL", 5: "ACRO", 6: "OFFBOARD", 7: "STABILIZED"}

# NAV_RCL_ACT values (commander_params.yaml; 7 is new in 1.18): what PX4 does when manual control
# is lost. 7 switches to Hold without flagging a failsafe (event commander_rc_loss_hold_no_failsafe).
NAV_RCL_ACT_VERDICT: dict[int, tuple[Verdict, str]] = {
    0: ("none", "0 = disabled (pre-1.14 firmware): no action, last setpoint kept"),
    1: ("stops", "1 = Hold"),
    2: ("takes_over", "2 = Return (needs home and position, else falls through to Land/Terminate)"),
    3: ("takes_over", "3 = Land"),
    5: ("stops", "5 = Terminate"),
    6: ("stops", "6 = Disarm"),
    7: ("stops", "7 = Hold (no failsafe)"),
}


class Px4Profile(Profile):
    name = "px4"
    mav_autopilot = MAV_AUTOPILOT_PX4
    quantisation_guard = 0.002
    force_arm_magic = 21196  # Commander.cpp: forced = lroundf(param2) == 21196
    # PX4 1.13+ reports arming-check failures as EVENTs, not STATUSTEXT (measured on 1.18 SITL: the
    # refusal's ACK comes with no text at all).
    events_protocol = True
    # Its health report's failures and arming denials as text as well (seen on 1.18 SITL while its
    # EKF aligns: "Preflight Fail: no heading reference", "Arming denied: Resolve system health
    # failures first").
    start_check_prefixes = ("Preflight Fail:", "Arming denied:")
    # PX4 takes SET_MESSAGE_INTERVAL (MavlinkReceiver::handle_message_command_long); it has no
    # REQUEST_DATA_STREAM fallback, and needs none.
    requests_message_rates = True
    failsafe_params = (
        "COM_RC_IN_MODE", "COM_RC_LOSS_T", "NAV_RCL_ACT", "COM_FAIL_ACT_T", "NAV_DLL_ACT",
        "CA_AIRFRAME", "RO_ACCEL_LIM", "RO_DECEL_LIM", "RO_MAX_THR_SPEED", YAW_STICK_GAIN,
    )
    mapping_needs_params = True

    def manual_control(self, left: float, right: float) -> ManualControlAxes:
        """The mapping with RD_YAW_STK_GAIN = 1 (neutral, and a firmware not yet read)."""
        return axes_for(left, right, YAW_STICK_GAIN_DEFAULT)

    def mapper(self, params: Mapping[str, float]) -> Callable[[float, float], ManualControlAxes]:
        """The roll axis scaled by the firmware's RD_YAW_STK_GAIN (absent: 1; not positive:
        ``assess_failsafe`` blocks thrust, and the plain mapping stays)."""
        gain = params.get(YAW_STICK_GAIN, YAW_STICK_GAIN_DEFAULT)
        if not gain > 0.0:
            return self.manual_control

        def axes(left: float, right: float) -> ManualControlAxes:
            return axes_for(left, right, gain)
        return axes

    def mode_names(self) -> tuple[str, ...]:
        return tuple(MODES)

    def encode_mode(self, name: str) -> tuple[float, float, float]:
        key = name.strip().upper()
        if key not in MODES:
            raise UnknownModeError(f"PX4 has no mode {name!r}; known: {', '.join(MODES)}")
        main, sub = MODES[key]
        return (float(CUSTOM_MODE_ENABLED), float(main), float(sub))

    def decode_mode(self, base_mode: int, custom_mode: int) -> str:
        if not base_mode & CUSTOM_MODE_ENABLED:
            return f"UNKNOWN(base_mode={base_mode})"
        main = (custom_mode >> 16) & 0xFF
        sub = (custom_mode >> 24) & 0xFF
        if main in _MAIN_ONLY:
            return _MAIN_ONLY[main]
        if main == 4 and sub == 0:
            return "MISSION"  # Commander: AUTO with sub mode 0 runs the mission
        return _DECODE.get((main, sub), f"UNKNOWN(main={main},sub={sub})")

    def assess_failsafe(self, params: dict[str, float], our_sysid: int,
                        rc_receiver: RcReceiver = "unknown") -> FailsafeAssessment:
        warnings: list[str] = []
        missing = [p for p in ("COM_RC_IN_MODE", "COM_RC_LOSS_T", "NAV_RCL_ACT") if p not in params]
        if missing:
            return FailsafeAssessment("unknown", f"PX4 did not report {', '.join(missing)}",
                                      params=dict(params))
        in_mode = int(params["COM_RC_IN_MODE"])
        loss_t = params["COM_RC_LOSS_T"]
        act = int(params["NAV_RCL_ACT"])
        if in_mode == 0:
            warnings.append("COM_RC_IN_MODE=0 (RC only): PX4 ignores our MANUAL_CONTROL")
        elif in_mode == 3:
            warnings.append("COM_RC_IN_MODE=3 keeps the first manual source until reboot: an RC "
                            "seen first locks MAVLink out (1, or 2/5/6 with an RC fitted, is safer)")
        if in_mode == 4:
            return FailsafeAssessment(
                "none", "COM_RC_IN_MODE=4: manual control disabled, so no manual-control loss "
                        "failsafe (and our MANUAL_CONTROL is ignored)",
                tuple(warnings), params=dict(params))
        if loss_t > 0.5:
            warnings.append(f"COM_RC_LOSS_T={loss_t:g} s: the thrusters keep our last command that "
                            "long after vehicle_io stops (0.5 s or less recommended)")
        verdict, what = NAV_RCL_ACT_VERDICT.get(act, ("unknown", f"{act} = not a known action"))
        if verdict == "takes_over":
            warnings.append(f"NAV_RCL_ACT={what}; 1 (Hold) or 6 (Disarm) stops the boat instead")
        fail_act_t = params.get("COM_FAIL_ACT_T")
        delay = f", after a {fail_act_t:g} s Hold" if fail_act_t and verdict != "stops" else ""
        if params.get("CA_AIRFRAME") is not None and int(params["CA_AIRFRAME"]) != 6:
            warnings.append(f"CA_AIRFRAME={int(params['CA_AIRFRAME'])}, not 6 (Rover Differential): "
                            "the MANUAL_CONTROL mapping assumes a differential rover")
        blocking: list[str] = []
        gain = params.get(YAW_STICK_GAIN)
        if gain is not None and not gain > 0.0:
            blocking.append(f"{YAW_STICK_GAIN}={gain:g}: PX4 turns no roll into a speed "
                            "difference, so no thrust difference can be commanded (1 wanted)")
        elif gain is not None and gain < 1.0:
            warnings.append(f"{YAW_STICK_GAIN}={gain:g}: thrust differences above {2 * gain:g} of "
                            "full scale (L - R) are cut to that (1 lets the full range through)")
        for slew in ("RO_ACCEL_LIM", "RO_DECEL_LIM"):
            if params.get(slew, 0.0) > 0 and params.get("RO_MAX_THR_SPEED", 0.0) > 0:
                warnings.append(f"{slew}={params[slew]:g} with RO_MAX_THR_SPEED>0 slew-limits the "
                                "throttle (L+R) part of every command")
        summary = (f"manual-control loss after COM_RC_LOSS_T={loss_t:g} s -> NAV_RCL_ACT={what}"
                   f"{delay}: {verdict}")
        return FailsafeAssessment(verdict, summary, tuple(warnings), tuple(blocking),
                                  params=dict(params))


def axes_for(left: float, right: float, yaw_stick_gain: float) -> ManualControlAxes:
    """Normalised (L port, R starboard) -> MANUAL_CONTROL for a firmware whose RD_YAW_STK_GAIN is
    ``yaw_stick_gain`` (> 0): the inverse of PX4's differential Manual mode (module docstring)."""
    return ManualControlAxes(
        x=0,
        y=clamp_int(500.0 * (left - right) / yaw_stick_gain, -1000, 1000),
        z=clamp_int(500.0 + 250.0 * (left + right), 0, 1000),
        r=0,
    )


PROFILE = register(Px4Profile())
