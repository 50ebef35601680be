"""Sensors and the vehicle's state (producer: vehicle_io, from the autopilot; the sim reaches the
bus through vehicle_io)."""

from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import BaseModel, ConfigDict, Field

from seaway.contract.messages.base import Message
from seaway.contract.units import in_range

GNSS_ALT_MIN_M, GNSS_ALT_MAX_M = -1_000.0, 100_000.0
"""Bounds of a fix's altitude [m]: below the Dead Sea's shore and the geoid's deepest dip together,
above anything a receiver on a surface vessel reports. An altitude past them is corruption, and
taken as the origin it would break the local frame (a 1e20 m origin rounds positions to 8 km)."""
MAX_GNSS_STD_M = 100.0
"""GNSS horizontal position std [m]: a fix worse than that is no fix (a simulated receiver is
bounded by it, and the estimator refuses a fix that reports more)."""
MAX_GNSS_RATE_HZ = 100.0
"""The most fixes a second a receiver gives [Hz] (RTK receivers: 20 to 50): a simulated receiver is
bounded by it, and a consumer may take fixes closer together than that as one sender's flood, not
as more information (each fix taken as independent, 2 s of 10 kHz fixes of 0.3 m would make a
filter sure of its position to 4 mm)."""
MAX_ATTITUDE_RATE_HZ = 250.0
"""The most attitudes a second an autopilot streams [Hz] (its attitude loop's rate): as
``MAX_GNSS_RATE_HZ``, for headings and yaw rates."""


class GnssFix(Message):
    """GNSS fix from the autopilot. WGS84 geodetic position; velocity over ground in NED."""

    SCHEMA: ClassVar[str] = "seaway.v1.GnssFix"
    lat_rad: float = Field(ge=-math.pi / 2, le=math.pi / 2, description="WGS84 latitude [rad]")
    lon_rad: float = Field(ge=-math.pi, le=math.pi, description="WGS84 longitude [rad]")
    alt_m: Annotated[float, in_range(GNSS_ALT_MIN_M, GNSS_ALT_MAX_M, "m")] = Field(
        ge=GNSS_ALT_MIN_M, le=GNSS_ALT_MAX_M,
        description="height above the WGS84 ellipsoid or MSL as the source says [m]")
    fix_type: int = Field(ge=0, le=8, description="MAVLink GPS_FIX_TYPE (0 none, 3 3D, 6 RTK fixed)")
    vel_n_mps: float | None = Field(default=None, description="velocity over ground, north [m/s]")
    vel_e_mps: float | None = Field(default=None, description="velocity over ground, east [m/s]")
    horizontal_std_m: float | None = Field(default=None, ge=0, description="1-sigma position [m]")
    satellites: int | None = Field(default=None, ge=0)


class Attitude(Message):
    """Vehicle attitude and body rates. Angles NED/FRD (Fossen), yaw = heading from north."""

    SCHEMA: ClassVar[str] = "seaway.v1.Attitude"
    roll_rad: float
    pitch_rad: float
    yaw_rad: float = Field(ge=-math.pi, le=math.pi, description="heading, clockwise from north [rad]")
    roll_rate_radps: float
    pitch_rate_radps: float
    yaw_rate_radps: float = Field(description="r, body z rate, positive clockwise from above [rad/s]")


class LocalPosition(Message):
    """The autopilot's own local position estimate (its NED origin, not necessarily ours)."""

    SCHEMA: ClassVar[str] = "seaway.v1.LocalPosition"
    x_m: float
    y_m: float
    z_m: float
    vx_mps: float
    vy_mps: float
    vz_mps: float


