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

Reconstruction error: 0.5/1000 from rounding plus 1 us of the 1000 us PWM span (0.002) that
``manual_override`` rounds to; the guard is 0.003.

Modes: HEARTBEAT ``custom_mode`` = Rover mode number (``Rover/mode.h``); DO_SET_MODE takes
param1 = 1 (MAV_MODE_FLAG_CUSTOM_MODE_ENABLED), param2 = number. ArduPilot's AUTO is Seaway's
MISSION (both names are accepted when setting).
"""

from __future__ import annotations

from seaway_vehicle_io.profile import (
    FailsafeAssessment,
    ManualControlAxes,
    Profile,
    UnknownModeError,
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

FS_ACTION_NAMES = {0: "None", 1: "RTL", 2: "Hold", 3: "SmartRTL->RTL->Hold",
                   4: "SmartRTL->Hold", 5: "Terminate"}


class ArduPilotProfile(Profile):
    name = "ardupilot"
    mav_autopilot = MAV_AUTOPILOT_ARDUPILOTMEGA
    quantisation_guard = 0.003
    force_arm_magic = 2989  # GCS.h magic_force_arm_value
    failsafe_params = (
        "FS_THR_ENABLE", "FS_ACTION", "FS_TIMEOUT", "FS_GCS_ENABLE", "RC_OVERRIDE_TIME",
        "RC_OPTIONS", "PILOT_STEER_TYPE", "SYSID_MYGCS", "FRAME_CLASS", "MOT_SLEWRATE",
        "MOT_THST_ASYM", "RC1_DZ", "RC3_DZ",
    )

    def manual_control(self, left: float, right: float) -> ManualControlAxes:
        return ManualControlAxes(
            x=0,
            y=clamp_int(1000.0 * left, -1000, 1000),
            z=clamp_int(1000.0 * right, -1000, 1000),
            r=0,
        )

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

    def assess_failsafe(self, params: dict[str, float], our_sysid: int) -> FailsafeAssessment:
        warnings: list[str] = []
        blocking: list[str] = []
        p = params
        if "PILOT_STEER_TYPE" in p and int(p["PILOT_STEER_TYPE"]) != 1:
            blocking.append(f"PILOT_STEER_TYPE={int(p['PILOT_STEER_TYPE'])}: the thrust mapping "
                            "needs 1 (Two Paddles); other values turn L/R into steering/throttle")
        elif "PILOT_STEER_TYPE" not in p:
            warnings.append("PILOT_STEER_TYPE not read: the mapping assumes 1 (Two Paddles)")
        if "SYSID_MYGCS" in p and int(p["SYSID_MYGCS"]) != our_sysid:
            warnings.append(f"SYSID_MYGCS={int(p['SYSID_MYGCS'])} but we are system {our_sysid}: "
                            "ArduPilot ignores our MANUAL_CONTROL")
        if int(p.get("RC_OPTIONS", 0)) & 0b10:
            warnings.append("RC_OPTIONS bit 1 set: ArduPilot ignores MAVLink overrides")
        if "FRAME_CLASS" in p and int(p["FRAME_CLASS"]) != 2:
            warnings.append(f"FRAME_CLASS={int(p['FRAME_CLASS'])}, not 2 (Boat)")
        if p.get("MOT_SLEWRATE", 0.0) != 0.0:
            warnings.append(f"MOT_SLEWRATE={p['MOT_SLEWRATE']:g} %/s slew-limits every command")
        if "MOT_THST_ASYM" in p and p["MOT_THST_ASYM"] != 1.0:
            warnings.append(f"MOT_THST_ASYM={p['MOT_THST_ASYM']:g}: reverse thrust is rescaled by "
                            "the autopilot; the vessel file's reverse_thrust_max_n must match")
        for dz in ("RC1_DZ", "RC3_DZ"):
            if p.get(dz, 0.0) != 0.0:
                warnings.append(f"{dz}={p[dz]:g} us: small commands fall in the RC dead zone")

        if "FS_THR_ENABLE" not in p or "FS_GCS_ENABLE" not in p:
            return FailsafeAssessment("unknown", "ArduPilot did not report FS_THR_ENABLE and "
                                      "FS_GCS_ENABLE", tuple(warnings), tuple(blocking), dict(p))
        action = int(p.get("FS_ACTION", -1))
        action_name = FS_ACTION_NAMES.get(action, f"{action}")
        timeout = p.get("FS_TIMEOUT")
        if int(p["FS_THR_ENABLE"]) >= 1:
            verdict = "stops"
            summary = ("overrides stop -> after 0.5 s pilot input forced to zero (FS_THR_ENABLE="
                       f"{int(p['FS_THR_ENABLE'])}), then FS_ACTION={action_name} after "
                       f"FS_TIMEOUT={timeout if timeout is not None else '?'} s: stops "
                       "(only without an RC receiver, which would take over instead)")
        elif int(p["FS_GCS_ENABLE"]) >= 1:
            verdict = {2: "stops", 5: "stops", 0: "none"}.get(action, "takes_over")
            summary = (f"GCS failsafe (FS_GCS_ENABLE={int(p['FS_GCS_ENABLE'])}) after FS_TIMEOUT="
                       f"{timeout if timeout is not None else '?'} s -> FS_ACTION={action_name}: "
                       f"{verdict}")
        else:
            override = p.get("RC_OVERRIDE_TIME")
            verdict = "none" if override is not None and override < 0 else "unknown"
            summary = (f"FS_THR_ENABLE=0 and FS_GCS_ENABLE=0: no loss failsafe; overrides expire "
                       f"after RC_OVERRIDE_TIME={override if override is not None else '?'} s: "
                       f"{verdict}")
        return FailsafeAssessment(verdict, summary, tuple(warnings), tuple(blocking), dict(p))


PROFILE = register(ArduPilotProfile())
