"""vehicle_io's pure core: MAVLink messages, thrust commands and time in; messages to send out.

Nothing here opens a socket, reads a clock or touches the bus. The node (``node.py``)
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
must also carry a valid MAVLink 2 signature (``seaway.mavlink.signing``). A link loss
releases the lock (``LockPeer(None)``) and the next autopilot HEARTBEAT locks again, within what
``SourcePolicy`` allows.

The core is composed of parts, each in a module of its own that owns its state: the link
(``core_link``), the thrust path (``core_thrust``), telemetry in (``core_telemetry``), what the
autopilot says (``core_said``), the parameter read (``core_params``), the telemetry rates
(``core_rates``), the arm and mode requests (``core_requests``) and the status (``core_status``;
the statuses said at once between the periodic ones are paced by ``status_pacing``).
This class admits each message, hands it to its part, and runs the schedule (``tick``); it is the
one entry the loop and everything else use. Its inputs and outputs are in ``core_outputs``.
"""

from __future__ import annotations

import logging
from typing import Any, ClassVar

from seaway.mavlink.signing import ACCEPTED, SignatureVerifier, signing_timestamp
from seaway.runtime.ratelog import RateLimitedLog
from seaway.vessel.battery import BatteryParams

from seaway_vehicle_io.authority import (
    FOREIGN_SOURCE,
    Address,
    Refusals,
    Source,
    SourcePolicy,
)
from seaway_vehicle_io.changelog import ChangeLog
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.conversions import FieldError, NoDataError
from seaway_vehicle_io.core_link import LinkWatch
from seaway_vehicle_io.core_outputs import (
    LockPeer,
    Now,
    Output,
    Publish,
    SendCommandLong,
    SendHeartbeat,
    SendManualControl,
    SendParamRequestRead,
    SendRequestDataStream,
)
from seaway_vehicle_io.core_params import ParamRead
from seaway_vehicle_io.core_rates import RateRequests
from seaway_vehicle_io.core_requests import Requests
from seaway_vehicle_io.core_said import AutopilotSaid, said_asking
from seaway_vehicle_io.core_status import StatusReport
from seaway_vehicle_io.core_telemetry import TelemetryIn
from seaway_vehicle_io.core_thrust import ThrustPath
from seaway_vehicle_io.failsafe_cause import cleared_cause
from seaway_vehicle_io.fence_sync import FenceSync
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.mission_transfer import TRANSFER_MESSAGES
from seaway_vehicle_io.thrust import ThrusterLimits
from seaway_vehicle_io.watchdog import FAILSAFE_THRUST_STALE

# The core's inputs and outputs, imported from here by the loop, the link and the tests.
__all__ = [
    "LockPeer",
    "Now",
    "Output",
    "Publish",
    "SendCommandLong",
    "SendHeartbeat",
    "SendManualControl",
    "SendParamRequestRead",
    "SendRequestDataStream",
    "VehicleIoCore",
]

log = logging.getLogger("seaway.vehicle_io")

UNKNOWN_MESSAGES = "UNKNOWN"  # counts[] key of messages the dialect does not define

LOG_EVERY_S = 5.0  # at most one log line per (message, field) per 5 s