ThrustWithheld = Literal["no_link", "disarmed", "mode", "autopilot_config", "autopilot_unhealthy"]
THRUST_APPLIED_ANYWAY: frozenset[str] = frozenset({"autopilot_unhealthy"})
"""``ThrustWithheld`` values under which the autopilot still applies what is commanded: a mission
waits for them to clear, but a thrust commanded meanwhile moves the boat (the estimator predicts
with it)."""
HoldReason = Literal["gcs_mode_change", "battery", "fence", "radio_loss", "gcs_link_loss", "other"]
"""Why the autopilot took the vessel from Seaway (``VehicleStatus.hold_reason``): a mode change
nobody in Seaway asked for ('gcs_mode_change'), or the failsafe it named: 'battery', 'fence',
'radio_loss' (RC / manual control), 'gcs_link_loss' (its ground-station link), 'other' (a failsafe
it did not name, e.g. ArduPilot's EKF failsafe)."""
HOLD_REASON_TEXT: dict[str, str] = {
    "gcs_mode_change": "a mode change Seaway did not ask for (another ground station, the RC)",
    "battery": "the autopilot's battery failsafe",
    "fence": "the autopilot's geofence breach (its fence action took the vessel)",
    "radio_loss": "the autopilot's radio (RC) failsafe",
    "gcs_link_loss": "the autopilot's ground-station link failsafe",
    "other": "a failsafe the autopilot did not name",
}
"""Each HoldReason for a person (the mission's reason, the page)."""
"""Why the autopilot does not apply the commanded thrust (``VehicleStatus.thrust_withheld``)."""


AutopilotFenceState = Literal["uploading", "verified", "mismatch", "failed", "refused"]
"""Where the operating area stands as the autopilot's own fence (``AutopilotFence.state``)."""


class AutopilotFence(BaseModel):
    """The operating area as the autopilot's own fence (vehicle_io uploads it over MAVLink's
    mission protocol and sets the fence's parameters): 'uploading' (under way), 'verified' (read
    back: the items and the parameters are those meant), 'mismatch' (read back, and they differ:
    ``detail`` says where), 'failed' (the transfer got no answer or a refusal; retried), 'refused'
    (the area does not fit the autopilot, ``detail`` names the field; not retried until it
    changes)."""

    model_config = ConfigDict(extra="ignore", allow_inf_nan=False, frozen=True)
    state: AutopilotFenceState
    detail: str = Field(default="", max_length=2000)
    area_since_ns: int = Field(ge=0, description="ActiveArea.since_ns of the area it is")
    fence_items: int = Field(ge=0, description="fence items uploaded (vertices and circles)")
    rally_points: int = Field(ge=0)
    action: str = Field(default="", max_length=200,
                        description="the fence parameters set, e.g. 'FENCE_ACTION=2 (Hold)'")


class VehicleStatus(Message):
    """Link, arming, mode, failsafe and battery state of the autopilot as vehicle_io sees it."""

    SCHEMA: ClassVar[str] = "seaway.v1.VehicleStatus"
    autopilot: str = Field(description="'px4', 'ardupilot' or 'unknown'")
    link_ok: bool
    armed: bool
    mode: str = Field(description="autopilot mode name, e.g. 'MANUAL'")
    failsafe: str | None = Field(default=None, description="active failsafe, e.g. 'thrust_stale'")
    battery_voltage_v: float | None = None
    battery_remaining_frac: float | None = Field(default=None, ge=0, le=1)
    heartbeat_age_s: float | None = Field(default=None, ge=0)
    rates_hz: dict[str, float] = Field(default_factory=dict, description="received MAVLink rates")
    dropped_messages: int = Field(default=0, ge=0, description="malformed MAVLink messages dropped")
    refused_messages: dict[str, int] = Field(
        default_factory=dict,
        description="MAVLink messages refused, by reason: 'foreign_source' (not the autopilot the "
                    "link is locked to), 'unsigned', 'bad_signature', 'replayed' (signing on)")
    refused_thrust: dict[str, int] = Field(
        default_factory=dict,
        description="ThrustCommands refused before the autopilot, by reason: 'absurd' (beyond twice "
                    "the vessel's thrust bounds), 'stamp_ahead', 'stamp_behind' (seaway.runtime.stamps)")
    autopilot_loss_failsafe: Literal["stops", "takes_over", "none", "unknown"] | None = Field(
        default=None,
        description="what the autopilot does if vehicle_io stops streaming commands, judged from its "
                    "parameters at connection; None until they have been read")
    autopilot_loss_failsafe_summary: str = Field(
        default="", description="the parameters and the action behind that verdict, one line")
    telemetry_rates_short: dict[str, float] | None = Field(
        default=None,
        description="each telemetry message vehicle_io asked for that arrives below its requested "
                    "rate, with the rate measured [Hz]: from the rate check at connection, after a "
                    "reboot or a drop, and kept up to date after it (cleared when the rates "
                    "recover); {} all arrive at their rates; None not checked (yet, or the "
                    "autopilot is not asked)")
    hold_reason: HoldReason | None = Field(
        default=None,
        description="why the autopilot took the vessel from Seaway (HoldReason), decoded from its "
                    "HEARTBEAT, SYS_STATUS, STATUSTEXT and EVENTs; stands until Seaway's own mode "
                    "request is accepted with no failsafe condition left; None: none")
    hold_reason_detail: str = Field(
        default="", description="the autopilot's own words (or the bit) behind hold_reason")
    thrust_withheld: ThrustWithheld | None = Field(
        default=None,
        description="why the commanded thrust does not reach the thrusters now, whatever the "
                    "controller commands: 'no_link' (no autopilot), 'disarmed', 'mode' (a mode in "
                    "which manual control does not drive the thrusters, e.g. HOLD after a "
                    "failsafe), 'autopilot_config' (vehicle_io sends neutral only), "
                    "'autopilot_unhealthy' (armed and in a thrust mode, but the autopilot says it is "
                    "not fit to start a mission: its estimator not using GNSS, a critical status; "
                    "what, in autopilot_unhealthy_detail); None: it does")
    autopilot_unhealthy_detail: str = Field(
        default="", description="what the autopilot lacks to be healthy, in its own terms (the "
                                "HEARTBEAT system_status, SYS_STATUS sensor bits, its estimator's "
                                "flags); '' healthy, or not said")
    failsafe_latched: HoldReason | None = Field(
        default=None,
        description="a failsafe the autopilot still stands in (HoldReason), whatever its mode: its "
                    "health bit for it still unhealthy, or its battery flag low or worse (ArduPilot "
                    "keeps a battery failsafe until reboot); a mission is not resumed onto it; None: none")
    failsafe_latched_detail: str = Field(
        default="", description="the autopilot's words (or the bit) behind failsafe_latched")
    autopilot_fence: AutopilotFence | None = Field(
        default=None, description="the operating area as the autopilot's own fence; None: no "
                                  "area heard, no origin, or not uploaded (autopilot_fence off)")


