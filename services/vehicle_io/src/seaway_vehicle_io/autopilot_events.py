"""The MAVLink events protocol: what PX4 says (why it refuses to arm) in EVENT messages, as text.

PX4 (1.13 and later) reports arming-check failures, and most of what it has to say, as EVENT
(#410) messages instead of STATUSTEXT: a 32-bit id and up to 40 bytes of packed arguments, whose
meaning is in the firmware's events metadata (``all_events.json``, fetched from the autopilot:
``component_metadata.py``). This module is that dictionary and a tracker of what was said. Pure:
time comes in as monotonic nanoseconds.

Measured against PX4 SITL (release/1.18, differential rover): an arm refused in MANUAL right after
boot gives COMMAND_ACK TEMPORARILY_REJECTED and, in the same millisecond, the event
``commander_arm_denied_resolve_failures`` ("Arming denied: Resolve system health failures first");
about 1 s later the arming-check report: ``commander_arming_check_summary`` followed by one event
per failing check (``check_estimator_heading_no_source``: "No heading reference", ...), each with
the navigation modes it blocks as its first argument. The reason passed on is the denial and the
failures that block the mode the vehicle is in.

Metadata layout (libevents): ``components[<component id>]`` has a ``namespace``, ``enums`` and
``event_groups[<group>].events[<sub id>]`` = {name, message, arguments: [{name, type}]}; the id on
the wire is ``component id << 24 | sub id``. Arguments are packed little-endian, in order. A
message's ``{N}`` (1-based) is argument N, optionally with a format (``{3:.1m/s}``: one decimal, unit
m/s) or a unit suffix (``{2m}``). ``navigation_mode_groups.groups[<bit>]`` lists the custom modes
(HEARTBEAT ``custom_mode``) in the mode group of that bit of a ``navigation_mode_group_t``.
"""

from __future__ import annotations

import json
import lzma
import re
import struct
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from seaway_vehicle_io.component_metadata import unpack_file

BASE_TYPES: dict[str, str] = {
    "uint8_t": "B", "int8_t": "b", "uint16_t": "H", "int16_t": "h", "uint32_t": "I",
    "int32_t": "i", "uint64_t": "Q", "int64_t": "q", "float": "f",
}
ARGUMENTS_LEN = 40  # EVENT.arguments
LOG_LEVELS = ("emergency", "alert", "critical", "error", "warning", "notice", "info", "debug",
              "protocol", "disabled")
ARMING_GROUP = "arming_check"
REPORT_GROUPS = frozenset({ARMING_GROUP, "health"})  # failures listed in an arming-check report
SUMMARY_SUFFIX = "arming_check_summary"
DENIAL_MARK = "arm_denied"  # commander_arm_denied_*: the verdict on an arm request
MODES_ARGUMENT = "modes"
KEEP = 64  # decoded events remembered
MAX_MISSING = 32
"""Lost events asked for again at most (a longer gap is a reboot's new count, or too old for the
autopilot's buffer: PX4 keeps its recent events for a REQUEST_EVENT)."""
SEEN_KEPT = 256  # sequence numbers remembered to tell a repeat from a restarted count
REPORT_FAILURES_KEPT = 64
"""Failures one arming-check report keeps (PX4 lists a few dozen checks at most): an autopilot
that never sends the next summary must not grow the report for ever."""


class MetadataError(ValueError):
    """Events metadata that cannot be read; the text says what is wrong with it."""


@dataclass(frozen=True)
class EnumDef:
    base: str  # one of BASE_TYPES
    entries: dict[int, str]  # value -> description (or name when there is none)
    bitfield: bool


@dataclass(frozen=True)
class EventDef:
    name: str
    message: str
    group: str
    arguments: tuple[tuple[str, str], ...]  # (name, type) in wire order
    namespace: str


