"""The core's autopilot link: locking to the first autopilot HEARTBEAT, following its armed state
and mode, and declaring it lost after ``heartbeat_timeout_s`` of silence (monotonic time).

``LinkState`` is what we know about the autopilot we command (its ids, peer address, profile,
armed, mode). A loss forgets everything learnt from that autopilot, every part's included: it may
come back rebooted, with another id, from another port, or be another autopilot altogether. A mode
change the vessel made while unheard, or unasked while heard, is the autopilot's own (its
failsafe), told to the hold-reason tracker (``failsafe_cause``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from seaway_vehicle_io import profile as profiles
from seaway_vehicle_io.authority import Address, SourcePolicy, address_key
from seaway_vehicle_io.autopilot_health import Health
from seaway_vehicle_io.conversions import BatteryReading
from seaway_vehicle_io.core_outputs import LockPeer, Now, Output
from seaway_vehicle_io.core_params import ParamCheck
from seaway_vehicle_io.events_channel import EventsChannel
from seaway_vehicle_io.failsafe_cause import FailsafeCause
from seaway_vehicle_io.profile import Profile

if TYPE_CHECKING:
    from seaway_vehicle_io.commands import CommandTracker
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.statustext import StatusTexts
    from seaway_vehicle_io.timesync import BootTimeOffset

log = logging.getLogger("seaway.vehicle_io")

MAV_MODE_FLAG_SAFETY_ARMED = 128
# HEARTBEAT.type values that are not a vehicle (GCS, onboard controller, gimbal, ADSB, camera...).
NON_VEHICLE_TYPES = frozenset({6, 18, 26, 27, 30, 31})


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


class LinkWatch:
    """The link part of ``VehicleIoCore``: owns ``link``, ``forced_profile`` and what was known
    when the link was lost (``_before_loss``). A connection starts the other parts' work (the
    parameter read, the rate request, the events fetch); a loss resets them all."""

    # read (and, on a connection or a loss, reset) from the other parts
    cfg: VehicleIoConfig
    policy: SourcePolicy
    verifier: object | None  # the signature verifier (None: signing off)
    counts: dict[str, int]
    health: Health
    _health_said: str | None
    _health_quiet: bool
    hold: FailsafeCause
    texts: StatusTexts
    events: EventsChannel
    offset: BootTimeOffset
    last_boot_ms: dict[str, int]
    commands: CommandTracker
    params: ParamCheck
    mapper: Any

    def _init_link(self, config: VehicleIoConfig) -> None:
        self.forced_profile = (profiles.by_name(config.autopilot)
                               if config.autopilot != profiles.AUTO else None)
        self.link = LinkState(profile=self.forced_profile)
        # (mode, armed, last HEARTBEAT [mono ns], address) when the link was lost: a mode changed
        # meanwhile was not Seaway's
        self._before_loss: tuple[str, bool, int, Address] | None = None

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
        if self.thrust_withheld() != self._withheld:  # armed, disarmed, another mode: say so now,
            return self._say_status(now)  # or at the gap's end if the autopilot flaps (pacing)
        return []

    def _connect(self, msg: Any, profile: Profile, now: Now, address: Address) -> list[Output]:
        link = self.link
        link.ok = True
        link.target_system, link.target_component = msg.get_srcSystem(), msg.get_srcComponent()
        link.target_address = address
        link.profile = profile
        link.connects += 1
        self.health = Health(px4=profile.name == "px4", since_mono_ns=now.mono_ns)
        self.counts["HEARTBEAT"] = self.counts.get("HEARTBEAT", 0) + 1
        self._apply_heartbeat(msg, now, announce=False)  # the line below says it all
        before, self._before_loss = self._before_loss, None
        if (before is not None and before[1] and link.armed and link.mode != before[0]
                and link.mode not in profile.booting_modes):
            # Still armed, so not rebooted: the autopilot changed mode while unheard (its failsafe)
            self._hold_changed(self.hold.mode_changed_unheard(
                before[0], link.mode, (now.mono_ns - before[2]) / 1e9, now.mono_ns), now)
        log.info("autopilot link up: %s system %d component %d at %s, %s, %s (connection #%d); "
                 "locked to that source: MAVLink from any other is refused%s", profile.name,
                 link.target_system, link.target_component, address_key(address),
                 "ARMED" if link.armed else "disarmed", link.mode, link.connects,
                 ", signing on" if self.verifier is not None else "")
        self._start_param_check(profile)
        self.mapper = None if self.cfg.check_failsafe_params else profile.mapper({})
        self.texts.clear()
        out: list[Output] = [LockPeer(address), *self._say_status(now)]
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
            self._log_change(now, "state", logging.INFO,
                             f"autopilot {'ARMED' if armed else 'disarmed'}, mode {mode}")
        if announce and mode != link.mode:
            if mode == self._mode_asked:
                self._mode_asked = None
            elif mode in link.profile.booting_modes:
                # Back in its start-up mode: a reboot faster than the link timeout, nobody's mode
                # change; the rebooted autopilot has no failsafe standing either.
                self._log_change(now, "rebooted", logging.WARNING,
                                 f"autopilot back in {mode}: it rebooted")
                self.hold = FailsafeCause()
            elif link.mode not in link.profile.booting_modes and link.mode != "UNKNOWN":
                self._hold_changed(self.hold.mode_changed(link.mode, mode, now.mono_ns, armed), now)
        if (link.mode in link.profile.booting_modes and mode not in link.profile.booting_modes
                and self.cfg.check_failsafe_params):
            # Read during start-up, some values were not final yet (measured: Rover answered
            # RC1_DZ = 0 before setting its 30 us default): read them all again now.
            self._log_change(now, "started", logging.INFO, f"autopilot finished starting "
                             f"({link.mode} -> {mode}): reading its parameters again")
            self._start_param_check(link.profile)
        elif armed and not link.armed:
            self._armed_now(now)
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
        self.last_boot_ms.clear()
        self.hold = FailsafeCause()
        self.health = Health()
        self._health_said, self._health_quiet = None, False  # the loss is said, not a recovery
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
