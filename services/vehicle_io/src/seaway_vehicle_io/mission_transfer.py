"""MAVLink's mission protocol, one transfer at a time: upload a list of items of one mission type
(fence, rally, mission), or download the autopilot's list. Pure: messages and time in, messages out.

Upload (we are the sender; https://mavlink.io/en/services/mission.html)::

    -> MISSION_COUNT(count, type)
    <- MISSION_REQUEST_INT(seq) or MISSION_REQUEST(seq)    any order, repeats allowed
    -> MISSION_ITEM_INT(seq)
    ...
    <- MISSION_ACK(type, result)                           ACCEPTED: done; anything else: refused

Download (we are the receiver)::

    -> MISSION_REQUEST_LIST(type)
    <- MISSION_COUNT(count)
    -> MISSION_REQUEST_INT(0) ... <- MISSION_ITEM_INT(0) ... (in order)
    -> MISSION_ACK(ACCEPTED)

Timeouts: when nothing of this transfer arrives for ``timeout_ns`` after our last send, the last
message is sent again (MISSION_COUNT until the first request, else the item or request in
flight), up to ``attempts`` sends of it; then the transfer fails with what it waited for. A
MISSION_ACK that is not ACCEPTED ends an upload with the autopilot's MAV_MISSION_RESULT name
(NO_SPACE: more items than it stores).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from seaway_vehicle_io.mav import mavlink

MAV_MISSION_ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
TYPE_NAMES = {mavlink.MAV_MISSION_TYPE_MISSION: "mission", mavlink.MAV_MISSION_TYPE_FENCE: "fence",
              mavlink.MAV_MISSION_TYPE_RALLY: "rally"}
TRANSFER_MESSAGES = frozenset({"MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK",
                               "MISSION_COUNT", "MISSION_ITEM_INT"})
"""The MAVLink messages a transfer reads (the core routes them here)."""


@dataclass(frozen=True)
class MissionItem:
    """One MISSION_ITEM_INT as it goes on the wire: ``lat_e7``/``lon_e7`` are degrees x 1e7."""

    command: int
    frame: int
    param1: float
    lat_e7: int
    lon_e7: int
    z: float = 0.0


# -- outputs (sent by the link) ---------------------------------------------------------------------


@dataclass(frozen=True)
class SendMissionCount:
    target_system: int
    target_component: int
    count: int
    mission_type: int


@dataclass(frozen=True)
class SendMissionItemInt:
    target_system: int
    target_component: int
    seq: int
    item: MissionItem
    mission_type: int


@dataclass(frozen=True)
class SendMissionRequestList:
    target_system: int
    target_component: int
    mission_type: int


@dataclass(frozen=True)
class SendMissionRequestInt:
    target_system: int
    target_component: int
    seq: int
    mission_type: int


@dataclass(frozen=True)
class SendMissionAck:
    target_system: int
    target_component: int
    result: int
    mission_type: int


TransferOutput = (SendMissionCount | SendMissionItemInt | SendMissionRequestList
                  | SendMissionRequestInt | SendMissionAck)


def mission_result_name(result: int) -> str:
    """MAV_MISSION_RESULT number -> name without the prefix, e.g. 4 -> 'NO_SPACE'."""
    entry = mavlink.enums["MAV_MISSION_RESULT"].get(result)
    if entry is None or entry.name.endswith("_ENUM_END"):
        return f"UNKNOWN_RESULT_{result}"
    return entry.name.removeprefix("MAV_MISSION_")


def item_of(msg: Any) -> MissionItem:
    """A received MISSION_ITEM_INT as a ``MissionItem``."""
    return MissionItem(int(msg.command), int(msg.frame), float(msg.param1), int(msg.x), int(msg.y),
                       float(msg.z))


class Transfer:
    """One upload or download of one mission type to one autopilot (see the module docstring).

    ``result`` is None while it runs; then ``"ok"`` or the reason it failed. ``items`` holds the
    downloaded list once a download is ok."""

    def __init__(self, target: tuple[int, int], mission_type: int, timeout_ns: int, attempts: int,
                 upload: tuple[MissionItem, ...] | None = None) -> None:
        self.target = target
        self.mission_type = mission_type
        self.timeout_ns = timeout_ns
        self.attempts = attempts
        self.upload = upload
        self.result: str | None = None
        self.items: list[MissionItem] = []
        self.expected: int | None = None  # download: the count the autopilot announced
        self.requested: set[int] = set()  # upload: the items asked for so far
        self._last: TransferOutput | None = None
        self._sent_ns = 0
        self._sends = 0

    @property
    def kind(self) -> str:
        return f"{TYPE_NAMES.get(self.mission_type, str(self.mission_type))} " + (
            "upload" if self.upload is not None else "download")

    def start(self, now_ns: int) -> list[TransferOutput]:
        ts, tc = self.target
        if self.upload is not None:
            first: TransferOutput = SendMissionCount(ts, tc, len(self.upload), self.mission_type)
        else:
            first = SendMissionRequestList(ts, tc, self.mission_type)
        return self._send(first, now_ns)

    def on_mavlink(self, msg: Any, now_ns: int) -> list[TransferOutput]:
        """A mission-protocol message from the autopilot (others' types are ignored)."""
        if self.result is not None or getattr(msg, "mission_type", 0) != self.mission_type:
            return []
        mtype = msg.get_type()
        if self.upload is not None:
            return self._upload_step(mtype, msg, now_ns)
        return self._download_step(mtype, msg, now_ns)

    def tick(self, now_ns: int) -> list[TransferOutput]:
        """Resend what is unanswered after ``timeout_ns``; fail after ``attempts`` sends."""
        if self.result is not None or self._last is None or now_ns < self.next_due_ns():
            return []
        if self._sends >= self.attempts:
            self.result = (f"{self.kind}: no answer to {_describe(self._last)} after "
                           f"{self._sends} attempts of {self.timeout_ns / 1e9:g} s")
            return []
        return self._send(self._last, now_ns, again=True)

    def next_due_ns(self) -> int:
        return self._sent_ns + self.timeout_ns

    # -- the two directions -------------------------------------------------------------------------

    def _upload_step(self, mtype: str, msg: Any, now_ns: int) -> list[TransferOutput]:
        assert self.upload is not None
        ts, tc = self.target
        if mtype in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            seq = int(msg.seq)
            if not 0 <= seq < len(self.upload):
                self.result = (f"{self.kind}: the autopilot asked for item {seq} of "
                               f"{len(self.upload)}")
                return [SendMissionAck(ts, tc, mavlink.MAV_MISSION_INVALID_SEQUENCE,
                                       self.mission_type)]
            self.requested.add(seq)
            return self._send(SendMissionItemInt(ts, tc, seq, self.upload[seq], self.mission_type),
                              now_ns)
        if mtype == "MISSION_ACK":
            result = int(msg.type)
            if result != MAV_MISSION_ACCEPTED:
                self.result = f"{self.kind} refused by the autopilot: {mission_result_name(result)}"
            elif len(self.requested) < len(self.upload):
                # An ACCEPTED before every item was asked for is not this upload's end (an ACK
                # left over from an earlier transfer); keep waiting.
                return []
            else:
                self.result = "ok"
        return []

    def _download_step(self, mtype: str, msg: Any, now_ns: int) -> list[TransferOutput]:
        ts, tc = self.target
        if mtype == "MISSION_COUNT" and self.expected is None:
            self.expected = int(msg.count)
            if self.expected == 0:
                self.result = "ok"
                return [SendMissionAck(ts, tc, MAV_MISSION_ACCEPTED, self.mission_type)]
            return self._send(SendMissionRequestInt(ts, tc, 0, self.mission_type), now_ns)
        if mtype == "MISSION_ITEM_INT" and self.expected is not None:
            if int(msg.seq) != len(self.items):
                return []  # a repeat or one out of order: the request in flight gets resent
            self.items.append(item_of(msg))
            if len(self.items) == self.expected:
                self.result = "ok"
                self._last = None
                return [SendMissionAck(ts, tc, MAV_MISSION_ACCEPTED, self.mission_type)]
            return self._send(SendMissionRequestInt(ts, tc, len(self.items), self.mission_type),
                              now_ns)
        if mtype == "MISSION_ACK" and int(msg.type) != MAV_MISSION_ACCEPTED:
            self.result = f"{self.kind} refused by the autopilot: {mission_result_name(int(msg.type))}"
        return []

    def _send(self, out: TransferOutput, now_ns: int, again: bool = False) -> list[TransferOutput]:
        self._sends = self._sends + 1 if again or out == self._last else 1
        self._last = out
        self._sent_ns = now_ns
        return [out]


def _describe(out: TransferOutput) -> str:
    if isinstance(out, SendMissionCount):
        return f"MISSION_COUNT {out.count}"
    if isinstance(out, SendMissionItemInt):
        return f"MISSION_ITEM_INT {out.seq}"
    if isinstance(out, SendMissionRequestInt):
        return f"MISSION_REQUEST_INT {out.seq}"
    if isinstance(out, SendMissionRequestList):
        return "MISSION_REQUEST_LIST"
    return type(out).__name__
