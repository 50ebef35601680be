"""What the autopilot says, heard by the core: STATUSTEXT and the events protocol (PX4's EVENTs, their
metadata fetched over COMPONENT_METADATA and MAVLink FTP).

Texts are logged (rate-limited), told to the fence sync and the hold-reason tracker, and kept
(monotonic time) so that a refused arm can be answered with the autopilot's own reason
(``refusal_texts``). A battery failsafe said in a STATUSTEXT is latched until a reboot.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from seaway_vehicle_io.conversions import BatteryReading, battery_level_from_text, worse_level
from seaway_vehicle_io.core_outputs import Now, Output
from seaway_vehicle_io.events_channel import EventsChannel, SendRequestEvent
from seaway_vehicle_io.failsafe_cause import (
    EVENT_WARNING_LEVEL,
    WARNING_SEVERITY,
    FailsafeCause,
    classify_text,
    cleared_cause,
)
from seaway_vehicle_io.statustext import StatusText, StatusTexts, matching

if TYPE_CHECKING:
    from seaway.contract.messages import BatteryLevel

    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.fence_sync import FenceSync

log = logging.getLogger("seaway.vehicle_io")


class AutopilotSaid:
    """The autopilot's-words part of ``VehicleIoCore``: owns the kept STATUSTEXTs and the events
    channel (anew per connection)."""

    # read from the other parts
    cfg: VehicleIoConfig
    link: LinkState
    fence: FenceSync | None
    hold: FailsafeCause
    battery_said: tuple[BatteryLevel, str] | None
    autopilot_starting: Callable[[Now], bool]

    def _init_said(self) -> None:
        self.texts = StatusTexts()
        self.events = EventsChannel()  # the events protocol (PX4's arming reasons), per connection

    def _on_statustext(self, msg: Any, now: Now) -> list[Output]:
        out: list[Output] = []
        for item in self.texts.add(msg.severity, msg.text, now.mono_ns,
                                   getattr(msg, "id", 0) or 0, getattr(msg, "chunk_seq", 0) or 0):
            out += self._said_text(item, now)
        return out

    def _said_texts_due(self, now: Now) -> list[Output]:
        """A held text (``StatusTexts.due``) whose continuation did not come: said now."""
        out: list[Output] = []
        for item in self.texts.due(now.mono_ns):
            out += self._said_text(item, now)
        return out

    def _said_text(self, item: StatusText, now: Now) -> list[Output]:
        """One complete text: logged, and what it says of the fence, a hold and the battery. A
        text PX4 also says in an EVENT (``StatusText.also_an_event``) is logged at DEBUG once its
        events are decoded: the EVENT is said, as a ground station that decodes them does."""
        # MAV_SEVERITY <= 4 is a warning or worse (PreArm failures are 2, CRITICAL)
        log_level = logging.WARNING if item.severity <= 4 else logging.INFO
        if item.also_an_event and self.events.catalog is not None:
            log_level = logging.DEBUG
        elif log_level == logging.WARNING and self._a_start_check(item.text, now):
            log_level = logging.INFO
        self._log_said(now, "STATUSTEXT", item.text, log_level)
        if self.fence is not None:
            self.fence.on_text(item.text)
        self._hold_changed(self.hold.cleared(cleared_cause(item.text), item.text, now.mono_ns),
                           now)
        if item.severity <= WARNING_SEVERITY:
            self._hold_changed(self.hold.said(classify_text(item.text), item.text,
                                              now.mono_ns), now)
            level = battery_level_from_text(item.text)
            if level is not None:
                # Latched: ArduPilot says it once, and its battery failsafe holds till reboot.
                self.battery_said = (worse_level(level, None if self.battery_said is None
                                                 else self.battery_said[0]) or level, item.text)
                return self._on_battery(BatteryReading(), now)
        return []

    def _a_start_check(self, text: str, now: Now) -> bool:
        """A check the autopilot fails while it starts (ArduPilot "PreArm:"/"Arm:", PX4
        "Preflight Fail:"; ``Profile.start_check_prefixes``): its expected state until its
        estimator has converged, said in the status, and again in a refused arm's reply."""
        profile = self.link.profile
        return (profile is not None and text.startswith(profile.start_check_prefixes)
                and self.autopilot_starting(now))

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
            self._log_said(now, "EVENT", ev.text, logging.WARNING if ev.level <= 4 else logging.INFO)
        if ev is not None and self.fence is not None:
            self.fence.on_text(ev.text)
        if ev is not None and ev.level <= EVENT_WARNING_LEVEL:
            self._hold_changed(self.hold.said(classify_text(ev.text), ev.text, now.mono_ns), now)
        return said_asking(asks)

    def _on_current_event_sequence(self, msg: Any, now: Now) -> list[Output]:
        if self.link.profile is None or not self.link.profile.events_protocol:
            return []
        return said_asking(self.events.on_current_sequence(int(msg.sequence), int(msg.flags),
                                                            now.mono_ns))

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


def said_asking(sends: list[Any]) -> list[Output]:
    """``sends``, each REQUEST_EVENT among them logged: events lost on the link asked for again."""
    for s in sends:
        if isinstance(s, SendRequestEvent):
            log.info("asking the autopilot again for its events %d-%d, lost on the link",
                     s.first_sequence, s.last_sequence)
    return list(sends)
