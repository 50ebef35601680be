"""What every autopilot profile provides, and the types they share.

A profile is everything that differs between PX4 and ArduPilot: the MANUAL_CONTROL axis mapping,
mode numbers, the arming "force" magic numbers, how PARAM_VALUE encodes integers, and which
parameters decide what the autopilot does when our MANUAL_CONTROL stream stops. The rest of
vehicle_io never tests which autopilot it talks to.

Each autopilot is one module (``px4.py``, ``ardupilot.py``) that ``register``s its profile here; the
package imports them all (``__init__.py``), so the registry is complete whenever any part of
vehicle_io runs. The config's ``autopilot`` values and the command line's ``--autopilot`` choices
are ``choices()``: ``auto`` and the registered names.
"""

from __future__ import annotations

import struct
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

Verdict = Literal["stops", "takes_over", "none", "unknown"]
RcReceiver = Literal["absent", "present", "unknown"]
"""Whether an RC receiver is wired to the autopilot (the operator says so in the config: MAVLink
cannot tell a receiver's input from our overrides). It decides what ArduPilot does when our
stream stops: see ``ardupilot.ArduPilotProfile.assess_failsafe``."""

# MAV_PARAM_TYPE values of the integer types (UINT8=1 ... INT32=6); REAL32 = 9.
INT_PARAM_TYPES = frozenset({1, 2, 3, 4, 5, 6})


class UnknownModeError(ValueError):
    """A mode name this autopilot does not have; the text lists the ones it has."""


@dataclass(frozen=True)
class ManualControlAxes:
    """MANUAL_CONTROL (#69) axis values, each in the range the autopilot accepts."""

    x: int
    y: int
    z: int
    r: int


@dataclass(frozen=True)
class FailsafeAssessment:
    """What the autopilot will do if vehicle_io dies (its MANUAL_CONTROL stream stops).

    verdict: ``stops`` (thrusters go to zero: Hold, Disarm, Terminate or zeroed pilot input),
    ``takes_over`` (the autopilot drives itself, e.g. Return), ``none`` (the last command stays or
    nothing reacts), ``unknown`` (parameters could not be read).
    ``blocking``: configuration under which our thrust mapping would move the boat wrongly;
    vehicle_io then sends neutral only (failsafe ``autopilot_config``) until it is fixed.
    """

    verdict: Verdict
    summary: str
    warnings: tuple[str, ...] = ()
    blocking: tuple[str, ...] = ()
    params: dict[str, float] = field(default_factory=dict)


def decode_param_value(value: float, param_type: int) -> float:
    """PARAM_VALUE.param_value -> the parameter's value.

    MAVLink carries every parameter in a float. For integer types there are two conventions:
    PX4 copies the integer's bytes into the float ("bytewise": ``param_get(param,
    &msg.param_value)`` in ``mavlink_parameters.cpp``), ArduPilot converts the number ("C cast").
    Bytewise small integers are denormal floats (2 -> 2.8e-45), while a cast integer is a whole
    float whose bit pattern as an int32 is huge (2.0 -> 1073741824); that difference tells them
    apart, so both encodings decode right whatever the profile.
    """
    if param_type not in INT_PARAM_TYPES:
        return float(value)
    as_int = struct.unpack("<i", struct.pack("<f", value))[0]
    is_whole = value == value and abs(value) < 2**24 and float(value).is_integer()
    if is_whole and value != 0 and abs(as_int) >= 2**24:
        return float(int(value))  # C-cast encoding
    return float(as_int)  # bytewise encoding (0 is the same in both)


