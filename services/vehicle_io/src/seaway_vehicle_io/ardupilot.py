"""ArduPilot Rover profile: boat (FRAME_CLASS=2), skid steering, MANUAL mode (docs/autopilots.md B).

With ``PILOT_STEER_TYPE = 1`` (Two Paddles) the pilot input is the exact inverse of the skid mixer
(``motor_left = thr + str``, ``motor_right = thr - str``): the steering channel is the left paddle
and the throttle channel the right one. Rover's ``handle_manual_control_axes`` takes only y
(steering) and z (throttle), both signed -1000..1000 with 0 = stop::

    y = round(1000 * L)      (left, port)
    z = round(1000 * R)      (right, starboard)
    x = 0, r = 0             (ignored by Rover)

Any other PILOT_STEER_TYPE would turn these into steering/throttle and move the boat wrongly, so a
read value other than 1 blocks thrust (neutral only, failsafe ``autopilot_config``).

RC dead zone and calibration (measured on Rover SITL, 4.7.0-dev): Rover turns MANUAL_CONTROL into an
RC override, ``pwm = RCn_MIN + (RCn_MAX - RCn_MIN) * (v + 1000) / 2000`` (truncated to whole us,
``GCS_MAVLINK::manual_override``), and reads each paddle with ``RC_Channel::norm_input_dz``, which
drops ``RCn_DZ`` us either side of ``RCn_TRIM`` and rescales the rest::

    n = (pwm - (trim + dz)) / (max - (trim + dz))   above the dead zone
    n = (pwm - (trim - dz)) / ((trim - dz) - min)   below it, 0 inside

With the 30 us default that made 12 N of 75 N come out 34 % low. ``RcChannel`` inverts both steps
from the parameters read at connection, so the paddle ArduPilot computes is the one we mean, to
1 us of PWM (0.2 % of full scale). Without a dead zone and with the trim mid-range it is exactly
the plain ``round(1000 * n)``.

Reconstruction error: 1 us of the (max - trim - dz) = 470 us span (0.0021) plus rounding; the
guard is 0.003.

Modes: HEARTBEAT ``custom_mode`` = Rover mode number (``Rover/mode.h``); DO_SET_MODE takes
param1 = 1 (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), param2 = number. ArduPilot's AUTO is Seaway's
MISSION (both names are accepted when setting).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

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

MAV_AUTOPILOT_ARDUPILOTMEGA = 3
CUSTOM_MODE_ENABLED = 1

MODES: dict[str, int] = {
    "MANUAL": 0,
    "ACRO": 1,
    "STEERING": 3,
    "HOLD": 4,
    "LOITER": 5,
    "FOLLOW": 6,
    "SIMPLE": 7,
    "DOCK": 8,
    "CIRCLE": 9,
    "MISSION": 10,
    "RTL": 11,
    "SMART_RTL": 12,
    "GUIDED": 15,
    "INITIALISING": 16,
}
ALIASES = {"AUTO": "MISSION"}
_DECODE = {v: k for k, v in MODES.items()}

# FS_ACTION values (Rover/Parameters.cpp, 4.7: "6:Loiter or Hold" is new). A value not named here
# is judged "unknown", never guessed.
FS_ACTION_NAMES = {0: "None", 1: "RTL", 2: "Hold", 3: "SmartRTL->RTL->Hold",
                   4: "SmartRTL->Hold", 5: "Terminate", 6: "Loiter->Hold"}
FS_ACTIONS_THAT_STOP = frozenset({2, 5})  # Hold, Terminate (RTL, SmartRTL, Loiter drive the boat)

RADIO_FAILSAFE_S = 0.5  # Rover::radio_failsafe_check: no new RC input (overrides included) for 500 ms

# REQUEST_DATA_STREAM groups (GCS_MAVLink/GCS_Common.cpp, ArduPilot's stream tables): the fallback
# for the rates SET_MESSAGE_INTERVAL could not set.
MAV_DATA_STREAM_EXTENDED_STATUS = 2
MAV_DATA_STREAM_POSITION = 6
MAV_DATA_STREAM_EXTRA1 = 10
MAV_DATA_STREAM_EXTRA3 = 12
DATA_STREAMS = {
    "SYS_STATUS": MAV_DATA_STREAM_EXTENDED_STATUS,
    "GPS_RAW_INT": MAV_DATA_STREAM_EXTENDED_STATUS,
    "GLOBAL_POSITION_INT": MAV_DATA_STREAM_POSITION,
    "LOCAL_POSITION_NED": MAV_DATA_STREAM_POSITION,
    "ATTITUDE": MAV_DATA_STREAM_EXTRA1,
    "BATTERY_STATUS": MAV_DATA_STREAM_EXTRA3,
}

# The GCS system id parameter: SYSID_MYGCS until 4.6, MAV_GCS_SYSID from 4.7 (measured on the
# 4.7.0-dev SITL: SYSID_MYGCS is not answered at all).
GCS_SYSID = "SYSID_MYGCS"
GCS_SYSID_NAMES = ("MAV_GCS_SYSID", "SYSID_MYGCS")

# RC input calibration ArduPilot assumes when a parameter was not read: RC_Channel's defaults,
# and Rover's 30 us dead zone on steering and throttle (Rover::init_rc_in).
RC_DEFAULTS = {"MIN": 1100.0, "TRIM": 1500.0, "MAX": 1900.0, "DZ": 30.0, "REVERSED": 0.0}
STEER_CHANNEL, THROTTLE_CHANNEL = 1, 3  # RCMAP_ROLL, RCMAP_THROTTLE defaults
RC_PARAMS = tuple(f"RC{ch}_{f}" for ch in (STEER_CHANNEL, THROTTLE_CHANNEL)
                  for f in ("MIN", "TRIM", "MAX", "DZ", "REVERSED"))


@dataclass(frozen=True)
class RcChannel:
    """One RC input channel's calibration [us], as ArduPilot reads it (see the module)."""

    min_us: float
    trim_us: float
    max_us: float
    dead_zone_us: float = 0.0
    reversed: bool = False

    def __post_init__(self) -> None:
        lo, hi = self.trim_us - self.dead_zone_us, self.trim_us + self.dead_zone_us
        if not (self.min_us < lo and hi < self.max_us and self.dead_zone_us >= 0):
            raise ValueError(f"RC calibration min {self.min_us:g} / trim {self.trim_us:g} / max "
                             f"{self.max_us:g} / dead zone {self.dead_zone_us:g} us: need min < "
                             "trim - dz and trim + dz < max")

    @classmethod
    def from_params(cls, params: Mapping[str, float], channel: int) -> RcChannel:
        def get(field: str) -> float:
            return float(params.get(f"RC{channel}_{field}", RC_DEFAULTS[field]))
        return cls(get("MIN"), get("TRIM"), get("MAX"), get("DZ"), get("REVERSED") != 0.0)

    def is_plain(self) -> bool:
        """No dead zone, trim mid-range, not reversed: ``round(1000 n)`` is already exact."""
        return (self.dead_zone_us == 0.0 and not self.reversed
                and self.trim_us * 2 == self.min_us + self.max_us)

    def pwm_for(self, n: float) -> int:
        """The PWM [us] for which ``norm_input_dz`` gives ``n`` in [-1, 1] (nearest whole us,
        outside the dead zone for any n != 0)."""
        n = min(max(n, -1.0), 1.0)
        if self.reversed:
            n = -n
        if n == 0.0:
            return round(self.trim_us)
        if n > 0:
            edge = self.trim_us + self.dead_zone_us
            return max(round(edge + n * (self.max_us - edge)), math.floor(edge) + 1)
        edge = self.trim_us - self.dead_zone_us
        return min(round(edge + n * (edge - self.min_us)), math.ceil(edge) - 1)

    def override_value(self, n: float) -> int:
        """MANUAL_CONTROL axis value (-1000..1000) that ArduPilot turns into ``pwm_for(n)``."""
        if self.is_plain():
            return clamp_int(1000.0 * n, -1000, 1000)
        pwm = self.pwm_for(n)
        span = self.max_us - self.min_us
        # Smallest v whose override reaches pwm: ArduPilot truncates, and each step of v moves the
        # PWM by span/2000 <= 1 us, so this lands on pwm exactly (1e-3 us keeps float noise off).
        v = math.ceil((pwm + 1e-3 - self.min_us) * 2000.0 / span - 1000.0)
        return min(max(v, -1000), 1000)

    def norm_input_dz(self, v: int) -> float:
        """What ArduPilot reads from axis value ``v`` (its arithmetic, for tests and the docs)."""
        pwm = math.trunc(self.min_us + (self.max_us - self.min_us) * (v + 1000) / 2000.0)
        lo, hi = self.trim_us - self.dead_zone_us, self.trim_us + self.dead_zone_us
        if pwm < lo:
            n = (pwm - lo) / (lo - self.min_us)
        elif pwm > hi:
            n = (pwm - hi) / (self.max_us - hi)
        else:
            n = 0.0
        n = -n if self.reversed else n
        return min(max(n, -1.0), 1.0)


