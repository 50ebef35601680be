"""vehicle_io's pure core: MAVLink messages, thrust commands and time in; messages to send out.

Nothing here opens a socket, reads a clock or touches the bus. The service loop (``service.py``)
feeds it:

* ``on_mavlink(msg, now, address)`` for every decoded MAVLink message (the one receive loop), with
  the peer address it came from, and ``on_refused_datagrams`` for what the link refused unread;
* ``on_thrust(cmd, now)`` for every ThrustCommand from the bus;
* ``tick(now)`` whenever ``next_wake_ns(now)`` says something is due;

and performs the returned outputs in order: ``Send*`` to the autopilot, ``Publish`` to the bus.
Every method is called under one lock by the loop, so the core needs no locking of its own.

Time: ``Now.wall_ns`` (Unix epoch) stamps messages; ``Now.mono_ns`` (monotonic) measures every
timeout, so an NTP step never trips or delays a watchdog.

Authority: the first valid autopilot HEARTBEAT locks the link to its source (system id, component
id, peer address); from then on a message from any other address or system id is refused and
counted (``authority.Refusals``), never interpreted: a forged "disarmed, HOLD" HEARTBEAT from the
autopilot's own system id but another socket changes nothing. With a signing key, every message
must also carry a valid MAVLink 2 signature (``seaway.vessel.mavlink_signing``). A link loss
releases the lock (``LockPeer(None)``) and the next autopilot HEARTBEAT locks again, within what
``SourcePolicy`` allows.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Any, ClassVar

from seaway.contract import keys
from seaway.contract.messages import (
    BatteryLevel,
    HoldReason,
    Message,
    ThrustCommand,
    ThrustWithheld,
    VehicleStatus,
)
from seaway.mavlink.signing import ACCEPTED, SignatureVerifier, signing_timestamp
from seaway.runtime.ratelog import RateLimitedLog
from seaway.runtime.stamps import STAMP_LOG_EVERY_S, StampBounds, StampGate
from seaway.vessel.battery import BatteryParams
from seaway.vessel.thrusters import absurd_thrust

from seaway_vehicle_io import profile as profiles
from seaway_vehicle_io import rates as telemetry_rates
from seaway_vehicle_io.authority import (
    FOREIGN_SOURCE,
    Address,
    Refusals,
    Source,
    SourcePolicy,
    address_key,
)
from seaway_vehicle_io.autopilot_health import Health, latched_failsafe
from seaway_vehicle_io.commands import (
    COMMAND_NAMES,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_SET_MODE,
    CommandTracker,
)
from seaway_vehicle_io.component_metadata import (
    MAV_CMD_REQUEST_MESSAGE,
    SendFileTransfer,
    SendRequestMessage,
)
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.conversions import (
    BatteryReading,
    FieldError,
    GpsQuality,
    NoDataError,
    attitude_from_attitude,
    battery_from_battery_status,
    battery_from_sys_status,
    battery_level_from_text,
    battery_state,
    gnss_from_global_position_int,
    gps_quality_from_gps_raw_int,
    local_position_from_local_position_ned,
    worse_level,
)
from seaway_vehicle_io.events_channel import EventsChannel, SendRequestEvent
from seaway_vehicle_io.failsafe_cause import (
    EVENT_WARNING_LEVEL,
    WARNING_SEVERITY,
    FailsafeCause,
    classify_text,
    cleared_cause,
)
from seaway_vehicle_io.fence_sync import FenceOutput, FenceSync
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import TRANSFER_MESSAGES
from seaway_vehicle_io.profile import FailsafeAssessment, ManualControlAxes, Profile
from seaway_vehicle_io.rates import MAV_CMD_SET_MESSAGE_INTERVAL, RateCheck, RateWatch
from seaway_vehicle_io.statustext import StatusTexts, matching
from seaway_vehicle_io.thrust import ThrusterLimits, normalise_pair
from seaway_vehicle_io.timesync import BootTimeOffset
from seaway_vehicle_io.watchdog import FAILSAFE_THRUST_STALE, ThrustWatchdog

log = logging.getLogger("seaway.vehicle_io")

MAV_MODE_FLAG_SAFETY_ARMED = 128
# HEARTBEAT.type values that are not a vehicle (GCS, onboard controller, gimbal, ADSB, camera...).
NON_VEHICLE_TYPES = frozenset({6, 18, 26, 27, 30, 31})

FAILSAFE_AUTOPILOT_CONFIG = "autopilot_config"
UNKNOWN_MESSAGES = "UNKNOWN"  # counts[] key of messages the dialect does not define

LOG_EVERY_S = 5.0  # at most one log line per (message, field) per 5 s
RATE_WINDOW_S = 2.0  # receive rates are counted over windows of at least this length


@dataclass(frozen=True)
class Now:
    """The two clocks the loop passes in [ns]."""

    wall_ns: int
    mono_ns: int


# -- outputs ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SendHeartbeat:
    """Our 1 Hz HEARTBEAT (as a GCS-type component)."""


@dataclass(frozen=True)
class SendManualControl:
    target_system: int
    axes: ManualControlAxes
    neutral: bool


@dataclass(frozen=True)
class SendCommandLong:
    target_system: int
    target_component: int
    command: int
    confirmation: int
    params: tuple[float, float, float, float, float, float, float]


@dataclass(frozen=True)
class SendParamRequestRead:
    target_system: int
    target_component: int
    param_id: str


@dataclass(frozen=True)
class SendRequestDataStream:
    """REQUEST_DATA_STREAM (start): the stream-rate fallback of the rate request (``rates.py``)."""

    target_system: int
    target_component: int
    stream_id: int
    rate_hz: int


@dataclass(frozen=True)
class Publish:
    message: Message


@dataclass(frozen=True)
class LockPeer:
    """Tell the link which peer address the autopilot is at (None: the lock is released), so it can
    refuse other datagrams before parsing them (cheap enough to outrun a flood) and, listening
    (udpin), answer the autopilot only."""

    address: Address


Output = (SendHeartbeat | SendManualControl | SendCommandLong | SendParamRequestRead
          | SendRequestDataStream | SendRequestMessage | SendFileTransfer | SendRequestEvent
          | Publish | LockPeer | FenceOutput)


# -- state pieces ---------------------------------------------------------------------------------


@dataclass
class LinkState:
    """What we know about the autopilot we command."""

    ok: bool = False
    target_system: int | None = None
    target_component: int | None = None
    target_address: Address = None  # the peer the locking HEARTBEAT came from (None: serial)
    profile: Profile | None = None
    last_heartbeat_mono_ns: int | None = None
    armed: bool = False
    mode: str = "UNKNOWN"
    custom_mode: int | None = None  # the HEARTBEAT's, as sent (the events protocol names modes so)
    connects: int = 0
    losses: int = 0


@dataclass
class ParamCheck:
    """The start-up read of the autopilot's loss-failsafe parameters.

    ``wanted`` are the names the assessment uses; ``alternatives`` the names each is asked under
    (a parameter renamed between firmware versions is asked under all its names at once, and the
    first answer settles it: no waiting for a name the firmware does not have)."""

    wanted: tuple[str, ...] = ()
    alternatives: dict[str, tuple[str, ...]] = field(default_factory=dict)
    values: dict[str, float] = field(default_factory=dict)
    answered_as: dict[str, str] = field(default_factory=dict)
    attempts: dict[str, int] = field(default_factory=dict)
    last_sent_mono_ns: int = 0
    done: bool = False
    assessment: FailsafeAssessment | None = None

    def names_for(self, wanted: str) -> tuple[str, ...]:
        return self.alternatives.get(wanted, (wanted,))

    def wanted_for(self, name: str) -> str | None:
        """The assessment's name for a PARAM_VALUE's ``name`` (None: not asked for)."""
        if name in self.wanted:
            return name
        return next((w for w, names in self.alternatives.items() if name in names), None)


class VehicleIoCore:
    """The whole of vehicle_io's logic. See the module docstring for how it is driven."""

    def __init__(self, config: VehicleIoConfig, limits: ThrusterLimits, start: Now,
                 signing_key: bytes | None = None, battery: BatteryParams | None = None) -> None:
        self.cfg = config
        # The vessel file's [battery] completes the autopilot's battery figures (None: it has none,
        # and only the measured figures are published).
        self.battery_params = battery
        # With a key, every incoming message must be signed with it (checked before anything else).
        self.verifier = SignatureVerifier(signing_key) if signing_key is not None else None
        self.refusals = Refusals()
        self.policy = SourcePolicy()
        self.limits = limits
        self.forced_profile = (profiles.by_name(config.autopilot)
                               if config.autopilot != profiles.AUTO else None)
        self.link = LinkState(profile=self.forced_profile)
        self.offset = BootTimeOffset(config.time_offset_window_s,
                                     confirm_s=config.time_confirm_s)
        self.watchdog = ThrustWatchdog(config.thrust_timeout_s)
        # The stamp bounds every service applies, held here too: the last step before the thrusters.
        self.thrust_stamps = StampGate("vehicle_io", log, StampBounds.live(config.thrust_max_age_s))
        self.thrust_absurd = 0  # ThrustCommands refused for an absurd thrust
        self._thrust_log = RateLimitedLog(log, STAMP_LOG_EVERY_S)  # as refused stamps are logged
        self.commands = CommandTracker()
        self.params = ParamCheck()
        self.rate_check: RateCheck | None = None
        self.rate_watch: RateWatch | None = None  # the rates after the check (None: not asked)
        self._rates_redrop_ns: int | None = None  # when a drop was last asked again (None: none)
        self._rates_asked_resets = 0  # the reboots the time offset had seen by then
        self.texts = StatusTexts()
        self.hold = FailsafeCause()  # why the autopilot took the vessel (failsafe_cause.py)
        self.health = Health()  # is it fit to start a mission (autopilot_health.py)
        self._health_said: str | None = None  # the health problem last logged
        self._mode_asked: str | None = None  # the mode vehicle_io last asked for, until it is seen
        # (mode, armed, last HEARTBEAT [mono ns], address) when the link was lost: a mode changed
        # meanwhile was not Seaway's
        self._before_loss: tuple[str, bool, int, Address] | None = None
        self.events = EventsChannel()  # the events protocol (PX4's arming reasons), per connection
        self.mapper: Any = None  # (L, R) -> axes for this autopilot's parameters; None: not yet
        self.gps_quality: GpsQuality | None = None
        self.gps_quality_mono_ns = 0
        self.battery = BatteryReading()
        self.battery_said: tuple[BatteryLevel, str] | None = None  # its battery text, latched
        self.dropped = 0
        self.counts: dict[str, int] = {}
        self.rates_hz: dict[str, float] = {}
        self.last_axes: ManualControlAxes | None = None
        self.manual_control_sent = 0
        self._rates_since_ns = start.mono_ns
        self._period_mc_ns = round(1e9 / config.manual_control_rate_hz)
        self._period_hb_ns = round(config.heartbeat_period_s * 1e9)
        self._period_status_ns = round(1e9 / config.status_rate_hz)
        self._next_mc_ns = start.mono_ns
        self._next_hb_ns = start.mono_ns
        self._next_status_ns = start.mono_ns
        self._ratelog = RateLimitedLog(log, LOG_EVERY_S)
        self._withheld: ThrustWithheld | None = self.thrust_withheld()  # as last published
        # The operating area as the autopilot's own fence (None: off); fed by the loop's area
        # and origin subscriptions, driven here.
        self.fence = (FenceSync(config.fence_timeout_s, config.fence_attempts)
                      if config.autopilot_fence else None)

    # ===========================================================================================
    # Inputs
    # ===========================================================================================

    def set_source_policy(self, policy: SourcePolicy) -> None:
        """What the transport says about where the autopilot is (set by the loop on each open)."""
        self.policy = policy

    def on_mavlink(self, msg: Any, now: Now, address: Address = None) -> list[Output]:
        """Handle one decoded MAVLink message (any type, from anyone) that arrived from ``address``
        (the UDP/TCP peer; None on a serial link)."""
        mtype = msg.get_type()
        link = self.link
        if mtype == "BAD_DATA":
            if link.ok and address != link.target_address:
                self.refusals.add(FOREIGN_SOURCE, (None, None, address), 1, now.mono_ns)
            else:
                self._drop(now, "BAD_DATA", "frame", getattr(msg, "reason", "unparseable bytes"))
            return []
        if msg.get_msgId() == mavlink.MAVLINK_MSG_ID_UNKNOWN:
            # A message our dialect does not define (PX4 1.18 sends CURRENT_MODE, AVAILABLE_MODES
            # and others): pymavlink keeps neither its header ids (it says 0/0) nor its whole frame
            # (no signature to check), so it is neither refused as foreign nor interpreted; only
            # counted when it came from the locked peer.
            if link.ok and address == link.target_address:
                self.counts[UNKNOWN_MESSAGES] = self.counts.get(UNKNOWN_MESSAGES, 0) + 1
            return []
        sysid, compid = msg.get_srcSystem(), msg.get_srcComponent()
        source: Source = (sysid, compid, address)
        if self.verifier is not None:
            verdict = self.verifier.check(msg.get_msgbuf(), signing_timestamp(now.wall_ns))
            if verdict != ACCEPTED:
                self.refusals.add(verdict, source, 1, now.mono_ns)
                return []
        if (sysid, compid) == (self.cfg.source_system, self.cfg.source_component):
            return []  # our own messages echoed back (a broadcast or a router)
        if link.ok:
            if address != link.target_address or sysid != link.target_system:
                self.refusals.add(FOREIGN_SOURCE, source, 1, now.mono_ns)
                return []
        elif mtype == "HEARTBEAT" and not self.policy.may_lock(address):
            self.refusals.add(FOREIGN_SOURCE, source, 1, now.mono_ns)
            return []
        if mtype == "HEARTBEAT":
            return self._on_heartbeat(msg, now, address)
        if not link.ok:
            if mtype == "STATUSTEXT" and self._before_loss is not None \
                    and address == self._before_loss[3]:
                # The autopilot lost, speaking again before its HEARTBEAT: ArduPilot's "GCS
                # Failsafe Cleared" goes out the moment our HEARTBEAT reaches it again.
                self.hold.cleared(cleared_cause(str(msg.text)), str(msg.text), now.mono_ns)
            return []  # no autopilot locked yet: nothing else is ours to interpret
        self.counts[mtype] = self.counts.get(mtype, 0) + 1
        if self.rate_check is not None:
            self.rate_check.count(mtype, now.mono_ns)
        if mtype in TRANSFER_MESSAGES:
            return [] if self.fence is None else list(self.fence.on_mavlink(msg, now.mono_ns))
        handler = self._HANDLERS.get(mtype)
        if handler is None:
            return []
        try:
            return handler(self, msg, now)
        except FieldError as err:
            self._drop(now, err.message_type, err.field, str(err))
            return []
        except NoDataError as err:
            self._log_limited(now, mtype, "nodata", logging.INFO, str(err))
            return []

    def on_refused_datagrams(self, tally: dict[Source, int], now: Now) -> None:
        """Count datagrams the link refused unparsed (from an address other than the locked peer;
        the ids are what their first header claims)."""
        for source, count in tally.items():
            self.refusals.add(FOREIGN_SOURCE, source, count, now.mono_ns)

    def on_thrust(self, cmd: ThrustCommand, now: Now) -> list[Output]:
        """A ThrustCommand arrived from the bus: becomes the latest, and goes out at once; unless it
        is refused (``thrust_refused``): then it changes nothing and never reaches the autopilot."""
        if self.thrust_refused(cmd, now):
            return []
        out: list[Output] = []
        event = self.watchdog.command(cmd, now.mono_ns)
        if event is not None:
            log.info("thrust commands fresh again (source %r): forwarding", cmd.source)
            out.append(Publish(self.status(now)))
        out.extend(self._manual_control(now))
        return out

    def thrust_refused(self, cmd: ThrustCommand, now: Now) -> bool:
        """Whether ``cmd`` is refused (counted and logged, at most one line per reason a minute):

        * an absurd thrust (``thrusters.absurd_thrust``: beyond twice the vessel's bounds), which
          saturation would otherwise turn into full power without a word;
        * a stamp over ``MAX_AHEAD_LIVE_S`` ahead of our wall clock or older than
          ``thrust_max_age_s`` (``seaway.runtime.stamps``). A command that stops both thrusters is
          exempt: stopping is always safe (the watchdog does it anyway), and the controller stamps
          its stale-state and shutdown stops with the last state's time, however old."""
        why = absurd_thrust(cmd.thrust_port_n, cmd.thrust_starboard_n, self.limits)
        if why is not None:
            self.thrust_absurd += 1
            self._thrust_log.warning("absurd", "refused a ThrustCommand (source %r): %s. Refused "
                                     "so far: %d (logged at most once a minute)", cmd.source, why,
                                     self.thrust_absurd, now_ns=now.mono_ns)
            return True
        if cmd.thrust_port_n == 0.0 and cmd.thrust_starboard_n == 0.0:
            return False
        return not self.thrust_stamps.admit(keys.THRUST.suffix, cmd.stamp_ns, now.wall_ns,
                                            now_ns=now.mono_ns)

    def refused_thrust(self) -> dict[str, int]:
        """ThrustCommands refused so far, by reason: 'absurd', 'stamp_ahead', 'stamp_behind'."""
        out = {f"stamp_{direction}": n for (_, direction), n in self.thrust_stamps.dropped.items()}
        if self.thrust_absurd:
            out["absurd"] = self.thrust_absurd
        return out

    def tick(self, now: Now) -> list[Output]:
        """Do whatever is due at ``now``: link check, watchdog, streams, retries, status."""
        out: list[Output] = []
        status_now = self._check_link(now)
        if status_now:
            out.append(LockPeer(None))  # released: the next autopilot HEARTBEAT locks again
        stream_due = now.mono_ns >= self._next_mc_ns
        event = self.watchdog.check(now.mono_ns)
        if event is not None:
            # Worth a warning only if it changed what the thrusters do: commands that stop after a
            # zero one (a mission over, a controller stopping in order), or while the autopilot
            # withholds the thrust anyway, are the expected end of a run.
            last = self.watchdog.latest
            cut = (last is not None and (last.thrust_port_n, last.thrust_starboard_n) != (0.0, 0.0)
                   and self.thrust_withheld() is None)
            log.log(logging.WARNING if cut else logging.INFO,
                    "no ThrustCommand for %.0f ms (timeout %.0f ms): thrust to neutral, failsafe "
                    "%s%s", (event.silent_for_ns or 0) / 1e6, self.cfg.thrust_timeout_s * 1e3,
                    FAILSAFE_THRUST_STALE, "" if cut else " (the thrusters were not driven: the "
                    "last command was zero thrust, or the autopilot withheld it)")
            stream_due = True  # neutral now, not at the next stream tick
            status_now = True
        if self.thrust_withheld() != self._withheld:
            status_now = True  # e.g. a link loss: say so at once, not at the next status tick
        if now.mono_ns >= self._next_hb_ns:
            out.append(SendHeartbeat())
            self._next_hb_ns = _next_after(self._next_hb_ns, self._period_hb_ns, now.mono_ns)
        if stream_due:
            out.extend(self._manual_control(now))
            if now.mono_ns >= self._next_mc_ns:
                self._next_mc_ns = _next_after(self._next_mc_ns, self._period_mc_ns, now.mono_ns)
        out.extend(self._param_requests(now))
        out.extend(self._fence_tick(now))
        if self.link.ok:
            sends, ended = self.events.tick(now.mono_ns)
            out.extend(_said_asking(sends))
            self._events_fetch_ended(ended)
        rates_out = self._rate_check_tick(now)
        if rates_out is not None:
            out.extend(rates_out)
            status_now = True
        self.refusals.flush(now.mono_ns)  # a refused source held back by the log's rate limit
        if status_now or now.mono_ns >= self._next_status_ns:
            out.extend(self._update_rates(now))
            out.append(Publish(self.status(now)))
            self._next_status_ns = now.mono_ns + self._period_status_ns
        return out

    def next_wake_ns(self) -> int:
        """The monotonic time at which ``tick`` next has something to do."""
        due = [self._next_hb_ns, self._next_mc_ns, self._next_status_ns]
        wd = self.watchdog.deadline_ns()
        if wd is not None:
            due.append(wd)
        if self.link.ok and self.link.last_heartbeat_mono_ns is not None:
            due.append(self.link.last_heartbeat_mono_ns + round(self.cfg.heartbeat_timeout_s * 1e9))
        if self.link.ok and not self.params.done and self.params.wanted:
            due.append(self.params.last_sent_mono_ns + round(self.cfg.param_timeout_s * 1e9))
        events_due = self.events.next_due_ns() if self.link.ok else None
        if events_due is not None:
            due.append(events_due)
        if self.link.ok and self.rate_check is not None:
            rc_due = self.rate_check.next_due_ns()
            if rc_due is not None:
                due.append(rc_due)
        fence_due = self.fence.next_due_ns() if self.fence is not None else None
        if fence_due is not None:
            due.append(fence_due)
        return min(due)

    def _fence_tick(self, now: Now) -> list[Output]:
        """Drive the fence sync; a new link or a reboot (the time offset's resets) checks it again."""
        if self.fence is None:
            return []
        link = self.link
        target = ((link.target_system, link.target_component)
                  if link.ok and link.target_system is not None and link.target_component is not None
                  else None)
        return list(self.fence.tick(now.mono_ns, target,
                                    link.profile.name if link.profile is not None else None,
                                    (link.connects, self.offset.resets)))

    # ===========================================================================================
    # Requests (arm, mode): the loop sends the returned command and waits for the ACK
    # ===========================================================================================

    def arm_command(self, arm: bool, force: bool) -> SendCommandLong | str:
        """The COMMAND_LONG for an arm/disarm request, or the reason it cannot be sent."""
        problem = self._command_precondition()
        if problem:
            return problem
        assert self.link.profile is not None
        p1, p2 = self.link.profile.arm_params(arm, force)
        return self._command_long(MAV_CMD_COMPONENT_ARM_DISARM, (p1, p2, 0, 0, 0, 0, 0))

    def mode_command(self, mode: str) -> SendCommandLong | str:
        """The COMMAND_LONG for a mode request, or the reason it cannot be sent."""
        problem = self._command_precondition()
        if problem:
            return problem
        assert self.link.profile is not None
        try:
            p1, p2, p3 = self.link.profile.encode_mode(mode)
        except ValueError as err:
            return str(err)
        self._mode_asked = mode.strip().upper()  # its HEARTBEAT may come before the ACK
        return self._command_long(MAV_CMD_DO_SET_MODE, (p1, p2, p3, 0, 0, 0, 0))

    def command_accepted(self, command: int, params: tuple[float, ...], mode: str | None) -> None:
        """An ACCEPTED ACK: take the new state now rather than at the next HEARTBEAT (<= 1 s)."""
        if command == MAV_CMD_COMPONENT_ARM_DISARM:
            if params[0] == 1.0 and not self.link.armed:
                self._armed_now()
            self.link.armed = params[0] == 1.0
        elif command == MAV_CMD_DO_SET_MODE and mode is not None:
            self.link.mode = mode.strip().upper()
            self._mode_asked = None  # taken: a later change to it is someone else's
            if self.hold.own_mode_accepted():
                log.info("Seaway's mode %s accepted: the autopilot's hold reason is cleared",
                         self.link.mode)

    def _command_precondition(self) -> str:
        if not self.link.ok or self.link.target_system is None or self.link.profile is None:
            return "no autopilot link (no HEARTBEAT from an autopilot yet, or link lost)"
        return ""

    def _command_long(self, command: int, params: tuple[float, ...]) -> SendCommandLong:
        assert self.link.target_system is not None and self.link.target_component is not None
        p = tuple(float(v) for v in params)
        return SendCommandLong(self.link.target_system, self.link.target_component, command, 0,
                               (p[0], p[1], p[2], p[3], p[4], p[5], p[6]))

    @staticmethod
    def command_name(command: int) -> str:
        return COMMAND_NAMES.get(command, str(command))

    # ===========================================================================================
    # Status
    # ===========================================================================================

    def failsafe(self, now: Now) -> str | None:
        """The failsafe to report, most serious first."""
        a = self.params.assessment
        if a is not None and a.blocking:
            return FAILSAFE_AUTOPILOT_CONFIG
        if self.watchdog.active(now.mono_ns) is None:
            return FAILSAFE_THRUST_STALE
        return None

    def thrust_withheld(self) -> ThrustWithheld | None:
        """Why the commanded thrust does not reach the thrusters now, whatever is commanded (None:
        it does): no autopilot link, a configuration under which vehicle_io sends neutral only,
        disarmed, or a mode in which manual control does not drive the thrusters
        (``Profile.thrust_modes``). The watchdog's staleness is not one of these: that is the
        commands stopping, which their sender knows."""
        link = self.link
        if not link.ok or link.profile is None:
            return "no_link"
        a = self.params.assessment
        if a is not None and a.blocking:
            return "autopilot_config"
        if not link.armed:
            return "disarmed"
        if link.mode not in link.profile.thrust_modes:
            return "mode"
        if self.health.problem() is not None:
            return "autopilot_unhealthy"
        return None

    def failsafe_latched(self) -> tuple[HoldReason, str] | None:
        """The failsafe the autopilot still stands in, and what says so (``autopilot_health``)."""
        said = self.battery_said
        level = worse_level(self.battery.level, None if said is None else said[0])
        return latched_failsafe(self.health.failsafe_bits, level, "" if said is None else said[1])

    def status(self, now: Now) -> VehicleStatus:
        link = self.link
        self._withheld = self.thrust_withheld()
        latched = self.failsafe_latched()
        problem = self.health.problem()
        if problem != self._health_said:
            if problem is not None:
                log.warning("%s", problem)
            elif self._health_said is not None:
                log.info("the autopilot is healthy again (estimator, status, sensors)")
            self._health_said = problem
        hb_age = (None if link.last_heartbeat_mono_ns is None
                  else max(0.0, (now.mono_ns - link.last_heartbeat_mono_ns) / 1e9))
        return VehicleStatus.make(
            stamp_ns=now.wall_ns,
            autopilot=link.profile.name if link.profile else "unknown",
            link_ok=link.ok,
            armed=link.armed,
            mode=link.mode,
            failsafe=self.failsafe(now),
            battery_voltage_v=self.battery.voltage_v,
            battery_remaining_frac=self.battery.remaining_frac,
            heartbeat_age_s=hb_age,
            rates_hz=dict(self.rates_hz),
            dropped_messages=self.dropped,
            refused_messages=dict(self.refusals.by_reason),
            # A standing hazard, not an event: reported beside the failsafe, not as one.
            autopilot_loss_failsafe=None if self.params.assessment is None
            else self.params.assessment.verdict,
            autopilot_loss_failsafe_summary="" if self.params.assessment is None
            else self.params.assessment.summary,
            hold_reason=self.hold.cause,
            hold_reason_detail=self.hold.detail,
            telemetry_rates_short=None if self.rate_watch is None or self.rate_watch.short is None
            else dict(self.rate_watch.short),
            thrust_withheld=self._withheld,
            refused_thrust=self.refused_thrust(),
            autopilot_fence=self.fence.report() if self.fence is not None else None,
            autopilot_unhealthy_detail=self.health.problem() or "",
            failsafe_latched=None if latched is None else latched[0],
            failsafe_latched_detail="" if latched is None else latched[1],
        )

    def _update_rates(self, now: Now) -> list[Output]:
        """Close a rate window (at least RATE_WINDOW_S long); what to send if the telemetry the
        autopilot was asked for has dropped (``rates.RateWatch``)."""
        dt = (now.mono_ns - self._rates_since_ns) / 1e9
        if dt < RATE_WINDOW_S:  # a 1 Hz message needs a window of seconds to show a steady rate
            return []
        self.rates_hz = {k: round(v / dt, 2) for k, v in sorted(self.counts.items())}
        verdict = None
        rc, watch = self.rate_check, self.rate_watch
        if (rc is not None and watch is not None and rc.phase == "done"
                and self._rates_since_ns >= rc.window_end_ns()):  # a window after the check's
            verdict = watch.window(self.counts, self._rates_since_ns, now.mono_ns)
        self.counts.clear()
        self._rates_since_ns = now.mono_ns
        if verdict == "recovered":
            self._rates_redrop_ns = None
            log.info("telemetry back at the requested rates: warning cleared")
        elif verdict == "drop" and watch is not None and self.link.profile is not None:
            want = {r.message: r.rate_hz for r in watch.requests}
            slow = ", ".join(f"{m} {hz:g} Hz of {want[m]:g} Hz" for m, hz in (watch.short or {}).items())
            last = self._rates_redrop_ns
            if last is None or now.mono_ns - last >= round(telemetry_rates.REREQUEST_EVERY_S * 1e9):
                self._rates_redrop_ns = now.mono_ns
                log.warning("telemetry DROPPED below the requested rate: %s; asking again", slow)
                return self._request_rates(self.link.profile, now)
            log.warning("telemetry below the requested rate: %s (asked again less than %g s ago)",
                        slow, telemetry_rates.REREQUEST_EVERY_S)
        return []

    # ===========================================================================================
    # Link
    # ===========================================================================================

    def _on_heartbeat(self, msg: Any, now: Now, address: Address) -> list[Output]:
        """A HEARTBEAT already admitted by ``on_mavlink`` (from the locked source, or one allowed to
        lock): locks the link to its source if none is locked, else refreshes it."""
        src_sys, src_comp = msg.get_srcSystem(), msg.get_srcComponent()
        if msg.type in NON_VEHICLE_TYPES:
            return []
        profile = profiles.by_mav_autopilot(msg.autopilot)
        link = self.link
        if link.ok:
            if src_sys != link.target_system or src_comp != link.target_component:
                return []  # another vehicle or component: we command exactly one
        else:
            if self.cfg.target_system is not None and src_sys != self.cfg.target_system:
                return []
            if profile is None:
                self._log_limited(now, "HEARTBEAT", "autopilot", logging.WARNING,
                                  f"ignoring HEARTBEAT from {src_sys}/{src_comp}: autopilot "
                                  f"{msg.autopilot} is none of {profiles.describe()}")
                return []
            if self.forced_profile is not None and profile is not self.forced_profile:
                self._log_limited(now, "HEARTBEAT", "mismatch", logging.ERROR,
                                  f"ignoring {profile.name} HEARTBEAT from {src_sys}: configured "
                                  f"for {self.forced_profile.name}")
                return []
            return self._connect(msg, profile, now, address)
        self.counts["HEARTBEAT"] = self.counts.get("HEARTBEAT", 0) + 1
        self._apply_heartbeat(msg, now)
        if self.thrust_withheld() != self._withheld:  # armed, disarmed, another mode: say so now
            return [Publish(self.status(now))]
        return []

    def _connect(self, msg: Any, profile: Profile, now: Now, address: Address) -> list[Output]:
        link = self.link
        link.ok = True
        link.target_system, link.target_component = msg.get_srcSystem(), msg.get_srcComponent()
        link.target_address = address
        link.profile = profile
        link.connects += 1
        self.health = Health(px4=profile.name == "px4")
        self.counts["HEARTBEAT"] = self.counts.get("HEARTBEAT", 0) + 1
        self._apply_heartbeat(msg, now, announce=False)  # the line below says it all
        before, self._before_loss = self._before_loss, None
        if (before is not None and before[1] and link.armed and link.mode != before[0]
                and link.mode not in profile.booting_modes):
            # Still armed, so not rebooted: the autopilot changed mode while unheard (its failsafe)
            self._hold_changed(self.hold.mode_changed_unheard(
                before[0], link.mode, (now.mono_ns - before[2]) / 1e9, now.mono_ns))
        log.info("autopilot link up: %s system %d component %d at %s, %s, %s (connection #%d); "
                 "locked to that source: MAVLink from any other is refused%s", profile.name,
                 link.target_system, link.target_component, address_key(address),
                 "ARMED" if link.armed else "disarmed", link.mode, link.connects,
                 ", signing on" if self.verifier is not None else "")
        self._start_param_check(profile)
        self.mapper = None if self.cfg.check_failsafe_params else profile.mapper({})
        self.texts.clear()
        out: list[Output] = [LockPeer(address), Publish(self.status(now))]
        out.extend(self._manual_control(now))  # start the stream at once (PX4 arms only with it)
        out.extend(self._param_requests(now))
        out.extend(self._request_rates(profile, now))
        if profile.events_protocol and self.cfg.autopilot_events:
            assert link.target_system is not None and link.target_component is not None
            out.extend(self.events.connect(link.target_system, link.target_component, now.mono_ns))
        return out

    def _apply_heartbeat(self, msg: Any, now: Now, announce: bool = True) -> None:
        link = self.link
        assert link.profile is not None
        armed = bool(msg.base_mode & MAV_MODE_FLAG_SAFETY_ARMED)
        mode = link.profile.decode_mode(msg.base_mode, msg.custom_mode)
        if announce and (armed != link.armed or mode != link.mode):
            log.info("autopilot %s, mode %s", "ARMED" if armed else "disarmed", mode)
        if announce and mode != link.mode:
            if mode == self._mode_asked:
                self._mode_asked = None
            elif mode in link.profile.booting_modes:
                # Back in its start-up mode: a reboot faster than the link timeout, nobody's mode
                # change; the rebooted autopilot has no failsafe standing either.
                log.warning("autopilot back in %s: it rebooted", mode)
                self.hold = FailsafeCause()
            elif link.mode not in link.profile.booting_modes and link.mode != "UNKNOWN":
                self._hold_changed(self.hold.mode_changed(link.mode, mode, now.mono_ns, armed))
        if (link.mode in link.profile.booting_modes and mode not in link.profile.booting_modes
                and self.cfg.check_failsafe_params):
            # Read during start-up, some values were not final yet (measured: Rover answered
            # RC1_DZ = 0 before setting its 30 us default): read them all again now.
            log.info("autopilot finished starting (%s -> %s): reading its parameters again",
                     link.mode, mode)
            self._start_param_check(link.profile)
        elif armed and not link.armed:
            self._armed_now()
        link.armed, link.mode = armed, mode
        link.custom_mode = int(msg.custom_mode)
        link.last_heartbeat_mono_ns = now.mono_ns
        self.health.heartbeat(msg.system_status)

    def _check_link(self, now: Now) -> bool:
        """Declare the link lost after heartbeat_timeout_s of silence; True if it just was."""
        link = self.link
        if not link.ok or link.last_heartbeat_mono_ns is None:
            return False
        silent_ns = now.mono_ns - link.last_heartbeat_mono_ns
        if silent_ns < round(self.cfg.heartbeat_timeout_s * 1e9):
            return False
        link.ok = False
        link.losses += 1
        self._before_loss = (link.mode, link.armed, link.last_heartbeat_mono_ns,
                             link.target_address)
        log.warning("autopilot link LOST: no HEARTBEAT from system %s for %.1f s; source lock "
                    "released, waiting for an autopilot HEARTBEAT to reconnect%s",
                    link.target_system, silent_ns / 1e9,
                    "" if self.policy.expected_address is None
                    else f" (from {address_key(self.policy.expected_address)} only)")
        # Forget everything learnt from this autopilot: it may come back rebooted, with another
        # id, from another port (udpin), or be a different autopilot altogether.
        link.target_system = link.target_component = None
        link.target_address = None
        link.profile = self.forced_profile
        link.armed = False
        link.mode = "UNKNOWN"
        link.custom_mode = None
        # Another firmware may answer next: fetch its catalog anew. The same one, not rebooted,
        # goes on counting its events: the gap across the outage is asked for (events_channel).
        self.events = EventsChannel(resume_after=self.events.tracker.last_sequence)
        self.offset.reset()
        self.hold = FailsafeCause()
        self.health = Health()
        self._mode_asked = None
        self.gps_quality = None
        self.battery = BatteryReading()
        self.battery_said = None
        self.commands.abandon_all()
        self.params = ParamCheck()
        self.rate_check = None
        self.rate_watch = None
        self._rates_redrop_ns = None
        self.mapper = None
        return True

    # ===========================================================================================
    # Thrust out
    # ===========================================================================================

    def axes_now(self, now: Now) -> tuple[ManualControlAxes, bool] | None:
        """The MANUAL_CONTROL axes to send now and whether they are neutral; None if no target."""
        link = self.link
        if not link.ok or link.profile is None or link.target_system is None:
            return None
        profile = link.profile
        cmd = self.watchdog.active(now.mono_ns)
        blocked = self.params.assessment is not None and bool(self.params.assessment.blocking)
        # A mapping that depends on parameters (ArduPilot's RC calibration) waits for them.
        unmapped = self.mapper is None and profile.mapping_needs_params
        if (cmd is None or blocked or unmapped
                or (self.cfg.forward_thrust_only_when_armed and not link.armed)):
            return profile.neutral(), True
        left, right = normalise_pair(cmd.thrust_port_n, cmd.thrust_starboard_n, self.limits,
                                     profile.quantisation_guard)
        axes = (self.mapper or profile.manual_control)(left, right)
        return axes, axes == profile.neutral()

    def neutral_command(self) -> SendManualControl | None:
        """Neutral MANUAL_CONTROL for the current target (None without one); used on shutdown."""
        link = self.link
        if not link.ok or link.profile is None or link.target_system is None:
            return None
        return SendManualControl(link.target_system, link.profile.neutral(), True)

    def _manual_control(self, now: Now) -> list[Output]:
        result = self.axes_now(now)
        if result is None:
            return []
        axes, neutral = result
        assert self.link.target_system is not None
        self.last_axes = axes
        self.manual_control_sent += 1
        return [SendManualControl(self.link.target_system, axes, neutral)]

    # ===========================================================================================
    # Telemetry in
    # ===========================================================================================

    def _stamp(self, msg: Any, now: Now) -> int:
        """Stamp for a message with time_boot_ms, validated before it may move the estimate
        (``timesync.BootTimeOffset``: a boot time far ahead is refused, a late one gets its older
        stamp, and only a streak of samples, never one, restarts the estimate)."""
        boot_ms = msg.time_boot_ms
        resets, rebases = self.offset.resets, self.offset.rebases
        stamp = self.offset.stamp(boot_ms, now.wall_ns)
        if self.offset.resets != resets:
            log.warning("autopilot clock restarted (every time_boot_ms over %.1f s behind the "
                        "estimate): time offset estimated anew", self.cfg.time_confirm_s)
            self._rebooted()
        elif self.offset.rebases != rebases:
            log.warning("time offset was wrong (every time_boot_ms over %.1f s ahead of it): "
                        "estimated anew from those messages", self.cfg.time_confirm_s)
        if stamp is None:
            raise FieldError(msg.get_type(), "time_boot_ms", boot_ms,
                             "jumps ahead of the autopilot's clock")
        if stamp < 0:
            raise FieldError(msg.get_type(), "time_boot_ms", boot_ms, "gives a negative stamp")
        return stamp

    def _publish_stamped(self, msg: Any, now: Now, convert: Any) -> list[Output]:
        stamp = self._stamp(msg, now)
        message = convert(stamp)  # raises FieldError before the estimate is touched
        self.offset.commit(msg.time_boot_ms, now.wall_ns)
        return [Publish(message)]

    def _on_system_time(self, msg: Any, now: Now) -> list[Output]:
        """SYSTEM_TIME: the autopilot's clock now; going back means it rebooted."""
        if self.offset.system_time(msg.time_boot_ms):
            log.warning("autopilot rebooted (SYSTEM_TIME time_boot_ms went back to %d ms): time "
                        "offset estimated anew", msg.time_boot_ms)
            self._rebooted()
        return []

    def _rebooted(self) -> None:
        """The autopilot rebooted without the link dropping (its clock went back): forget what it
        said before, as a link loss does. A reboot ends what it latched till reboot (ArduPilot's
        battery failsafe), and a failsafe or a mode change before it is no cause of a hold after."""
        self.battery_said = None
        self.health = Health(px4=self.health.px4)
        self.events.restart_count()
        if self.hold.cause is not None:
            log.info("the autopilot's hold reason (%s) ends with its reboot", self.hold.cause)
        self.hold = FailsafeCause()

    def _on_global_position_int(self, msg: Any, now: Now) -> list[Output]:
        fresh = (self.gps_quality is not None and now.mono_ns - self.gps_quality_mono_ns
                 <= round(self.cfg.gps_raw_max_age_s * 1e9))
        quality = self.gps_quality if fresh else None
        return self._publish_stamped(msg, now, lambda stamp: gnss_from_global_position_int(
            msg, stamp, quality, self.cfg.fix_type_without_gps_raw))

    def _on_attitude(self, msg: Any, now: Now) -> list[Output]:
        return self._publish_stamped(msg, now, lambda stamp: attitude_from_attitude(msg, stamp))

    def _on_local_position_ned(self, msg: Any, now: Now) -> list[Output]:
        return self._publish_stamped(
            msg, now, lambda stamp: local_position_from_local_position_ned(msg, stamp))

    def _on_gps_raw_int(self, msg: Any, now: Now) -> list[Output]:
        self.gps_quality = gps_quality_from_gps_raw_int(msg)
        self.gps_quality_mono_ns = now.mono_ns
        return []

    def _on_sys_status(self, msg: Any, now: Now) -> list[Output]:
        reading = battery_from_sys_status(msg)  # refuses an absurd message before it is used
        self._hold_changed(self.hold.health(msg.onboard_control_sensors_present,
                                            msg.onboard_control_sensors_enabled,
                                            msg.onboard_control_sensors_health, now.mono_ns))
        self.health.sys_status(msg.onboard_control_sensors_present,
                               msg.onboard_control_sensors_enabled,
                               msg.onboard_control_sensors_health)
        return self._on_battery(reading, now)

    def _on_estimator_report(self, msg: Any, now: Now) -> list[Output]:
        """EKF_STATUS_REPORT (ArduPilot) or ESTIMATOR_STATUS (PX4): is it using GNSS."""
        self.health.estimator_flags(msg.get_type(), int(msg.flags))
        return []

    def _on_battery_status(self, msg: Any, now: Now) -> list[Output]:
        if msg.id != 0:
            return []  # the first battery is the one SYS_STATUS also describes
        return self._on_battery(battery_from_battery_status(msg), now)

    def _on_battery(self, reading: BatteryReading, now: Now) -> list[Output]:
        """A battery message converted (refused before this if a field is absurd): the pack's
        state, completed from the vessel file, on ``vehicle/battery`` at once. Stamped at receipt
        (wall clock), as VehicleStatus: neither message carries the autopilot's time."""
        self.battery = self.battery.merged(reading)
        return [Publish(battery_state(self.battery, self.battery_params, now.wall_ns,
                                      self.battery_said))]

    def _on_command_ack(self, msg: Any, now: Now) -> list[Output]:
        if msg.command == MAV_CMD_SET_MESSAGE_INTERVAL:
            if self.rate_check is not None and (getattr(msg, "target_system", 0) or 0) in (
                    0, self.cfg.source_system):
                self.rate_check.on_ack(msg.result)
            return []
        if msg.command == MAV_CMD_REQUEST_MESSAGE:  # only ever sent for COMPONENT_METADATA
            self._events_fetch_ended(self.events.on_request_ack(msg.result, now.mono_ns))
            return []
        self.commands.on_ack(msg.command, msg.result, msg.get_srcSystem(),
                             getattr(msg, "target_system", 0) or 0, self.cfg.source_system)
        return []

    def _on_statustext(self, msg: Any, now: Now) -> list[Output]:
        item = self.texts.add(msg.severity, msg.text, now.mono_ns, getattr(msg, "id", 0) or 0,
                              getattr(msg, "chunk_seq", 0) or 0)
        if item is not None:
            # MAV_SEVERITY <= 4 is a warning or worse (PreArm failures are 2, CRITICAL)
            self._log_limited(now, "STATUSTEXT", item.text, logging.WARNING if item.severity <= 4
                              else logging.INFO, f"autopilot says: {item.text}")
            if self.fence is not None:
                self.fence.on_text(item.text)
            self._hold_changed(self.hold.cleared(cleared_cause(item.text), item.text, now.mono_ns))
            if item.severity <= WARNING_SEVERITY:
                self._hold_changed(self.hold.said(classify_text(item.text), item.text,
                                                  now.mono_ns))
                level = battery_level_from_text(item.text)
                if level is not None:
                    # Latched: ArduPilot says it once, and its battery failsafe holds till reboot.
                    self.battery_said = (worse_level(level, None if self.battery_said is None
                                                     else self.battery_said[0]) or level, item.text)
                    return self._on_battery(BatteryReading(), now)
        return []

    def refusal_texts(self, since_mono_ns: int) -> tuple[list[str], bool]:
        """Why the autopilot refused an arm sent at ``since_mono_ns``, in its own words: its
        STATUSTEXTs with the profile's prefixes (ArduPilot), its EVENTs (PX4: the denial and each
        failing check for the current mode); and whether that is all it will say (no use waiting
        longer)."""
        profile = self.link.profile
        if profile is None:
            return [], True
        texts = matching(self.texts.since(since_mono_ns), profile.arming_refusal_prefixes) \
            if profile.arming_refusal_prefixes else []
        complete = bool(texts)
        if profile.events_protocol and self.events.catalog is not None:
            said, events_complete = self.events.tracker.refusal(since_mono_ns, self.link.custom_mode)
            texts += [t for t in said if t not in texts]
            complete = complete or events_complete
        return texts, complete

    def explains_refusals(self) -> bool:
        """Whether this autopilot says why it refused (worth waiting for): in STATUSTEXT, or in
        EVENTs once their descriptions are known."""
        profile = self.link.profile
        if profile is None:
            return False
        return bool(profile.arming_refusal_prefixes) or (
            profile.events_protocol and self.events.catalog is not None)

    def _on_event(self, msg: Any, now: Now) -> list[Output]:
        if self.link.profile is None or not self.link.profile.events_protocol:
            return []
        ev, asks = self.events.on_event(msg, now.mono_ns)
        if ev is not None and ev.level <= 6 and not ev.name.endswith("_summary"):
            # warning or worse (arming-check failures are error, 3) as a warning, notices and
            # info as info; debug and protocol chatter not at all
            self._log_limited(now, "EVENT", ev.text, logging.WARNING if ev.level <= 4
                              else logging.INFO, f"autopilot says: {ev.text}")
        if ev is not None and self.fence is not None:
            self.fence.on_text(ev.text)
        if ev is not None and ev.level <= EVENT_WARNING_LEVEL:
            self._hold_changed(self.hold.said(classify_text(ev.text), ev.text, now.mono_ns))
        return _said_asking(asks)

    def _on_current_event_sequence(self, msg: Any, now: Now) -> list[Output]:
        if self.link.profile is None or not self.link.profile.events_protocol:
            return []
        return _said_asking(self.events.on_current_sequence(int(msg.sequence), int(msg.flags),
                                                            now.mono_ns))

    def _hold_changed(self, changed: bool) -> None:
        if changed:
            log.warning("autopilot took the vessel: %s (%s)", self.hold.cause, self.hold.detail)

    def _on_component_metadata(self, msg: Any, now: Now) -> list[Output]:
        return list(self.events.on_component_metadata(msg, now.mono_ns))

    def _on_file_transfer_protocol(self, msg: Any, now: Now) -> list[Output]:
        if (msg.target_system, msg.target_component) not in (
                (self.cfg.source_system, self.cfg.source_component), (0, 0)):
            return []  # another client's transfer
        sends, ended = self.events.on_ftp(bytes(msg.payload), now.mono_ns)
        self._events_fetch_ended(ended)
        return list(sends)

    def _events_fetch_ended(self, line: str | None) -> None:
        if line is not None:
            # an autopilot that says it has no metadata (Seaway's own simulator) is no news
            quiet = self.events.catalog is not None or self.events.unsupported
            log.log(logging.INFO if quiet else logging.WARNING, "%s", line)

    # ===========================================================================================
    # Telemetry rates (rates.py)
    # ===========================================================================================

    def _request_rates(self, profile: Profile, now: Now) -> list[Output]:
        """At connection, after a reboot and on a drop: SET_MESSAGE_INTERVAL for every message at
        its configured rate. A standing shortfall stays in the status until the new check ends."""
        self.rate_check = None
        if not profile.requests_message_rates or not self.cfg.message_rates_hz:
            return []
        requests = telemetry_rates.plan(self.cfg.message_rates_hz)
        self.rate_check = RateCheck(requests, now.mono_ns)
        if self.rate_watch is None:
            self.rate_watch = RateWatch(requests)
        self._rates_asked_resets = self.offset.resets
        link = self.link
        assert link.target_system is not None and link.target_component is not None
        return [SendCommandLong(link.target_system, link.target_component,
                                MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                (float(r.msg_id), r.interval_us, 0.0, 0.0, 0.0, 0.0, 0.0))
                for r in requests]

    def _rate_check_tick(self, now: Now) -> list[Output] | None:
        """Advance the rate check; None when nothing changed, else what to send (maybe nothing)."""
        rc, link = self.rate_check, self.link
        if rc is None or not link.ok or link.profile is None or link.target_system is None:
            return None
        if self.offset.resets != self._rates_asked_resets:
            # A reboot (SYSTEM_TIME or every stamp going back) without the link dropping: the
            # autopilot forgot the intervals it was asked for and streams at its defaults.
            log.warning("autopilot rebooted: asking for the telemetry rates again")
            return self._request_rates(link.profile, now)
        if rc.all_accepted():
            rc.start_measuring(now.mono_ns, fallback=False)
            return []
        if rc.needs_fallback(now.mono_ns):
            streams = telemetry_rates.fallback_streams(rc.requests, link.profile.data_streams)
            log.warning("autopilot did not take SET_MESSAGE_INTERVAL (%d of %d accepted, refused "
                        "with %s): %s", rc.accepted, len(rc.requests), rc.refused or "no ACK",
                        f"asking with REQUEST_DATA_STREAM (streams {streams})" if streams else
                        f"{link.profile.name} has no stream-rate fallback: measuring what it sends")
            rc.start_measuring(now.mono_ns, fallback=True)
            assert link.target_component is not None
            return [SendRequestDataStream(link.target_system, link.target_component, sid, hz)
                    for sid, hz in sorted(streams.items())]
        if rc.phase == "measuring" and now.mono_ns >= rc.window_end_ns():
            short = rc.finish()
            if self.rate_watch is not None:
                self.rate_watch.checked(short)
            asked = ", ".join(f"{r.message} {r.rate_hz:g}" for r in rc.requests)
            how = "REQUEST_DATA_STREAM" if rc.fallback_used else "SET_MESSAGE_INTERVAL"
            if short:
                want = {r.message: r.rate_hz for r in rc.requests}
                log.warning("telemetry BELOW the requested rate (asked with %s): %s; the estimator "
                            "may time out. Check the link's bandwidth and its stream-rate "
                            "parameters (ArduPilot SRn_*/MAVn_*)", how, ", ".join(
                                f"{m} {hz:g} Hz of {want[m]:g} Hz" for m, hz in short.items()))
            else:
                log.info("telemetry at the requested rates (Hz: %s; asked with %s)", asked, how)
            return []
        return None

    # ===========================================================================================
    # Failsafe parameters
    # ===========================================================================================

    def _on_param_value(self, msg: Any, now: Now) -> list[Output]:
        pc = self.params
        name = str(msg.param_id).rstrip("\x00")
        if self.fence is not None and self.link.profile is not None:
            value = self.link.profile.decode_param(msg.param_value, msg.param_type)
            if value == value and abs(value) != float("inf"):
                fence_out: list[Output] = list(self.fence.on_param_value(name, value, now.mono_ns))
                if fence_out:
                    return fence_out
        wanted = pc.wanted_for(name)
        if pc.done or wanted is None or self.link.profile is None:
            return []
        value = self.link.profile.decode_param(msg.param_value, msg.param_type)
        if value != value or value in (float("inf"), float("-inf")):
            raise FieldError("PARAM_VALUE", "param_value", msg.param_value, "not finite")
        pc.values[wanted] = value
        pc.answered_as[wanted] = name
        if len(pc.values) == len(pc.wanted):
            self._finish_param_check()
        return []

    def _armed_now(self) -> None:
        """The vessel just armed (its ACK or HEARTBEAT, whichever came first): read the thrust
        mapping's parameters again before thrust matters.

        Read after start-up, a value can still be a boot-time one: measured on Rover SITL, RC1_DZ
        read 0 even after the mode left INITIALISING (its 30 us default came with the first RC
        input, seconds later), so the port paddle lost its dead-zone compensation, 30 us or about
        1 N in 25, and the boat turned steadily to port. The mapping in use stays until the new one
        is made."""
        profile = self.link.profile
        if (profile is None or not profile.mapping_needs_params or not self.cfg.check_failsafe_params
                or not self.params.done):
            return
        log.info("autopilot armed: reading its parameters again (the thrust mapping's)")
        self._start_param_check(profile)

    def _start_param_check(self, profile: Profile) -> None:
        """(Re)start the parameter read; the mapping in use stays until the new one is made."""
        self.params = ParamCheck(
            wanted=profile.failsafe_params if self.cfg.check_failsafe_params else (),
            alternatives=dict(profile.param_alternatives),
            done=not self.cfg.check_failsafe_params)

    def _param_requests(self, now: Now) -> list[Output]:
        pc, link = self.params, self.link
        if pc.done or not pc.wanted or not link.ok or link.target_system is None:
            return []
        if pc.attempts and now.mono_ns < pc.last_sent_mono_ns + round(self.cfg.param_timeout_s * 1e9):
            return []
        missing = [p for p in pc.wanted if p not in pc.values]
        exhausted = [p for p in missing if pc.attempts.get(p, 0) >= self.cfg.param_attempts]
        if exhausted and len(exhausted) == len(missing):
            self._finish_param_check()
            return []
        assert link.target_component is not None
        out: list[Output] = []
        for p in missing:
            if pc.attempts.get(p, 0) < self.cfg.param_attempts:
                pc.attempts[p] = pc.attempts.get(p, 0) + 1
                out.extend(SendParamRequestRead(link.target_system, link.target_component, name)
                           for name in pc.names_for(p))
        pc.last_sent_mono_ns = now.mono_ns
        return out

    def _finish_param_check(self) -> None:
        pc = self.params
        assert self.link.profile is not None
        pc.done = True
        missing = ["/".join(pc.names_for(p)) for p in pc.wanted if p not in pc.values]
        a = self.link.profile.assess_failsafe(pc.values, self.cfg.source_system,
                                              self.cfg.rc_receiver)
        pc.assessment = a
        self.mapper = self.link.profile.mapper(pc.values)
        level = logging.INFO if a.verdict in ("stops", "takes_over") else logging.WARNING
        log.log(level, "if vehicle_io dies, the autopilot %s: %s", {
            "stops": "STOPS the thrusters", "takes_over": "TAKES OVER (does not simply stop)",
            "none": "DOES NOT STOP the thrusters", "unknown": "may or may not stop the thrusters",
        }[a.verdict], a.summary)
        if missing:
            log.warning("parameters not reported by the autopilot: %s", ", ".join(missing))
        for w in a.warnings:
            log.warning("autopilot configuration: %s", w)
        for b in a.blocking:
            log.error("autopilot configuration BLOCKS thrust (neutral only): %s", b)

    # ===========================================================================================
    # Dropping and logging
    # ===========================================================================================

    def _drop(self, now: Now, mtype: str, fieldname: str, text: str) -> None:
        self.dropped += 1
        self._log_limited(now, mtype, fieldname, logging.WARNING,
                          f"dropped {mtype} (field {fieldname}): {text}")

    def _log_limited(self, now: Now, mtype: str, fieldname: str, level: int, text: str) -> None:
        """Log, but at most once per (message, field) per 5 s, saying how many were suppressed."""
        self._ratelog.log((mtype, fieldname), level, "%s", text, now_ns=now.mono_ns)

    _HANDLERS: ClassVar[dict[str, Any]] = {
        "GLOBAL_POSITION_INT": _on_global_position_int,
        "ATTITUDE": _on_attitude,
        "LOCAL_POSITION_NED": _on_local_position_ned,
        "GPS_RAW_INT": _on_gps_raw_int,
        "SYS_STATUS": _on_sys_status,
        "BATTERY_STATUS": _on_battery_status,
        "COMMAND_ACK": _on_command_ack,
        "PARAM_VALUE": _on_param_value,
        "STATUSTEXT": _on_statustext,
        "SYSTEM_TIME": _on_system_time,
        "EKF_STATUS_REPORT": _on_estimator_report,
        "ESTIMATOR_STATUS": _on_estimator_report,
        "EVENT": _on_event,
        "CURRENT_EVENT_SEQUENCE": _on_current_event_sequence,
        "COMPONENT_METADATA": _on_component_metadata,
        "FILE_TRANSFER_PROTOCOL": _on_file_transfer_protocol,
    }


def _said_asking(sends: list[Any]) -> list[Output]:
    """``sends``, each REQUEST_EVENT among them logged: events lost on the link asked for again."""
    for s in sends:
        if isinstance(s, SendRequestEvent):
            log.info("asking the autopilot again for its events %d-%d, lost on the link",
                     s.first_sequence, s.last_sequence)
    return list(sends)


def _next_after(due_ns: int, period_ns: int, now_ns: int) -> int:
    """The next tick of a fixed-rate schedule after ``now_ns`` (skips missed ticks, no burst)."""
    nxt = due_ns + period_ns
    if nxt <= now_ns:
        nxt = now_ns + period_ns - (now_ns - due_ns) % period_ns
    return nxt
