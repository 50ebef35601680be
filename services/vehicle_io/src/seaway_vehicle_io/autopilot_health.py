"""Is the autopilot fit to start a mission, and is it still standing in a failsafe?

Health (``Health.problem``): what the autopilot lacks, in its own terms, or None. A mission waits
for it (``ThrustWithheld`` 'autopilot_unhealthy'), because an autopilot can be armed and in a thrust
mode before it is ready: ArduPilot Rover arms in MANUAL while its EKF has not yet fused GPS, and
reports MAV_STATE_CRITICAL while a failsafe of its own is triggered. It is unhealthy while any of:

* HEARTBEAT ``system_status`` is CRITICAL or EMERGENCY (ArduPilot Rover: a failsafe triggered or
  its EKF failsafe, ``GCS_MAVLINK_Rover::vehicle_system_status``; PX4: a failsafe in force);
* SYS_STATUS says a sensor the position fix depends on is present and enabled but not healthy:
  AHRS and GPS on both firmwares, and on PX4 the local position estimate (its health report's
  ``local_position_estimate``, sent as the XY position control bit; ArduPilot uses that bit for
  its position controller, so it is not read there);
* the estimator's own flags (ArduPilot EKF_STATUS_REPORT, PX4 ESTIMATOR_STATUS, when sent) lack an
  absolute horizontal position (``*_POS_HORIZ_ABS``: not using GNSS), or say it is uninitialised.

What is not said is not a problem: an autopilot that sends no estimator report is judged on the
rest. Arming checks are the autopilot's own: a disarmed vehicle is withheld as 'disarmed' first.

Starting (``Health.starting``): an autopilot just booted is not healthy yet, and says so for tens of
seconds (ArduPilot Rover SITL: 40 s from its first HEARTBEAT to an EKF using GPS; a real receiver's
cold start takes longer), refusing to arm meanwhile. What it lacks then is the expected state of a
start, shown in the status, not a warning. It is starting until it has first been healthy for
``READY_SETTLE_S`` (a SYS_STATUS and its estimator's report heard, ``healthy_now``), for at most
``START_GRACE_S`` from the link coming up (or the reboot seen) and while its own clock
(``time_boot_ms``) says it booted less than that ago: one restarted vehicle_io meets an autopilot
up for long, and what that one lacks is a warning at once. An absurd ``time_boot_ms`` can only end
the start earlier.

Latched (``latched_failsafe``): the failsafe the autopilot still stands in, whatever its mode, so
that a mission is not resumed onto it: a failsafe health bit still unhealthy
(``failsafe_cause.HEALTH_CAUSES``: ArduPilot keeps its battery bit unhealthy while
``AP_BattMonitor::has_failsafed()``, which holds until reboot), or its battery flag low or worse
(BATTERY_STATUS ``charge_state``; PX4's battery warning only rises; ArduPilot's battery text, kept).

Pure: each message replaces what it says; the monotonic time [ns] is passed in.
"""

from __future__ import annotations

from dataclasses import dataclass

from seaway.contract.messages import BatteryLevel, HoldReason

from seaway_vehicle_io.failsafe_cause import HEALTH_CAUSES
from seaway_vehicle_io.mav import mavlink

MAV_STATE_NAMES = {mavlink.MAV_STATE_CRITICAL: "CRITICAL", mavlink.MAV_STATE_EMERGENCY: "EMERGENCY"}
"""HEARTBEAT system_status values that make the autopilot unhealthy."""

SENSOR_NAMES_ALL = {mavlink.MAV_SYS_STATUS_AHRS: "attitude/heading estimate (AHRS)",
                    mavlink.MAV_SYS_STATUS_SENSOR_GPS: "GPS"}
SENSOR_NAMES_PX4 = SENSOR_NAMES_ALL | {
    mavlink.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL: "local position estimate"}

EST_POS_HORIZ_ABS = 16  # EKF_POS_HORIZ_ABS = ESTIMATOR_POS_HORIZ_ABS: an absolute (GNSS) position
EST_UNINITIALIZED = 1024  # EKF_UNINITIALIZED / ESTIMATOR_UNINITIALIZED
START_GRACE_S = 120.0
"""How long an autopilot that has not been healthy since it came up counts as starting [s]."""
READY_SETTLE_S = 5.0
"""Healthy this long, as sampled by each status, ends a start [s]."""
ESTIMATOR_REPORT_WAIT_S = 10.0
"""Healthy needs its estimator's report, unless none came within this long of it coming up [s]."""
BAD_BATTERY_LEVELS: frozenset[BatteryLevel | None] = frozenset(
    {"low", "critical", "emergency", "failed", "unhealthy"})