class VehicleIoCore(LinkWatch, ThrustPath, TelemetryIn, AutopilotSaid, ParamRead, RateRequests,
                    Requests, StatusReport):
    """The whole of vehicle_io's logic. See the module docstring for how it is driven."""

    def __init__(self, config: VehicleIoConfig, limits: ThrusterLimits, start: Now,
                 signing_key: bytes | None = None, battery: BatteryParams | None = None) -> None:
        self.cfg = config
        # With a key, every incoming message must be signed with it (checked before anything else).
        self.verifier = SignatureVerifier(signing_key) if signing_key is not None else None
        self.refusals = Refusals()
        self.policy = SourcePolicy()
        self.dropped = 0
        self.counts: dict[str, int] = {}
        self._period_hb_ns = round(config.heartbeat_period_s * 1e9)
        self._period_status_ns = round(1e9 / config.status_rate_hz)
        self._next_hb_ns = start.mono_ns
        self._next_status_ns = start.mono_ns
        self._ratelog = RateLimitedLog(log, LOG_EVERY_S)
        # The autopilot's own words (STATUSTEXT, EVENT) are keyed by their text, and texts with
        # numbers in them are ever new: a table of their own, so that they never fill the one
        # above (256 keys) and pool a new message's drop warning with them.
        self._said_log = RateLimitedLog(log, LOG_EVERY_S)
        # Its mode, arming, health and hold reason changing: every change at once, not a flood.
        self._changes = ChangeLog(log)
        # The operating area as the autopilot's own fence (None: off); fed by the loop's area
        # and origin subscriptions, driven here.
        self.fence = (FenceSync(config.fence_timeout_s, config.fence_attempts)
                      if config.autopilot_fence else None)
        self._init_link(config)
        self._init_thrust(config, limits, start)
        self._init_telemetry(config, battery)
        self._init_said()
        self._init_params()
        self._init_rates(start)
        self._init_requests()
        self._init_status()

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
                # Before the link is up, a broken frame is the stream joined mid-message (a serial
                # port opened mid-frame, a firmware already talking on a TCP port), and while the
                # autopilot starts, its ports starting (ArduPilot SITL: one a second after its
                # first HEARTBEAT): counted, not a warning. After that, it is the link corrupting
                # frames.
                quiet = not link.ok or self.autopilot_starting(now)
                self._drop(now, "BAD_DATA", "frame", getattr(msg, "reason", "unparseable bytes"),
                           logging.INFO if quiet else logging.WARNING)
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
            if address != link.target_address or sysid != link.target_system or (
                    compid != link.target_component and not self._ftp_peer(mtype, compid)):
                # Another component of the autopilot's system (a gimbal, a smart battery, a
                # companion computer behind the same router) speaks for itself, not for the
                # vessel: its position, texts, ACKs and clock are not the autopilot's.
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

    def _ftp_peer(self, mtype: str, compid: int) -> bool:
        """Whether ``compid`` is the component the events metadata is being read from over MAVLink
        FTP (a COMPONENT_METADATA URI may name one other than the autopilot's)."""
        fetch = self.events.fetch
        return mtype == "FILE_TRANSFER_PROTOCOL" and fetch is not None \
            and compid == fetch.target_component

    def on_refused_datagrams(self, tally: dict[Source, int], now: Now) -> None:
        """Count datagrams the link refused unparsed (from an address other than the locked peer;
        the ids are what their first header claims)."""
        for source, count in tally.items():
            self.refusals.add(FOREIGN_SOURCE, source, count, now.mono_ns)

    # ===========================================================================================
    # The schedule: what is due when
    # ===========================================================================================

    def tick(self, now: Now) -> list[Output]:
        """Do whatever is due at ``now``: link check, watchdog, streams, retries, status (the
        periodic one, one to say at once, or one the pacing held back, due now)."""
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
        out.extend(self._said_texts_due(now))
        out.extend(self._fence_tick(now))
        if self.link.ok:
            sends, ended = self.events.tick(now.mono_ns)
            out.extend(said_asking(sends))
            self._events_fetch_ended(ended)
        rates_out = self._rate_check_tick(now)
        if rates_out is not None:
            out.extend(rates_out)
            status_now = True
        self.refusals.flush(now.mono_ns)  # a refused source held back by the log's rate limit
        self._changes.flush(now.mono_ns)  # the latest state change held back, with its count
        pacer = self.status_pacer
        if status_now or pacer.due(now.mono_ns):
            # Said at once unless another was less than a gap ago: then held to the gap's end, when
            # it is due here with the state as it is then (``status_pacing``: a link loss or a
            # disarm waits at most ``MIN_STATUS_GAP_NS``).
            status_now = pacer.may_say(now.mono_ns)
        if status_now or now.mono_ns >= self._next_status_ns:
            out.extend(self._update_rates(now))
            out.append(Publish(self.status(now)))
            pacer.said()  # the latest state: nothing held back is left unsaid
            self._next_status_ns = now.mono_ns + self._period_status_ns
        return out

    def next_wake_ns(self) -> int:
        """The monotonic time at which ``tick`` next has something to do."""
        due = [self._next_hb_ns, self._next_mc_ns, self._next_status_ns]
        held = self.status_pacer.next_due_ns()  # a status held back by the pacing
        if held is not None:
            due.append(held)
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
    # Dropping and logging
    # ===========================================================================================

    def _drop(self, now: Now, mtype: str, fieldname: str, text: str,
              level: int = logging.WARNING) -> None:
        self.dropped += 1
        self._log_limited(now, mtype, fieldname, level, f"dropped {mtype} (field {fieldname}): {text}")

    def _log_limited(self, now: Now, mtype: str, fieldname: str, level: int, text: str) -> None:
        """Log, but at most once per (message, field) per 5 s, saying how many were suppressed."""
        self._ratelog.log((mtype, fieldname), level, "%s", text, now_ns=now.mono_ns)

    def _log_said(self, now: Now, mtype: str, text: str, level: int) -> None:
        """Log what the autopilot said (``text``), at most once per text per 5 s."""
        self._said_log.log((mtype, text), level, "autopilot says: %s", text, now_ns=now.mono_ns)

    def _log_change(self, now: Now, kind: str, level: int, text: str) -> None:
        """Log a change of the autopilot's state (``changelog.ChangeLog``: a flapping autopilot
        is not a flood)."""
        self._changes.log(kind, level, text, now.mono_ns)

    _HANDLERS: ClassVar[dict[str, Any]] = {
        "GLOBAL_POSITION_INT": TelemetryIn._on_global_position_int,
        "ATTITUDE": TelemetryIn._on_attitude,
        "LOCAL_POSITION_NED": TelemetryIn._on_local_position_ned,
        "GPS_RAW_INT": TelemetryIn._on_gps_raw_int,
        "SYS_STATUS": TelemetryIn._on_sys_status,
        "BATTERY_STATUS": TelemetryIn._on_battery_status,
        "COMMAND_ACK": Requests._on_command_ack,
        "PARAM_VALUE": ParamRead._on_param_value,
        "STATUSTEXT": AutopilotSaid._on_statustext,
        "SYSTEM_TIME": TelemetryIn._on_system_time,
        "EKF_STATUS_REPORT": TelemetryIn._on_estimator_report,
        "ESTIMATOR_STATUS": TelemetryIn._on_estimator_report,
        "EVENT": AutopilotSaid._on_event,
        "CURRENT_EVENT_SEQUENCE": AutopilotSaid._on_current_event_sequence,
        "COMPONENT_METADATA": AutopilotSaid._on_component_metadata,
        "FILE_TRANSFER_PROTOCOL": AutopilotSaid._on_file_transfer_protocol,
    }


def _next_after(due_ns: int, period_ns: int, now_ns: int) -> int:
    """The next tick of a fixed-rate schedule after ``now_ns`` (skips missed ticks, no burst)."""
    nxt = due_ns + period_ns
    if nxt <= now_ns:
        nxt = now_ns + period_ns - (now_ns - due_ns) % period_ns
    return nxt
