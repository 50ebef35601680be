"""The core's side of the arm and mode requests: the COMMAND_LONG to send (or why not), the state
an accepted one sets, and the COMMAND_ACKs routed to whoever waits for them.

The loop sends the returned command and waits for its ACK (``commands.CommandTracker``);
vehicle_io never arms, disarms or changes mode by itself.
"""

from __future__ import annotations

import logging
from typing import TYPE_CHECKING, Any

from seaway_vehicle_io.commands import (
    COMMAND_NAMES,
    MAV_CMD_COMPONENT_ARM_DISARM,
    MAV_CMD_DO_SET_MODE,
    CommandTracker,
)
from seaway_vehicle_io.component_metadata import MAV_CMD_REQUEST_MESSAGE
from seaway_vehicle_io.core_outputs import Now, Output, SendCommandLong
from seaway_vehicle_io.rates import MAV_CMD_SET_MESSAGE_INTERVAL

if TYPE_CHECKING:
    from seaway_vehicle_io.config import VehicleIoConfig
    from seaway_vehicle_io.core_link import LinkState
    from seaway_vehicle_io.events_channel import EventsChannel
    from seaway_vehicle_io.failsafe_cause import FailsafeCause
    from seaway_vehicle_io.rates import RateCheck

log = logging.getLogger("seaway.vehicle_io")


class Requests:
    """The requests part of ``VehicleIoCore``: owns the commands awaiting an ACK and the mode last
    asked for (until the autopilot is seen in it)."""

    # read from the other parts
    cfg: VehicleIoConfig
    link: LinkState
    hold: FailsafeCause
    events: EventsChannel
    rate_check: RateCheck | None

    def _init_requests(self) -> None:
        self.commands = CommandTracker()
        self._mode_asked: str | None = None  # the mode vehicle_io last asked for, until it is seen

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