class Profile(ABC):
    """One autopilot's dialect of MAVLink for a twin-thruster vessel in manual mode."""

    name: str
    mav_autopilot: int  # HEARTBEAT.autopilot value (MAV_AUTOPILOT)
    quantisation_guard: float  # worst-case error of L or R after the wire encoding [normalised]
    failsafe_params: tuple[str, ...]
    force_arm_magic: int
    force_disarm_magic: int = 21196  # both autopilots: MAV_CMD_COMPONENT_ARM_DISARM param2
    param_alternatives: Mapping[str, tuple[str, ...]] = {}
    """Parameters known under more than one name (a rename between firmware versions): the name the
    assessment uses -> every name to ask for. The first that answers is the value; the others are
    not waited for (ArduPilot never answers a name it does not have)."""
    requests_message_rates: bool = False
    """Ask for ``message_rates_hz`` at connection and check they arrive (``rates.py``)."""
    data_streams: Mapping[str, int] = {}
    """Message -> REQUEST_DATA_STREAM stream id holding it: the fallback when the autopilot does not
    take SET_MESSAGE_INTERVAL."""
    arming_refusal_prefixes: tuple[str, ...] = ()
    """STATUSTEXT prefixes in which the autopilot says why it refused to arm."""
    start_check_prefixes: tuple[str, ...] = ()
    """STATUSTEXT prefixes of the checks it fails while it starts (its estimator not converged):
    said at INFO until it has started (``autopilot_health.Health.starting``), a warning after."""
    events_protocol: bool = False
    """The autopilot says why it refused to arm (and most else) in EVENT messages, described by
    events metadata it serves over MAVLink FTP (``events_channel.py``)."""
    booting_modes: tuple[str, ...] = ()
    """Modes in which the autopilot is still starting: parameters read then may still change (Rover
    sets its RC dead zones during start-up), so they are read again once it leaves them."""
    mapping_needs_params: bool = False
    """The MANUAL_CONTROL mapping depends on parameters read at connection (``mapper``): neutral is
    sent until they have been read."""
    thrust_modes: tuple[str, ...] = ("MANUAL",)
    """Modes in which the autopilot drives the thrusters from MANUAL_CONTROL as ``manual_control``
    maps it. In any other (HOLD after a failsafe, an AUTO mode, ACRO's rate control) the commanded
    thrust is not what the thrusters do: ``VehicleStatus.thrust_withheld`` says ``mode``."""

    @abstractmethod
    def manual_control(self, left: float, right: float) -> ManualControlAxes:
        """Normalised (L = port, R = starboard) in [-1, 1] -> MANUAL_CONTROL axes."""

    def neutral(self) -> ManualControlAxes:
        return self.manual_control(0.0, 0.0)

    def mapper(self, params: Mapping[str, float]) -> Callable[[float, float], ManualControlAxes]:
        """The (L, R) -> axes mapping for an autopilot with these parameters (the ones read at
        connection; absent ones are missing). Default: ``manual_control``, whatever the params."""
        return self.manual_control

    @abstractmethod
    def mode_names(self) -> tuple[str, ...]:
        """Seaway mode names this autopilot can be set to."""

    @abstractmethod
    def encode_mode(self, name: str) -> tuple[float, float, float]:
        """Seaway mode name -> MAV_CMD_DO_SET_MODE (param1, param2, param3); UnknownModeError if none."""

    @abstractmethod
    def decode_mode(self, base_mode: int, custom_mode: int) -> str:
        """HEARTBEAT base_mode/custom_mode -> Seaway mode name ('UNKNOWN(...)' if not recognised)."""

    def arm_params(self, arm: bool, force: bool) -> tuple[float, float]:
        """MAV_CMD_COMPONENT_ARM_DISARM (param1, param2)."""
        if not force:
            return (1.0 if arm else 0.0, 0.0)
        return (1.0, float(self.force_arm_magic)) if arm else (0.0, float(self.force_disarm_magic))

    def decode_param(self, value: float, param_type: int) -> float:
        return decode_param_value(value, param_type)

    @abstractmethod
    def assess_failsafe(self, params: dict[str, float], our_sysid: int,
                        rc_receiver: RcReceiver = "unknown") -> FailsafeAssessment:
        """Judge the parameters read (absent ones are missing from ``params``; renamed ones under
        their ``param_alternatives`` key)."""


def clamp_int(value: float, lo: int, hi: int) -> int:
    """Round half away from zero, then clamp: the axis value on the wire."""
    rounded = int(value + 0.5) if value >= 0 else -int(-value + 0.5)
    return min(max(rounded, lo), hi)


# -- the registry ---------------------------------------------------------------------------------

AUTO = "auto"
"""The autopilot setting that takes the profile from the first autopilot HEARTBEAT."""

_REGISTERED: dict[str, Profile] = {}


def register(profile: Profile) -> Profile:
    """Add ``profile`` (once per name and per HEARTBEAT autopilot number); its module calls this."""
    if profile.name == AUTO or profile.name in _REGISTERED:
        raise ValueError(f"autopilot profile name {profile.name!r} is taken")
    for other in _REGISTERED.values():
        if other.mav_autopilot == profile.mav_autopilot:
            raise ValueError(f"{profile.name} and {other.name} both claim MAV_AUTOPILOT "
                             f"{profile.mav_autopilot}")
    _REGISTERED[profile.name] = profile
    return profile


def profiles() -> tuple[Profile, ...]:
    """Every registered profile, in registration order."""
    return tuple(_REGISTERED.values())


def names() -> tuple[str, ...]:
    """The registered autopilot names ('px4', 'ardupilot', ...)."""
    return tuple(_REGISTERED)


def by_name(name: str) -> Profile:
    """The profile registered as ``name``; ValueError naming the known ones otherwise."""
    try:
        return _REGISTERED[name]
    except KeyError:
        raise ValueError(f"unknown autopilot {name!r}; known: {', '.join(_REGISTERED)}") from None


def by_mav_autopilot(number: int) -> Profile | None:
    """The profile of a HEARTBEAT's ``autopilot`` field (MAV_AUTOPILOT), or None if none is."""
    for profile in _REGISTERED.values():
        if profile.mav_autopilot == number:
            return profile
    return None


def choices() -> tuple[str, ...]:
    """What the ``autopilot`` setting may be: ``auto``, then every registered name."""
    return (AUTO, *_REGISTERED)


def describe() -> str:
    """The registered autopilots with their MAV_AUTOPILOT numbers, for messages: 'px4 (12), ...'."""
    return ", ".join(f"{p.name} ({p.mav_autopilot})" for p in _REGISTERED.values())
