"""vehicle_io's configuration: defaults, a file (TOML or JSON; unknown fields are errors), flags.

Every field has a safe default, so a file is needed only to change something. ``--config`` takes a
path, or the name of a file shipped in ``services/vehicle_io/config/`` (``ardupilot-sitl``,
``px4-sitl``, ``boat-serial``, ...: ``config_path``). The fields marked ``Flag`` are also flags
(``--mavlink``, ``--autopilot``, ``--thrust-timeout``, ``--signing-key-file``) that override the
file (``seaway.runtime.config``). The vessel file (thruster limits, dead zone) is a run-wide fact:
it comes from the run description (``seaway.runtime.run``), not from here.
"""

from __future__ import annotations

import ipaddress
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator
from seaway.contract.config import ConfigModel, named_file
from seaway.mavlink.signing import read_key
from seaway.runtime.config import Flag

from seaway_vehicle_io import profile, rates
from seaway_vehicle_io.signing import (
    DEFAULT_LINK_ID,
    SigningSetup,
    TimestampFileError,
    read_timestamp,
    timestamp_path,
)

AUTOPILOT_CHOICES: tuple[str, ...] = profile.choices()
"""``auto`` and every registered autopilot profile's name (``profile.py``)."""
CONFIG_DIR = Path(__file__).resolve().parents[2] / "config"
"""The shipped configs and autopilot parameter files (``ardupilot-boat.parm``, ``px4-boat.params``)."""


def config_path(name_or_path: str) -> Path:
    """A config's path, or ``CONFIG_DIR/<name>.toml``; ConfigError listing the shipped names."""
    return named_file(CONFIG_DIR, name_or_path, "vehicle_io config", "services/vehicle_io/config/")


AutopilotChoice = Literal[AUTOPILOT_CHOICES]  # type: ignore[valid-type]  # built from the registry


SOURCE_SYSTEM = 245
"""vehicle_io's default MAVLink system id: one no ground station uses by default (QGroundControl,
Mission Planner and MAVProxy all speak as 255), so that a second ground station is told apart.
Its component is MAV_COMP_ID_ONBOARD_COMPUTER (191)."""
SOURCE_COMPONENT = 191  # MAV_COMP_ID_ONBOARD_COMPUTER

# Upper bounds of the two safety timeouts: a longer one keeps the last thrust running long after
# the controller goes silent, or reports a silent autopilot lost too late.
MAX_THRUST_TIMEOUT_S = 2.0
"""The thrust watchdog's longest timeout [s]: 20 control periods of 0.1 s, several times the default
0.3 s; at a cruise speed of 2 m/s already 4 m run on the last command."""
MAX_HEARTBEAT_TIMEOUT_S = 30.0
"""The longest wait for an autopilot HEARTBEAT before the link counts as lost [s]: autopilots send it
at 1 Hz, and an autopilot rebooting (3-15 s) is back within it."""


