"""Why the autopilot took the vessel away from Seaway: the named cause behind a failsafe or a mode
change nobody in Seaway asked for (``VehicleStatus.hold_reason``).

The autopilot says it in four places, none of them alone enough:

* HEARTBEAT: the mode changed, and vehicle_io did not ask for it. With no failsafe said around it,
  someone else (a second ground station, the RC mode switch) changed it: ``gcs_mode_change``, if
  the vessel is armed (a disarmed one changing mode is one starting or back from a restart);
* SYS_STATUS: ``onboard_control_sensors_*`` bits going unhealthy (present and enabled, not
  healthy): RC receiver (radio loss), geofence (breach), battery. ArduPilot Rover says a fence
  breach nowhere else: it changes mode and writes its log, with no STATUSTEXT (Rover/fence.cpp);
* STATUSTEXT at warning or worse: ArduPilot's "Radio Failsafe", "GCS Failsafe" (``"%s Failsafe"``,
  Rover/failsafe.cpp), "Battery 1 is low 11.00V used 500 mAh" (AP_BattMonitor), "EKF failsafe";
* EVENT (PX4 1.13+, decoded by ``autopilot_events``): ``commander_failsafe_enter*`` whose cause
  argument reads "Manual control loss", "GCS connection loss", "Low/Critical/Emergency battery
  level"; ``commander_rc_lost``, ``commander_gcs_lost``; geofence violations from the health report.

The texts and the mode change come in either order within a second or so, so a cause said within
``CAUSE_WINDOW_S`` of an unasked mode change names it, and a named cause replaces a vaguer one
(``other``, ``gcs_mode_change``) said within that window. The cause stands until vehicle_io's own
mode request is accepted (the operator took the vessel back) while no health bit is still unhealthy,
or until the link is lost or the autopilot reboots (vehicle_io starts a new ``FailsafeCause``).

Pure: time comes in as monotonic nanoseconds.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from seaway.contract.messages import HoldReason

CAUSE_WINDOW_S = 3.0  # a failsafe said this close to an unasked mode change is its cause
WARNING_SEVERITY = 4  # MAV_SEVERITY_WARNING: texts at this level or worse may name a failsafe
EVENT_WARNING_LEVEL = 4  # events log level "warning" (autopilot_events.LOG_LEVELS)

# MAV_SYS_STATUS_SENSOR bits whose going unhealthy is a failsafe condition.
MAV_SYS_STATUS_SENSOR_RC_RECEIVER = 1 << 16
MAV_SYS_STATUS_GEOFENCE = 1 << 20
MAV_SYS_STATUS_SENSOR_BATTERY = 1 << 25
HEALTH_CAUSES: dict[int, HoldReason] = {
    MAV_SYS_STATUS_SENSOR_RC_RECEIVER: "radio_loss",
    MAV_SYS_STATUS_GEOFENCE: "fence",
    MAV_SYS_STATUS_SENSOR_BATTERY: "battery",
}
VAGUE: frozenset[HoldReason | None] = frozenset({None, "other", "gcs_mode_change"})


def classify_text(text: str) -> HoldReason | None:
    """The failsafe a STATUSTEXT or a decoded EVENT text names (None: none). Arming-check texts
    ("PreArm: ..."), "cleared" texts and PX4's causeless "Failsafe warning:" (sent while disarmed,
    its action only a warning) name no failsafe in force."""
    t = text.lower()
    if t.startswith(("prearm", "arm:")) or "cleared" in t or "regained" in t:
        return None
    if "battery" in t and any(w in t for w in ("low", "critical", "emergency", "failsafe")):
        return "battery"
    if "fence" in t and any(w in t for w in ("breach", "violation")) and "waypoint" not in t:
        return "fence"
    if ("radio" in t and "failsafe" in t) or "manual control los" in t or "rc lost" in t:
        return "radio_loss"
    if ("gcs" in t and ("failsafe" in t or "connection loss" in t)) or "ground control station lost" in t:
        return "gcs_link_loss"
    if "failsafe" in t and "failsafe warning" not in t:
        # PX4's "Failsafe warning: ..." (Action::Warn) takes no action: news only with a cause
        return "other"
    return None


def cleared_cause(text: str) -> HoldReason | None:
    """The failsafe a "<kind> Failsafe Cleared" text says had fired (ArduPilot Rover sends it, at
    INFO, when the condition ends: vehicle_io's HEARTBEATs reach it again, the receiver is back;
    the vessel stays in the failsafe's mode). None: the text says no such thing."""
    suffix = " cleared"
    if not text.lower().rstrip().endswith("failsafe" + suffix):
        return None
    return classify_text(text.rstrip()[: -len(suffix)])


@dataclass
class FailsafeCause:
    """The standing cause (``cause``, with the autopilot's words in ``detail``)."""

    cause: HoldReason | None = None
    detail: str = ""
    since_ns: int | None = None
    unhealthy: int = 0  # HEALTH_CAUSES bits unhealthy in the last SYS_STATUS
    _last_said: tuple[HoldReason, str, int] | None = field(default=None, repr=False)
    _health_seen: bool = False

    def said(self, cause: HoldReason | None, text: str, now_ns: int) -> bool:
        """The autopilot named ``cause`` (``classify_text``); True if the standing cause changed."""
        if cause is None:
            return False
        self._last_said = (cause, text, now_ns)
        return self._offer(cause, text, now_ns)

    def health(self, present: int, enabled: int, healthy: int, now_ns: int) -> bool:
        """SYS_STATUS sensor bits; a bit going unhealthy (not one unhealthy from the first message
        on: some autopilots report an RC receiver they never had) names its cause. True if the
        standing cause changed."""
        bad = 0
        for bit in HEALTH_CAUSES:
            if present & enabled & bit and not healthy & bit:
                bad |= bit
        newly = bad & ~self.unhealthy if self._health_seen else 0
        self.unhealthy, self._health_seen = bad, True
        changed = False
        for bit, cause in HEALTH_CAUSES.items():
            if newly & bit:
                changed |= self.said(cause, f"SYS_STATUS: {cause.replace('_', ' ')} unhealthy", now_ns)
        return changed

    def mode_changed(self, old: str, new: str, now_ns: int, armed: bool = True) -> bool:
        """The mode changed from ``old`` to ``new`` and vehicle_io did not ask for it: the cause said
        around it, else the failsafe still standing, else someone else, if the autopilot is
        ``armed``. True if the standing cause (or its detail) changed."""
        last = self._last_said
        window = round(CAUSE_WINDOW_S * 1e9)
        if last is not None and now_ns - last[2] <= window:
            return self._offer(last[0], f"{last[1]} (mode {old} -> {new})", now_ns)
        if self.cause is not None and self.cause != "gcs_mode_change":
            # A failsafe still standing moves on by itself (PX4 holds COM_FAIL_ACT_T, then
            # returns; it gives the mode back once the link is regained): its next step is not
            # someone else's doing, be the failsafe named or not ('other').
            self.detail = f"{self.detail.split(' (mode ')[0]} (mode {old} -> {new})"
            return True
        if not armed:
            # Nobody took a disarmed vessel from Seaway, which drives an armed one only: an
            # autopilot back from a restart within the link timeout says disarmed and the mode it
            # boots into (PX4: Hold) in one HEARTBEAT, and one starting settles into its own mode.
            return False
        return self._offer("gcs_mode_change", f"mode {old} -> {new}, not asked by Seaway", now_ns, force=True)

    def mode_changed_unheard(self, old: str, new: str, silent_s: float, now_ns: int) -> bool:
        """The link came back after ``silent_s`` of silence with the mode changed from ``old`` to
        ``new``, unasked: the autopilot said nothing vehicle_io heard (its failsafe text went out
        while the link was down), so the cause is a failsafe not named (``other``) until a text
        names it (``cleared``). True if the standing cause changed."""
        last = self._last_said
        if last is not None and now_ns - last[2] <= round(CAUSE_WINDOW_S * 1e9):
            return self._offer(last[0], f"{last[1]} (mode {old} -> {new})", now_ns)
        return self._offer("other", f"mode {old} -> {new} while vehicle_io heard nothing from the "
                           f"autopilot for {silent_s:.0f} s", now_ns, force=True)

    def cleared(self, cause: HoldReason | None, text: str, now_ns: int) -> bool:
        """The autopilot said its failsafe ``cause`` had fired and is over (``cleared_cause``): it
        names the hold that failsafe made if that is standing unnamed (or follows within the
        window). True if the standing cause changed."""
        if cause is None:
            return False
        self._last_said = (cause, text, now_ns)
        if self.cause is None or self.cause not in VAGUE:
            return False  # nothing unnamed standing: news of a failsafe already over
        return self._offer(cause, f"{text}: it fired while the link was down", now_ns)

    def own_mode_accepted(self) -> bool:
        """vehicle_io's own mode request was accepted: the cause is over unless a health bit still
        says it is not. True if the standing cause changed."""
        if self.cause is None or self.unhealthy & _bits_of(self.cause):
            return False
        self.cause, self.detail, self.since_ns = None, "", None
        return True

    def _offer(self, cause: HoldReason, text: str, now_ns: int, force: bool = False) -> bool:
        """Take ``cause`` if it is news: nothing standing, a forced mode change, or it names more
        than a vague cause said within the window."""
        if cause == self.cause:  # said again (ArduPilot repeats its battery text): no news
            self.detail = text
            return False
        recent = self.since_ns is not None and now_ns - self.since_ns <= round(CAUSE_WINDOW_S * 1e9)
        if not force and self.cause is not None and recent and (cause in VAGUE or self.cause not in VAGUE):
            return False
        if not force and cause in VAGUE and self.cause not in VAGUE:
            # PX4 names its battery failsafe ("Low battery level"), then says only "Failsafe
            # activated" when it acts on it, later: that is the same failsafe, not another one.
            return False
        self.cause, self.detail, self.since_ns = cause, text, now_ns
        return True


def _bits_of(cause: HoldReason) -> int:
    return sum(bit for bit, c in HEALTH_CAUSES.items() if c == cause)