@dataclass(frozen=True)
class Event:
    """One decoded EVENT."""

    mono_ns: int
    sequence: int
    event_id: int
    name: str  # "" when the catalog does not know the id
    text: str
    group: str
    level: int  # external log level: 0 emergency ... 7 debug (LOG_LEVELS)
    modes: int | None  # the navigation_mode_group_t bits it concerns (arming checks), if any

    @property
    def is_error(self) -> bool:
        """Error or worse: what stops an arm (PX4 reports blocking checks at level error)."""
        return self.level <= 3


def _strip_tags(text: str) -> str:
    return re.sub(r"<[^>]+>", "", text).strip()


class EventCatalog:
    """Event id -> what it means, from a firmware's events metadata."""

    def __init__(self, events: dict[int, EventDef], enums: dict[tuple[str, str], EnumDef],
                 mode_groups: dict[int, frozenset[int]]) -> None:
        self.events = events
        self.enums = enums  # (namespace, enum name) -> definition
        self.mode_groups = mode_groups  # group bit -> custom_mode values in it

    @classmethod
    def from_bytes(cls, data: bytes) -> EventCatalog:
        """``all_events.json`` as the autopilot holds it (xz-compressed or plain JSON)."""
        try:
            doc = json.loads(unpack_file(data))
        except (lzma.LZMAError, ValueError) as err:
            raise MetadataError(f"events metadata is neither JSON nor xz-compressed JSON: {err}") \
                from None
        return cls.from_json(doc)

    @classmethod
    def from_json(cls, doc: Any) -> EventCatalog:
        if not isinstance(doc, dict) or not isinstance(doc.get("components"), dict):
            raise MetadataError("events metadata has no 'components' object (libevents format)")
        events: dict[int, EventDef] = {}
        enums: dict[tuple[str, str], EnumDef] = {}
        mode_groups: dict[int, frozenset[int]] = {}
        try:
            for comp_id, comp in doc["components"].items():
                namespace = str(comp.get("namespace", ""))
                for enum_name, enum in (comp.get("enums") or {}).items():
                    if enum.get("type") not in BASE_TYPES:
                        continue
                    enums[(namespace, enum_name)] = EnumDef(
                        enum["type"],
                        {int(k): str(v.get("description") or v.get("name", k))
                         for k, v in enum.get("entries", {}).items()},
                        bool(enum.get("is_bitfield")))
                for group, body in (comp.get("event_groups") or {}).items():
                    for sub_id, ev in (body.get("events") or {}).items():
                        full = (int(comp_id) << 24) | int(sub_id)
                        events[full] = EventDef(
                            str(ev.get("name", "")), str(ev.get("message", "")), str(group),
                            tuple((str(a["name"]), str(a["type"]))
                                  for a in ev.get("arguments", [])), namespace)
                groups = (comp.get("navigation_mode_groups") or {}).get("groups") or {}
                for bit, modes in groups.items():
                    mode_groups[int(bit)] = frozenset(int(m) for m in modes)
        except (AttributeError, KeyError, TypeError, ValueError) as err:
            raise MetadataError(f"events metadata malformed: {err!r}") from None
        if not events:
            raise MetadataError("events metadata defines no events")
        return cls(events, enums, mode_groups)

    def _enum(self, namespace: str, type_name: str) -> EnumDef | None:
        ns, _, name = type_name.rpartition("::")
        return self.enums.get((ns or namespace, name))

    def decode_arguments(self, ev: EventDef, raw: bytes) -> list[Any]:
        """The arguments' values in order (enum values as their integer); short data ends them."""
        values: list[Any] = []
        offset = 0
        for _, type_name in ev.arguments:
            enum = None if type_name in BASE_TYPES else self._enum(ev.namespace, type_name)
            base = type_name if enum is None else enum.base
            code = BASE_TYPES.get(base)
            if code is None:
                break  # a type we cannot size: the rest cannot be located
            size = struct.calcsize("<" + code)
            if offset + size > len(raw):
                break
            values.append(struct.unpack_from("<" + code, raw, offset)[0])
            offset += size
        return values

    def format(self, ev: EventDef, values: list[Any]) -> str:
        """The event's message with its arguments filled in."""

        def fill(match: re.Match[str]) -> str:
            index = int(match.group(1)) - 1
            spec = match.group(2) or ""
            if not 0 <= index < len(values) or index >= len(ev.arguments):
                return match.group(0)
            value = values[index]
            enum = self._enum(ev.namespace, ev.arguments[index][1])
            if enum is not None:
                if enum.bitfield:
                    names = [d for bit, d in sorted(enum.entries.items()) if bit and value & bit]
                    return ", ".join(names) or "none"
                return enum.entries.get(int(value), str(value))
            precision = re.match(r":\.(\d+)", spec)
            unit = re.sub(r"^:?(\.\d+)?", "", spec).split("_")[0]
            if precision and isinstance(value, float):
                text = f"{value:.{int(precision.group(1))}f}"
            elif isinstance(value, float):
                text = f"{value:g}"
            else:
                text = str(value)
            return f"{text} {unit}" if unit else text

        return _strip_tags(re.sub(r"\{(\d+)([^}]*)\}", fill, ev.message))

    def decode(self, event_id: int, raw: bytes, log_levels: int, sequence: int,
               mono_ns: int) -> Event:
        ev = self.events.get(event_id)
        level = log_levels & 0x0F
        if ev is None:
            return Event(mono_ns, sequence, event_id, "", f"event {event_id:#x} (not in the "
                         "autopilot's events metadata)", "", level, None)
        values = self.decode_arguments(ev, raw)
        modes = None
        if ev.arguments and ev.arguments[0][0] == MODES_ARGUMENT and values:
            modes = int(values[0])
        return Event(mono_ns, sequence, event_id, ev.name, self.format(ev, values), ev.group,
                     level, modes)

    def mode_bit(self, custom_mode: int) -> int | None:
        """The navigation_mode_group_t bit of the group holding ``custom_mode``, if one does."""
        for bit, modes in self.mode_groups.items():
            if custom_mode in modes:
                return bit
        return None