class VehicleIoConfig(ConfigModel):
    """How vehicle_io talks to the autopilot and how it guards the thrusters."""

    mavlink: Annotated[str, Flag()] = Field(
        default="udpout:127.0.0.1:14580",
        description="pymavlink connection URL: udpin:HOST:PORT (listen), udpout:HOST:PORT (send "
                    "first), tcp:HOST:PORT, or a serial device /dev/ttyX (baud from 'baud')",
    )
    baud: int = Field(default=57600, gt=0, description="serial baud rate (serial URLs only)")
    bind_host: str | None = Field(
        default=None,
        description="udpout: the local address our socket listens on for the autopilot's answers. "
                    "None: 127.0.0.1 when the autopilot's address is loopback, else 0.0.0.0 (every "
                    "interface). udpin listens where its URL says",
    )
    autopilot: Annotated[AutopilotChoice, Flag()] = Field(
        default=profile.AUTO,
        description=f"expected autopilot, one of {', '.join(AUTOPILOT_CHOICES)}; "
                    f"'{profile.AUTO}' takes it from the HEARTBEAT. A HEARTBEAT that contradicts a "
                    "named autopilot is ignored (never commanded)",
    )
    source_system: int = Field(
        default=SOURCE_SYSTEM, ge=1, le=255,
        description="our MAVLink system id; not 255, every ground station's default, so the "
                    "autopilot (and its log) tells vehicle_io from a ground station. ArduPilot "
                    "accepts MANUAL_CONTROL only from MAV_GCS_SYSID (SYSID_MYGCS before 4.7): set "
                    "it to this (ardupilot-boat.parm does)",
    )
    source_component: int = Field(
        default=SOURCE_COMPONENT, ge=1, le=255,
        description="our component id (191 MAV_COMP_ID_ONBOARD_COMPUTER)"
    )
    target_system: int | None = Field(
        default=None, ge=1, le=255,
        description="autopilot system id to command; None learns it from the first autopilot "
                    "HEARTBEAT after start or after a link loss",
    )
    heartbeat_timeout_s: float = Field(
        default=3.0, gt=0, le=MAX_HEARTBEAT_TIMEOUT_S,
        description="no autopilot HEARTBEAT for this long = link lost [s]; at most 30 s: an "
                    "autopilot silent for longer (a stalled autopilot, a cut cable) must be "
                    "reported lost, and an autopilot reboot (the longest wait, 3-15 s) fits",
    )
    heartbeat_period_s: float = Field(default=1.0, gt=0, description="our HEARTBEAT period [s]")
    thrust_timeout_s: Annotated[float, Flag("--thrust-timeout", metavar="S")] = Field(
        default=0.3, gt=0, le=MAX_THRUST_TIMEOUT_S,
        description="watchdog: no ThrustCommand received for this long -> neutral thrust [s]; at "
                    "most 2 s: the last thrust keeps driving the vessel for this long after the "
                    "controller goes silent (20 of its 0.1 s periods; metres at cruise speed)",
    )
    thrust_max_age_s: float = Field(
        default=1.0, gt=0, le=10.0,
        description="a ThrustCommand whose stamp (its state's time) is older than this on our wall "
                    "clock is refused, as one stamped over 1 s ahead of it is (seaway.runtime.stamps); "
                    "the controller acts on states up to 0.5 s old (--max-state-age-s), so 1 s leaves "
                    "a solve and the transport. A zero-thrust command is taken whatever its stamp [s]",
    )
    manual_control_rate_hz: float = Field(
        default=20.0, ge=5.0, le=100.0,
        description="MANUAL_CONTROL stream rate; >= 5 Hz keeps PX4 (COM_RC_LOSS_T 0.5 s) and "
                    "ArduPilot (500 ms radio failsafe) from declaring manual control lost",
    )
    status_rate_hz: float = Field(default=2.0, gt=0, le=50, description="VehicleStatus rate [Hz]")
    command_ack_timeout_s: float = Field(
        default=1.0, gt=0, description="wait this long for COMMAND_ACK before resending [s]"
    )
    command_attempts: int = Field(
        default=3, ge=1, le=10, description="COMMAND_LONG transmissions before giving up"
    )
    time_offset_window_s: float = Field(
        default=10.0, gt=0,
        description="window of the min filter that maps autopilot boot time to wall time [s]",
    )
    time_confirm_s: float = Field(
        default=1.0, gt=0, le=10.0,
        description="time_boot_ms more than 1 s away from the offset estimate, in every message for "
                    "this long, restarts the estimate (an autopilot reboot the link did not show, "
                    "or a wrong estimate); one late or corrupt message never does [s]",
    )
    gps_raw_max_age_s: float = Field(
        default=3.0, gt=0, description="GPS_RAW_INT older than this no longer qualifies a fix [s]"
    )
    fix_type_without_gps_raw: int = Field(
        default=0, ge=0, le=8,
        description="GnssFix.fix_type when no recent GPS_RAW_INT exists (0 = unknown/no GPS: the "
                    "position is the autopilot's fused estimate, its quality unknown)",
    )
    check_failsafe_params: bool = Field(
        default=True, description="read the autopilot's loss-failsafe parameters after connecting"
    )
    param_timeout_s: float = Field(
        default=1.0, gt=0, description="wait this long for each PARAM_VALUE before asking again [s]"
    )
    param_attempts: int = Field(default=3, ge=1, le=10, description="PARAM_REQUEST_READ "
                                "transmissions of one parameter before giving up")
    autopilot_fence: bool = Field(
        default=True,
        description="upload the operating area the controller enforces to the autopilot as its own fence, "
                    "with its fence action Hold, and read it back (fence_sync.py)",
    )
    fence_timeout_s: float = Field(
        default=1.5, gt=0, le=30,
        description="fence upload/download: wait this long for each answer before sending again [s]",
    )
    fence_attempts: int = Field(default=5, ge=1, le=20,
                                description="fence upload/download: sends of one message before "
                                            "the transfer fails (and is retried 10 s later)")
    message_rates_hz: dict[str, float] = Field(
        default_factory=lambda: dict(rates.DEFAULT_RATES_HZ),
        description="telemetry rates asked of the autopilot at each connection (ArduPilot: "
                    "SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM as the fallback) and checked at "
                    f"start-up (>= {rates.TOLERANCE:.0%} of each); message name -> Hz. Names: "
                    f"{', '.join(sorted(rates.TELEMETRY))}; empty: ask for nothing",
    )
    rc_receiver: profile.RcReceiver = Field(
        default="unknown",
        description="is an RC receiver wired to the autopilot? 'absent', 'present' or 'unknown'. "
                    "MAVLink cannot tell, and it decides what ArduPilot does when vehicle_io dies: "
                    "without one its radio failsafe stops the thrusters 0.5 s after our last "
                    "command; with one the last command is held for RC_OVERRIDE_TIME, then the "
                    "sticks drive",
    )
    statustext_grace_s: float = Field(
        default=1.5, ge=0, le=5,
        description="after a refused arm, wait up to this long for the autopilot to say why "
                    "(ArduPilot's STATUSTEXT comes with or just after the ACK; PX4's arming-check "
                    "report about 1 s after it); the reply goes as soon as the reason is complete "
                    "[s]",
    )
    autopilot_events: bool = Field(
        default=True,
        description="at each connection to an autopilot that speaks the MAVLink events protocol "
                    "(PX4), fetch its events metadata over MAVLink FTP and decode its EVENTs: "
                    "its reasons for refusing to arm reach the reply and the log",
    )
    forward_thrust_only_when_armed: bool = Field(
        default=True,
        description="send neutral while the autopilot reports disarmed, so arming never starts "
                    "the thrusters at a demand computed before it",
    )
    signing_key_file: Annotated[Path | None, Flag(metavar="PATH")] = Field(
        default=None,
        description="MAVLink 2 signing: a file holding the 32-byte secret key as 64 hex characters "
                    "(a relative path is from the working directory). Set: everything we send is "
                    "signed, and unsigned or wrongly signed incoming messages are refused "
                    "(counted). None: no signing. "
                    "`seaway signing new PATH` writes one, `seaway signing push` gives it to the "
                    "autopilot",
    )
    signing_link_id: int = Field(
        default=DEFAULT_LINK_ID, ge=0, le=255,
        description="MAVLink signing link id of our frames; two senders sharing a key and ids must "
                    "differ in it",
    )
    signing_timestamp_file: Path | None = Field(
        default=None,
        description="where our signing timestamp is kept across restarts, so that it never goes "
                    "back (written every 10 s and at exit, mode 0600). None: the key file's path "
                    "with '.timestamp' appended",
    )

    @field_validator("signing_key_file")
    @classmethod
    def _check_key_file(cls, path: Path | None) -> Path | None:
        if path is not None:
            read_key(path)  # KeyFileError (a ValueError) names the file and what it must hold
        return path

    @model_validator(mode="after")
    def _check_timestamp_file(self) -> VehicleIoConfig:
        if self.signing_key_file is not None:
            try:
                read_timestamp(self.timestamp_file())
            except TimestampFileError as err:
                raise ValueError(f"signing_timestamp_file: {err}") from None
        return self

    def timestamp_file(self) -> Path:
        """Where the signing timestamp is kept (only meaningful with a key file)."""
        if self.signing_timestamp_file is not None:
            return self.signing_timestamp_file
        return timestamp_path(self.signing_key_file or Path("mavlink.key"))

    def signing_setup(self) -> SigningSetup | None:
        """The signing this config asks for (None: none), the key read now. KeyFileError."""
        if self.signing_key_file is None:
            return None
        return SigningSetup(read_key(self.signing_key_file), self.signing_link_id,
                            self.timestamp_file())

    @field_validator("bind_host")
    @classmethod
    def _check_bind_host(cls, value: str | None) -> str | None:
        if value is not None:
            try:
                ipaddress.ip_address(value)
            except ValueError:
                raise ValueError(f"bind_host {value!r} is not an IP address (e.g. 127.0.0.1, "
                                 "0.0.0.0, or the address of one interface)") from None
        return value

    @field_validator("message_rates_hz")
    @classmethod
    def _check_rates(cls, value: dict[str, float]) -> dict[str, float]:
        rates.plan(value)  # ValueError names the message or the rate and what is allowed
        return value

    @model_validator(mode="after")
    def _check_timing(self) -> VehicleIoConfig:
        period = 1.0 / self.manual_control_rate_hz
        if self.thrust_timeout_s < period:
            raise ValueError(
                f"thrust_timeout_s ({self.thrust_timeout_s}) must be at least one MANUAL_CONTROL "
                f"period ({period:.3f} s)"
            )
        if self.heartbeat_timeout_s <= 1.0:
            # PX4 and ArduPilot send HEARTBEAT at 1 Hz (docs/autopilots.md A.5): a shorter
            # timeout would declare the link lost between two healthy heartbeats.
            raise ValueError("heartbeat_timeout_s must exceed the autopilots' 1 s HEARTBEAT period")
        return self
