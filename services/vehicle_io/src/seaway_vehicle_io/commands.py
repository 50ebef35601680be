"""COMMAND_LONG bookkeeping: which commands are in flight and what their COMMAND_ACK said.

MAVLink's command protocol (https://mavlink.io/en/services/command.html) allows one command of a
given id in flight per target; a sender resends after a timeout with ``confirmation`` incremented,
and MAV_RESULT_IN_PROGRESS (5) means "wait, do not resend". This class is pure state; the service
loop does the waiting.
"""

from __future__ import annotations

from dataclasses import dataclass

MAV_RESULT_ACCEPTED = 0
MAV_RESULT_IN_PROGRESS = 5

MAV_CMD_DO_SET_MODE = 176
MAV_CMD_COMPONENT_ARM_DISARM = 400
COMMAND_NAMES = {MAV_CMD_DO_SET_MODE: "DO_SET_MODE",
                 MAV_CMD_COMPONENT_ARM_DISARM: "COMPONENT_ARM_DISARM"}


@dataclass
class Pending:
    command: int
    target_system: int
    result: int | None = None
    in_progress: bool = False


class CommandTracker:
    """Commands awaiting COMMAND_ACK, keyed by command id."""

    def __init__(self) -> None:
        self._pending: dict[int, Pending] = {}

    def begin(self, command: int, target_system: int) -> None:
        self._pending[command] = Pending(command, target_system)

    def on_ack(self, command: int, result: int, src_system: int, ack_target_system: int,
               our_system: int) -> bool:
        """Record an ACK; True if it answered a pending command of ours.

        ``ack_target_system`` is a MAVLink 2 extension: 0 when the autopilot does not fill it,
        otherwise it must be us (another GCS's ACK is not ours).
        """
        p = self._pending.get(command)
        if p is None or src_system != p.target_system:
            return False
        if ack_target_system not in (0, our_system):
            return False
        if result == MAV_RESULT_IN_PROGRESS:
            p.in_progress = True
            return True
        p.result = result
        return True

    def state(self, command: int) -> Pending | None:
        return self._pending.get(command)

    def finish(self, command: int) -> None:
        self._pending.pop(command, None)

    def abandon_all(self) -> None:
        """Forget every command (link lost: their ACKs can no longer be trusted to come)."""
        self._pending.clear()