@dataclass
class Health:
    """The autopilot's health from its last HEARTBEAT, SYS_STATUS and estimator report."""

    px4: bool = False  # which SYS_STATUS bits to read (see the module docstring)
    system_status: int | None = None
    sensors_bad: tuple[str, ...] = ()
    estimator: str = ""  # what the estimator report lacks ('' fine, or not sent)
    estimator_heard: bool = False  # an estimator report came
    failsafe_bits: int = 0  # HEALTH_CAUSES bits unhealthy now that were not so from the start
    _from_start: int | None = None  # those unhealthy from the first SYS_STATUS on, until healthy
    since_mono_ns: int = 0  # the link came up, or the autopilot was seen to reboot [monotonic ns]
    uptime_ms: int | None = None  # its time since boot, from the last message stamped with it
    ready: bool = False  # healthy for READY_SETTLE_S at least once since ``since_mono_ns``
    _healthy_since_ns: int | None = None  # healthy at every ``healthy_now`` since [monotonic ns]

    def booted_ms(self, time_boot_ms: int) -> None:
        """The autopilot's ``time_boot_ms`` in a message taken for true (its stamp accepted)."""
        self.uptime_ms = int(time_boot_ms)

    def healthy_now(self, now_ns: int) -> bool:
        """Whether it is healthy now: a SYS_STATUS has told, and its estimator's report, or none
        came within ``ESTIMATOR_REPORT_WAIT_S`` (ArduPilot starts sending EKF_STATUS_REPORT seconds
        after its first SYS_STATUS, which says nothing of the EKF). Healthy at every call over
        ``READY_SETTLE_S`` marks it ``ready`` (PX4 SITL: healthy for 1 s, its local position
        unhealthy for 2 s, then healthy for good)."""
        waited = now_ns - self.since_mono_ns >= ESTIMATOR_REPORT_WAIT_S * 1e9
        healthy = (self._from_start is not None and (self.estimator_heard or waited)
                   and self.problem() is None)
        if not healthy:
            self._healthy_since_ns = None
        elif self._healthy_since_ns is None:
            self._healthy_since_ns = now_ns
        self.ready = self.ready or (self._healthy_since_ns is not None
                                    and now_ns - self._healthy_since_ns >= READY_SETTLE_S * 1e9)
        return healthy

    def starting(self, now_ns: int) -> bool:
        """Still starting at ``now_ns`` (the module docstring): not yet healthy since it came up,
        which was less than ``START_GRACE_S`` ago by our clock and by its own."""
        self.healthy_now(now_ns)
        if self.ready or now_ns - self.since_mono_ns >= START_GRACE_S * 1e9:
            return False
        return self.uptime_ms is None or self.uptime_ms < START_GRACE_S * 1e3

    def heartbeat(self, system_status: int) -> None:
        self.system_status = int(system_status)

    def sys_status(self, present: int, enabled: int, healthy: int) -> None:
        names = SENSOR_NAMES_PX4 if self.px4 else SENSOR_NAMES_ALL
        self.sensors_bad = tuple(name for bit, name in names.items()
                                 if present & enabled & bit and not healthy & bit)
        bad = sum(bit for bit in HEALTH_CAUSES if present & enabled & bit and not healthy & bit)
        # A bit unhealthy from the first message on is no failsafe (some autopilots report an RC
        # receiver they never had), as failsafe_cause judges it; once healthy it counts.
        self._from_start = bad if self._from_start is None else self._from_start & bad
        self.failsafe_bits = bad & ~self._from_start

    def estimator_flags(self, message: str, flags: int) -> None:
        """EKF_STATUS_REPORT (ArduPilot) or ESTIMATOR_STATUS (PX4) ``flags``."""
        self.estimator_heard = True
        if flags & EST_UNINITIALIZED:
            self.estimator = f"its estimator not initialised ({message} flags 0x{flags:x})"
        elif not flags & EST_POS_HORIZ_ABS:
            self.estimator = f"its estimator not using GNSS yet ({message} flags 0x{flags:x})"
        else:
            self.estimator = ""

    def problem(self) -> str | None:
        """What the autopilot lacks to start a mission, for a person; None: nothing said."""
        said = []
        if self.system_status in MAV_STATE_NAMES:
            said.append(f"status {MAV_STATE_NAMES[self.system_status]} (HEARTBEAT)")
        if self.estimator:
            said.append(self.estimator)
        if self.sensors_bad:
            said.append(f"{', '.join(self.sensors_bad)} unhealthy (SYS_STATUS)")
        return "the autopilot is not healthy: " + "; ".join(said) if said else None


def latched_failsafe(unhealthy_bits: int, battery_level: BatteryLevel | None,
                     battery_detail: str) -> tuple[HoldReason, str] | None:
    """The failsafe the autopilot still stands in and what says so (None: none): a failsafe health
    bit unhealthy now (``unhealthy_bits``, ``Health.failsafe_bits``), or its battery level
    (``battery_level``, with its text ``battery_detail`` if any) low or worse."""
    for bit, cause in HEALTH_CAUSES.items():
        if unhealthy_bits & bit:
            return cause, f"SYS_STATUS: {cause.replace('_', ' ')} still unhealthy"
    if battery_level in BAD_BATTERY_LEVELS:
        return "battery", battery_detail or f"battery {battery_level} (BATTERY_STATUS charge_state)"
    return None