@dataclass
class ArmingReport:
    """One arming-check report: the summary's arrival and the failures listed after it."""

    mono_ns: int
    failures: list[Event] = field(default_factory=list)


class EventTracker:
    """The decoded events of one autopilot, and its latest arming-check report."""

    def __init__(self, catalog: EventCatalog | None = None) -> None:
        self.catalog = catalog
        self.recent: deque[Event] = deque(maxlen=KEEP)
        self.report: ArmingReport | None = None
        self.undecoded = 0  # EVENTs that arrived before the catalog did
        self.last_sequence: int | None = None
        self.lost = 0  # events skipped in the sequence (a gap: lost on the link)
        self.missing: set[int] = set()
        """Sequence numbers skipped (lost on the link) that a REQUEST_EVENT may still bring."""
        self.recovered = 0  # missing events that came after all (re-sent on request)
        self.to_ask: tuple[int, int] | None = None
        """The latest gap (first, last sequence) not yet asked for (``EventsChannel``)."""
        # The event id of each sequence number taken lately (the last SEEN_KEPT): a repeat is one
        # of these again, while a sequence behind the count that was never taken is a new count.
        self._seen: dict[int, int] = {}
        self._seen_order: deque[int] = deque()

    def note_sequence(self, sequence: int) -> tuple[int, int] | None:
        """The autopilot's latest event is ``sequence`` (an EVENT's, or CURRENT_EVENT_SEQUENCE's):
        the (first, last) sequence numbers it reveals as lost, if any, now ``missing``. A jump back
        or of more than ``MAX_MISSING`` (a reboot restarts the count) asks for nothing."""
        last, self.last_sequence = self.last_sequence, sequence
        if last is None:
            return None
        gap = (sequence - last - 1) & 0xFFFF
        if gap == 0 or gap >= 0x8000:
            if gap >= 0x8000 and (last - sequence) & 0xFFFF > MAX_MISSING:
                self.missing.clear()  # the count restarted: nothing old can be asked for
            elif gap >= 0x8000:
                self.last_sequence = last  # an old one again (re-sent): the newest stays
            return None
        self.lost += gap
        if gap > MAX_MISSING:
            return None
        first = (last + 1) & 0xFFFF
        self.missing.update((first + k) & 0xFFFF for k in range(gap))
        while len(self.missing) > MAX_MISSING:
            self.missing.discard(min(self.missing))
        self.to_ask = (first, (sequence - 1) & 0xFFFF)
        return self.to_ask

    def on_event(self, event_id: int, raw: bytes, log_levels: int, sequence: int,
                 mono_ns: int) -> Event | None:
        """One EVENT message; the decoded event, or None when there is no catalog yet or it was
        handled already (a repeat). One that was ``missing`` is taken, late."""
        if sequence in self.missing:
            self.missing.discard(sequence)
            self.recovered += 1
        elif self.last_sequence is not None and (
                (sequence - self.last_sequence - 1) & 0xFFFF) >= 0x8000:
            if self._seen.get(sequence) == event_id:
                return None  # a repeat (re-sent on request): already handled
            # Behind the count, and never taken: the autopilot's count restarted (it rebooted,
            # perhaps while the link was down and the old count was carried over).
            self.missing.clear()
            self.last_sequence = sequence
        else:
            self.note_sequence(sequence)
        self._remember(sequence, event_id)
        if self.catalog is None:
            self.undecoded += 1
            return None
        ev = self.catalog.decode(event_id, raw, log_levels, sequence, mono_ns)
        self.recent.append(ev)
        if ev.name.endswith(SUMMARY_SUFFIX):
            self.report = ArmingReport(mono_ns)
        elif (ev.group in REPORT_GROUPS and ev.modes is not None and self.report is not None
              and len(self.report.failures) < REPORT_FAILURES_KEPT):
            self.report.failures.append(ev)
        return ev

    def _remember(self, sequence: int, event_id: int) -> None:
        if sequence not in self._seen:
            self._seen_order.append(sequence)
            if len(self._seen_order) > SEEN_KEPT:
                self._seen.pop(self._seen_order.popleft(), None)
        self._seen[sequence] = event_id

    def denials_since(self, mono_ns: int) -> list[str]:
        """What the autopilot said about an arm request since ``mono_ns``: its denials."""
        out: list[str] = []
        for ev in self.recent:
            if ev.mono_ns >= mono_ns and DENIAL_MARK in ev.name and ev.text not in out:
                out.append(ev.text)
        return out

    def blocking(self, custom_mode: int | None) -> list[str]:
        """The failures of the latest arming-check report that block ``custom_mode`` (all error
        level ones when the mode's group is unknown)."""
        if self.report is None:
            return []
        bit = None
        if custom_mode is not None and self.catalog is not None:
            bit = self.catalog.mode_bit(custom_mode)
        out: list[str] = []
        for ev in self.report.failures:
            blocks = (ev.modes is not None and bool(ev.modes & (1 << bit))) if bit is not None \
                else ev.is_error
            if blocks and ev.text not in out:
                out.append(ev.text)
        return out

    def refusal(self, since_mono_ns: int, custom_mode: int | None) -> tuple[list[str], bool]:
        """Why an arm sent at ``since_mono_ns`` was refused: the denial, then each failing check
        for the current mode; and whether that is complete (a report arrived after the request, so
        the checks are the ones that refused it)."""
        denials = self.denials_since(since_mono_ns)
        report_fresh = self.report is not None and self.report.mono_ns >= since_mono_ns
        return denials + self.blocking(custom_mode), bool(denials) and report_fresh