BatterySource = Literal["autopilot", "sim"]
BatteryLevel = Literal["ok", "low", "critical", "emergency", "failed", "unhealthy", "charging"]
"""The autopilot's own judgement of its battery: MAVLink MAV_BATTERY_CHARGE_STATE (BATTERY_STATUS
``charge_state``), or what it said in STATUSTEXT ("Battery 1 is low"), whichever is worse."""
"""Who measured a ``BatteryState``: the autopilot's battery monitor (through vehicle_io; also the
MAVLink-speaking simulator), or the lockstep simulator itself."""


class BatteryState(Message):
    """The propulsion battery as the autopilot (or the lockstep simulator) reports it, in SI units.

    Measured figures (voltage, current, energy drawn) are the autopilot's; the energies it does not
    report are completed from the vessel file's ``[battery]`` (``seaway.vessel.battery``):
    ``remaining_j`` = remaining fraction x usable energy when the autopilot gives a fraction, else
    usable energy - energy drawn. None: neither the autopilot nor the vessel file says.
    """

    SCHEMA: ClassVar[str] = "seaway.v1.BatteryState"
    source: BatterySource
    voltage_v: float | None = Field(default=None, ge=0, description="pack voltage [V]")
    current_a: float | None = Field(default=None, description="current drawn [A], positive discharging")
    power_w: float | None = Field(default=None, description="power drawn [W]: voltage x current "
                                  "where the autopilot measures both")
    consumed_j: float | None = Field(default=None, ge=0, description="energy drawn since the pack "
                                     "was full (or the autopilot's count started) [J]")
    remaining_j: float | None = Field(default=None, ge=0, description="usable energy left [J]")
    remaining_frac: float | None = Field(default=None, ge=0, le=1,
                                         description="remaining_j over the usable energy")
    capacity_j: float | None = Field(default=None, gt=0, description="usable energy full to empty [J]")
    reserve_j: float | None = Field(default=None, ge=0, description="what a return home must leave [J]")
    autopilot_level: BatteryLevel | None = Field(
        default=None,
        description="the autopilot's own low/critical flag (BatteryLevel): BATTERY_STATUS "
                    "charge_state, raised by its battery STATUSTEXT; None: it says nothing")
    autopilot_level_detail: str = Field(
        default="", description="the autopilot's battery text behind autopilot_level, if any")