class ArduPilotProfile(Profile):
    name = "ardupilot"
    mav_autopilot = MAV_AUTOPILOT_ARDUPILOTMEGA
    quantisation_guard = 0.003
    force_arm_magic = 2989  # GCS.h magic_force_arm_value
    failsafe_params = (
        "FS_THR_ENABLE", "FS_ACTION", "FS_TIMEOUT", "FS_GCS_ENABLE", "RC_OVERRIDE_TIME",
        "RC_OPTIONS", "PILOT_STEER_TYPE", GCS_SYSID, "FRAME_CLASS", "MOT_SLEWRATE",
        "MOT_THST_ASYM", "RCMAP_ROLL", "RCMAP_THROTTLE", *RC_PARAMS,
    )
    param_alternatives = MappingProxyType({GCS_SYSID: GCS_SYSID_NAMES})
    requests_message_rates = True
    data_streams = DATA_STREAMS
    arming_refusal_prefixes = ("PreArm:", "Arm:")
    start_check_prefixes = arming_refusal_prefixes
    mapping_needs_params = True
    booting_modes = ("INITIALISING",)

    def manual_control(self, left: float, right: float) -> ManualControlAxes:
        """The plain mapping (no RC dead zone, trim mid-range): neutral, and autopilots whose
        calibration is unknown."""
        return ManualControlAxes(
            x=0,
            y=clamp_int(1000.0 * left, -1000, 1000),
            z=clamp_int(1000.0 * right, -1000, 1000),
            r=0,
        )

    def mapper(self, params: Mapping[str, float]) -> Callable[[float, float], ManualControlAxes]:
        """Left paddle on the steering channel (RC1), right paddle on the throttle channel (RC3),
        each through its calibration and dead zone (``RcChannel``)."""
        try:
            steer = RcChannel.from_params(params, STEER_CHANNEL)
            throttle = RcChannel.from_params(params, THROTTLE_CHANNEL)
        except ValueError:
            return self.manual_control  # assess_failsafe blocks thrust for this calibration

        def axes(left: float, right: float) -> ManualControlAxes:
            return ManualControlAxes(x=0, y=steer.override_value(left),
                                     z=throttle.override_value(right), r=0)
        return axes

    def mode_names(self) -> tuple[str, ...]:
        return (*MODES, *ALIASES)

    def encode_mode(self, name: str) -> tuple[float, float, float]:
        key = name.strip().upper()
        key = ALIASES.get(key, key)
        if key not in MODES or key == "INITIALISING":
            known = ", ".join(n for n in (*MODES, *ALIASES) if n != "INITIALISING")
            raise UnknownModeError(f"ArduPilot Rover has no settable mode {name!r}; known: {known}")
        return (float(CUSTOM_MODE_ENABLED), float(MODES[key]), 0.0)

    def decode_mode(self, base_mode: int, custom_mode: int) -> str:
        return _DECODE.get(custom_mode, f"UNKNOWN({custom_mode})")

    def assess_failsafe(self, params: dict[str, float], our_sysid: int,
                        rc_receiver: RcReceiver = "unknown") -> FailsafeAssessment:
        """What Rover does when our MANUAL_CONTROL (RC overrides) stops, from its parameters and
        whether a receiver is fitted (docs/autopilots.md B.1, measured on SITL):

        * every override is held for ``RC_OVERRIDE_TIME`` s after the last one (0: overrides are
          refused, so we cannot drive at all; -1: held for ever);
        * **no receiver**: no new RC input for 0.5 s -> radio failsafe (``FS_THR_ENABLE`` >= 1):
          pilot input forced to zero (thrusters neutral), then ``FS_ACTION`` after ``FS_TIMEOUT``;
        * **receiver**: its frames keep arriving, so the radio failsafe never trips; the overrides
          expire after ``RC_OVERRIDE_TIME`` and the sticks drive the thrusters;
        * ``FS_GCS_ENABLE``: our heartbeats stop too -> ``FS_ACTION`` after ``FS_TIMEOUT``
          (``FS_GCS_TIMEOUT`` in newer builds), with or without a receiver.
        """
        warnings: list[str] = []
        blocking: list[str] = []
        p = params
        if "PILOT_STEER_TYPE" in p and int(p["PILOT_STEER_TYPE"]) != 1:
            blocking.append(f"PILOT_STEER_TYPE={int(p['PILOT_STEER_TYPE'])}: the thrust mapping "
                            "needs 1 (Two Paddles); other values turn L/R into steering/throttle")
        elif "PILOT_STEER_TYPE" not in p:
            warnings.append("PILOT_STEER_TYPE not read: the mapping assumes 1 (Two Paddles)")
        if GCS_SYSID in p and int(p[GCS_SYSID]) != our_sysid:
            warnings.append(f"{'/'.join(GCS_SYSID_NAMES)}={int(p[GCS_SYSID])} but we are system "
                            f"{our_sysid}: ArduPilot ignores our MANUAL_CONTROL (set it to {our_sysid})")
        override = p.get("RC_OVERRIDE_TIME")
        if override is not None and override == 0.0:
            blocking.append("RC_OVERRIDE_TIME=0 disables RC overrides: ArduPilot ignores our "
                            "MANUAL_CONTROL")
        if int(p.get("RC_OPTIONS", 0)) & 0b10:
            blocking.append("RC_OPTIONS bit 1 set: ArduPilot ignores MAVLink overrides")
        if "FRAME_CLASS" in p and int(p["FRAME_CLASS"]) != 2:
            warnings.append(f"FRAME_CLASS={int(p['FRAME_CLASS'])}, not 2 (Boat)")
        if p.get("MOT_SLEWRATE", 0.0) != 0.0:
            warnings.append(f"MOT_SLEWRATE={p['MOT_SLEWRATE']:g} %/s slew-limits every command "
                            "(and delays neutral)")
        if "MOT_THST_ASYM" in p and p["MOT_THST_ASYM"] != 1.0:
            warnings.append(f"MOT_THST_ASYM={p['MOT_THST_ASYM']:g}: reverse thrust is rescaled by "
                            "the autopilot; the vessel file's reverse_thrust_max_n must match")
        for name, want in (("RCMAP_ROLL", STEER_CHANNEL), ("RCMAP_THROTTLE", THROTTLE_CHANNEL)):
            if name in p and int(p[name]) != want:
                warnings.append(f"{name}={int(p[name])}: the dead-zone compensation uses RC{want}'s "
                                "calibration, so small thrusts are off")
        unread = [n for n in RC_PARAMS if n not in p]
        if unread:
            warnings.append(f"not read: {', '.join(unread)}; the RC dead-zone compensation assumes "
                            "ArduPilot's defaults (min 1100, trim 1500, max 1900, dz 30 us)")
        for ch in (STEER_CHANNEL, THROTTLE_CHANNEL):
            try:
                RcChannel.from_params(p, ch)
            except ValueError as err:
                blocking.append(f"RC{ch}: {err}")

        verdict, summary = self._loss_verdict(p, rc_receiver)
        return FailsafeAssessment(verdict, summary, tuple(warnings), tuple(blocking), dict(p))

    @staticmethod
    def _loss_verdict(p: dict[str, float], rc_receiver: RcReceiver) -> tuple[Verdict, str]:
        if "FS_THR_ENABLE" not in p or "FS_GCS_ENABLE" not in p or "RC_OVERRIDE_TIME" not in p:
            return "unknown", ("ArduPilot did not report FS_THR_ENABLE, FS_GCS_ENABLE and "
                               "RC_OVERRIDE_TIME")
        action = int(p.get("FS_ACTION", -1))
        action_name = FS_ACTION_NAMES.get(action, f"{action}")
        timeout = p.get("FS_TIMEOUT")
        timeout_text = f"{timeout:g}" if timeout is not None else "?"
        action_verdict: Verdict = "stops" if action in FS_ACTIONS_THAT_STOP else (
            "none" if action == 0 else "takes_over" if action in FS_ACTION_NAMES else "unknown")
        override = p["RC_OVERRIDE_TIME"]
        held = ("held for ever (RC_OVERRIDE_TIME=-1)" if override < 0
                else f"held for RC_OVERRIDE_TIME={override:g} s")
        fs_thr = int(p["FS_THR_ENABLE"]) >= 1
        fs_gcs = int(p["FS_GCS_ENABLE"]) >= 1
        gcs = (f"; GCS failsafe (FS_GCS_ENABLE={int(p['FS_GCS_ENABLE'])}): FS_ACTION={action_name} "
               f"after FS_TIMEOUT={timeout_text} s" if fs_gcs else "")

        # Without a receiver: the overrides are the only RC input.
        if fs_thr:
            absent: tuple[Verdict, str] = ("stops", (
                f"no receiver: the last command is held {RADIO_FAILSAFE_S:g} s, then the radio "
                f"failsafe (FS_THR_ENABLE={int(p['FS_THR_ENABLE'])}) forces the thrusters to "
                f"neutral, and FS_ACTION={action_name} follows after FS_TIMEOUT={timeout_text} s"))
        elif fs_gcs:
            absent = (action_verdict, f"no receiver: the last command is {held}, then nothing"
                      " (FS_THR_ENABLE=0)")
        else:
            absent = ("none", f"no receiver and FS_THR_ENABLE=0, FS_GCS_ENABLE=0: the last "
                      f"command is {held}, then the thrusters keep the last RC input")
        # With a receiver: its frames keep the radio failsafe quiet; the sticks take over.
        present: tuple[Verdict, str] = (
            action_verdict if fs_gcs else ("none" if override < 0 else "takes_over"),
            f"receiver: the last command is {held}, then the receiver's sticks drive the "
            "thrusters (no radio failsafe while the receiver works)")
        if fs_gcs and action_verdict == "stops":
            absent = ("stops", absent[1] + gcs)
            present = ("stops", present[1] + gcs)
        elif fs_gcs:
            absent, present = (absent[0], absent[1] + gcs), (present[0], present[1] + gcs)
        if rc_receiver == "absent":
            return absent[0], absent[1] + " (rc_receiver = absent)"
        if rc_receiver == "present":
            return present[0], present[1] + " (rc_receiver = present)"
        verdict: Verdict = absent[0] if absent[0] == present[0] else "unknown"
        return verdict, (f"{absent[1]}; with a {present[1]} (rc_receiver not set in the config: "
                         "set it to make this exact)")


PROFILE = register(ArduPilotProfile())
