"""PX4's events protocol in vehicle_io: the added dialect, the catalog, the tracker, the MAVLink FTP
fetch of the metadata and the core's use of them (pure logic; the firmware itself is met in
tests/system/vehicle_io/test_px4_sitl.py)."""

from __future__ import annotations

import json
import lzma
import os
import struct
from pathlib import Path
from typing import Any

import pytest
from seaway_vehicle_io import component_metadata as cm
from seaway_vehicle_io.autopilot_events import EventCatalog, EventTracker, MetadataError
from seaway_vehicle_io.config import VehicleIoConfig
from seaway_vehicle_io.core import Now, SendCommandLong, VehicleIoCore
from seaway_vehicle_io.dialect import __main__ as dialect_gen
from seaway_vehicle_io.dialect import events as dialect
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.thrust import ThrusterLimits

from tests.conftest import REPO

MS = 1_000_000
MANUAL = 1 << 16  # PX4 custom_mode of MANUAL (main mode 1)
HOLD = 4 << 16 | 3 << 24
PX4_EVENTS = Path(os.environ.get("SEAWAY_PX4_SITL", REPO.parent / "shared" / "sitl" / "px4")) \
    / "etc" / "extras" / "all_events.json.xz"

# A catalog shaped like PX4's (libevents): component 1 "px4", modes as navigation_mode_group_t.
DOC = {
    "version": 2,
    "components": {
        "1": {
            "namespace": "px4",
            "enums": {
                "navigation_mode_group_t": {"type": "uint32_t", "is_bitfield": True, "entries": {
                    "1": {"name": "manual", "description": "Manual"},
                    "16": {"name": "hold", "description": "Hold"}}},
                "sensor_type_t": {"type": "uint8_t", "entries": {
                    "2": {"name": "mag", "description": "Magnetometer"}}},
            },
            "navigation_mode_groups": {"groups": {"0": [MANUAL], "4": [HOLD]}},
            "event_groups": {
                "default": {"events": {
                    "133277": {"name": "commander_arm_denied_resolve_failures",
                               "message": "Arming denied: Resolve system health failures first"},
                    "200": {"name": "wind", "message": "Wind speed is above limit ({1:.1m/s})",
                            "arguments": [{"name": "a", "type": "float"}]},
                    "201": {"name": "sensor", "message": "<param>X</param> {1} failed ({2})",
                            "arguments": [{"name": "t", "type": "px4::sensor_type_t"},
                                          {"name": "n", "type": "int16_t"}]},
                }},
                "arming_check": {"events": {
                    "300": {"name": "commander_arming_check_summary", "message": "summary",
                            "arguments": [{"name": "x", "type": "uint32_t"}]},
                    "301": {"name": "check_estimator_heading_no_source",
                            "message": "No heading reference",
                            "arguments": [{"name": "modes", "type": "navigation_mode_group_t"},
                                          {"name": "health_component_index", "type": "uint8_t"}]},
                    "302": {"name": "check_modes_mission", "message": "No valid mission available",
                            "arguments": [{"name": "modes", "type": "navigation_mode_group_t"},
                                          {"name": "health_component_index", "type": "uint8_t"}]},
                }},
            },
        },
    },
}
CATALOG = EventCatalog.from_json(DOC)


def eid(sub: int) -> int:
    return 1 << 24 | sub


def args(fmt: str, *values: Any) -> bytes:
    return struct.pack("<" + fmt, *values).ljust(40, b"\0")


# -- the dialect -------------------------------------------------------------------------------------


def test_added_messages_have_the_published_crc_extras_and_decode_in_our_dialect():
    published = {397: 182, 410: 160, 411: 106, 412: 33, 413: 77}  # MAVLink's generated C headers
    assert {i: dialect.mavlink_map[i].crc_extra for i in published} == published
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    msg = dialect.MAVLink_event_message(0, 0, eid(301), 1234, 7, 0x33, list(args("IB", 1, 17)))
    got = mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))
    assert got.get_type() == "EVENT" and got.id == eid(301) and got.sequence == 7
    assert bytes(got.arguments)[:5] == args("IB", 1, 17)[:5]


def test_the_committed_dialect_is_what_the_xml_generates(tmp_path):
    generated = dialect_gen.generate(tmp_path / "events.py").read_text()
    assert generated == (Path(dialect.__file__)).read_text(), \
        "events.py is stale: run python -m seaway_vehicle_io.dialect"


# -- the catalog ---------------------------------------------------------------------------------------


def test_catalog_formats_arguments_enums_units_and_tags():
    ev = CATALOG.decode(eid(200), args("f", 12.345), 0x44, 1, 0)
    assert ev.text == "Wind speed is above limit (12.3 m/s)" and ev.level == 4
    ev = CATALOG.decode(eid(201), args("Bh", 2, -3), 0x33, 2, 0)
    assert ev.text == "X Magnetometer failed (-3)"
    ev = CATALOG.decode(eid(301), args("IB", 1 | 16, 17), 0x33, 3, 0)
    assert (ev.name, ev.modes, ev.is_error) == ("check_estimator_heading_no_source", 17, True)
    unknown = CATALOG.decode(eid(999), b"", 0x66, 4, 0)
    assert unknown.name == "" and "0x10003e7" in unknown.text and "not in" in unknown.text


def test_catalog_reads_xz_and_refuses_what_is_not_events_metadata():
    assert len(EventCatalog.from_bytes(lzma.compress(json.dumps(DOC).encode())).events) == 6
    with pytest.raises(MetadataError, match="neither JSON nor xz"):
        EventCatalog.from_bytes(b"\xfd7zXZ\x00garbage")
    with pytest.raises(MetadataError, match="no 'components'"):
        EventCatalog.from_json({"parameters": []})
    with pytest.raises(MetadataError, match="defines no events"):
        EventCatalog.from_json({"components": {"1": {"namespace": "px4"}}})


@pytest.mark.skipif(not PX4_EVENTS.exists(), reason=f"no PX4 events metadata at {PX4_EVENTS}")
def test_px4s_own_metadata_decodes_what_px4_sitl_sent():
    """The bytes PX4 SITL (1.18) sent on a refused arm, decoded with its own all_events.json."""
    cat = EventCatalog.from_bytes(PX4_EVENTS.read_bytes())
    denial = cat.decode(0x102089D, bytes(40), 0x62, 4, 0)
    assert denial.text == "Arming denied: Resolve system health failures first"
    heading = cat.decode(0x1CCDEF5, bytes.fromhex("fc007e0011").ljust(40, b"\0"), 0x33, 6, 0)
    assert heading.text == "No heading reference" and heading.modes == 0x007E00FC
    mission = cat.decode(0x105C2D9, bytes.fromhex("0800000014").ljust(40, b"\0"), 0x66, 10, 0)
    assert mission.modes == 8 and not mission.is_error
    # MANUAL is in group 0, Hold (AUTO.LOITER) in group 4: the heading blocks Hold, not MANUAL
    assert cat.mode_bit(MANUAL) == 0 and cat.mode_bit(HOLD) == 4


# -- the tracker -----------------------------------------------------------------------------------------


def test_refusal_is_the_denial_and_the_checks_blocking_the_current_mode():
    t = EventTracker(CATALOG)
    t.on_event(eid(133277), b"", 0x62, 1, 100 * MS)  # the denial, with the ACK
    said, complete = t.refusal(100 * MS, MANUAL)
    assert said == ["Arming denied: Resolve system health failures first"] and not complete
    t.on_event(eid(300), args("I", 0), 0x88, 2, 1100 * MS)  # the report, ~1 s later
    t.on_event(eid(301), args("IB", 1 | 16, 17), 0x33, 3, 1100 * MS)  # blocks manual and hold
    t.on_event(eid(302), args("IB", 16, 20), 0x66, 4, 1100 * MS)  # blocks hold only
    said, complete = t.refusal(100 * MS, MANUAL)
    assert complete and said == ["Arming denied: Resolve system health failures first",
                                 "No heading reference"]
    assert t.refusal(100 * MS, HOLD)[0][1:] == ["No heading reference",
                                                "No valid mission available"]
    assert t.refusal(100 * MS, 99)[0][1:] == ["No heading reference"]  # unknown mode: errors
    assert t.refusal(2000 * MS, MANUAL) == (["No heading reference"], False)  # a later request


def test_tracker_counts_lost_events_ignores_repeats_and_waits_for_its_catalog():
    t = EventTracker()
    assert t.on_event(eid(133277), b"", 0x62, 10, 0) is None and t.undecoded == 1
    t.catalog = CATALOG
    assert t.on_event(eid(133277), b"", 0x62, 13, 1) is not None and t.lost == 2
    assert t.missing == {11, 12} and t.to_ask == (11, 12)
    assert t.on_event(eid(133277), b"", 0x62, 12, 2) is not None  # a lost one, re-sent: taken
    assert t.missing == {11} and t.recovered == 1 and t.last_sequence == 13
    assert t.on_event(eid(133277), b"", 0x62, 12, 2) is None  # and again: already seen
    assert t.on_event(eid(133277), b"", 0x62, 13, 2) is None
    wrap = EventTracker(CATALOG)
    wrap.on_event(eid(133277), b"", 0x62, 0xFFFE, 3)
    assert wrap.on_event(eid(133277), b"", 0x62, 0, 4) is not None  # wrapped: one lost
    assert wrap.lost == 1


def test_a_count_restarted_by_a_reboot_is_decoded_not_taken_for_repeats():
    """PX4 rebooted while the link was down: the tracker resumes the old count (200, to ask for
    what the fade lost), and the new boot's EVENTs come numbered from 0. Behind the count but never
    taken, they are a new count, not repeats: before, "Failsafe activated" at 5..9 was dropped."""
    far = EventTracker(CATALOG)
    far.last_sequence = 200  # EventsChannel(resume_after=200)
    assert far.on_event(eid(133277), b"", 0x62, 5, 0) is not None and far.last_sequence == 5
    assert far.on_event(eid(133277), b"", 0x62, 6, 1) is not None
    near = EventTracker(CATALOG)  # the old count within MAX_MISSING of the new one
    for seq in range(18, 21):
        near.on_event(eid(133277), b"", 0x62, seq, seq)
    assert near.on_event(eid(133277), b"", 0x62, 9, 30) is not None and near.last_sequence == 9
    assert near.on_event(eid(133277), b"", 0x62, 9, 31) is None  # that one again: a repeat
    assert near.on_event(eid(133277), b"", 0x62, 10, 32) is not None


# -- the MAVLink FTP fetch --------------------------------------------------------------------------------


class FakeFtpServer:
    """PX4's MavlinkFTP as far as a read goes: files by path, one session, NAKs as PX4 sends."""

    def __init__(self, files: dict[str, bytes]) -> None:
        self.files = files
        self.open: bytes | None = None
        self.requests = 0

    def reply(self, payload: bytes) -> bytes:
        self.requests += 1
        seq, _session, op, size, _, _, _, offset = cm.FTP_HEADER.unpack_from(payload)
        data = payload[cm.FTP_HEADER.size:cm.FTP_HEADER.size + size]

        def out(opcode: int, body: bytes = b"", off: int = 0) -> bytes:
            return cm.FTP_HEADER.pack(seq + 1, 3, opcode, len(body), op, 0, 0, off) + body

        if op == cm.OP_OPEN_RO:
            path = data.decode()
            if path not in self.files:
                return out(cm.OP_NAK, bytes([cm.NAK_FILE_NOT_FOUND]))
            self.open = self.files[path]
            return out(cm.OP_ACK, struct.pack("<I", len(self.open)))
        if op == cm.OP_READ:
            assert self.open is not None
            if offset >= len(self.open):
                return out(cm.OP_NAK, bytes([6]))
            return out(cm.OP_ACK, self.open[offset:offset + size], offset)
        if op == cm.OP_TERMINATE:
            self.open = None
            return out(cm.OP_ACK)
        return out(cm.OP_NAK, bytes([7]))


def general(events_uri: str) -> bytes:
    return lzma.compress(json.dumps({"version": 1, "metadataTypes": [
        {"type": 1, "uri": "mftp://etc/extras/parameters.json.xz"},
        {"type": 4, "uri": events_uri}]}).encode())


def run_fetch(server: FakeFtpServer, uri: str, drop_every: int = 0, max_steps: int = 5000):
    """Drive a fetch against ``server``; with ``drop_every`` = n, every n-th request is lost and
    time moves on until the fetch resends it."""
    fetch = cm.MetadataFetch(1, 1)
    now = 0
    pending = fetch.start(now)
    assert pending == [cm.SendRequestMessage(1, 1, cm.MSG_ID_COMPONENT_METADATA)]
    pending = fetch.on_component_metadata(uri, now)
    sent = 0
    for _ in range(max_steps):
        if fetch.finished:
            return fetch
        if not pending:
            now += cm.REPLY_TIMEOUT_NS
            pending = fetch.tick(now)
            continue
        req = pending[0]
        assert isinstance(req, cm.SendFileTransfer) and len(req.payload) <= 251
        sent += 1
        if drop_every and sent % drop_every == 0:
            pending = []
            continue
        now += MS
        pending = fetch.on_ftp(server.reply(req.payload), now)
    raise AssertionError("the fetch never ended")


def test_fetch_reads_general_then_events_metadata_over_ftp():
    events = lzma.compress(json.dumps(DOC).encode() * 3)  # several 239-byte pieces
    server = FakeFtpServer({"etc/extras/component_general.json.xz":
                            general("mftp://etc/extras/all_events.json.xz"),
                            "etc/extras/all_events.json.xz": events})
    fetch = run_fetch(server, "mftp://etc/extras/component_general.json.xz")
    assert fetch.stage == "done" and fetch.result == lzma.decompress(events)
    assert fetch.events_uri == "mftp://etc/extras/all_events.json.xz"
    assert server.open is None  # the session was terminated


def test_fetch_survives_lost_replies_and_tries_an_absolute_path():
    events = json.dumps(DOC).encode()  # plain JSON this time
    server = FakeFtpServer({"/etc/general.json": general("mftp://[;comp=1]x/events.json"),
                            "/x/events.json": events})
    fetch = run_fetch(server, "mftp://etc/general.json", drop_every=4)
    assert fetch.stage == "done" and fetch.result == events


def test_fetch_fails_with_the_reason():
    fetch = run_fetch(FakeFtpServer({}), "mftp://etc/general.json")
    assert fetch.stage == "failed" and "file not found" in fetch.error
    silent = cm.MetadataFetch(1, 1)
    silent.start(0)
    for k in range(1, cm.ATTEMPTS + 1):
        silent.tick(k * cm.REPLY_TIMEOUT_NS)
    assert silent.stage == "failed" and "no COMPONENT_METADATA" in silent.error
    bad = cm.MetadataFetch(1, 1)
    bad.start(0)
    bad.on_component_metadata("https://example.com/x.json", 0)
    assert bad.stage == "failed" and "not a MAVLink FTP URI" in bad.error


@pytest.mark.parametrize("uri", ["mftp://[;comp=300]x.json", "mftp://[;comp=-1]x.json",
                                 "mftp://[;comp=0]x.json", "mftp://[;comp=one]x.json",
                                 "mftp://" + "e" * (cm.FTP_DATA_MAX + 1)])
def test_an_uri_the_ftp_cannot_ask_for_fails_the_fetch_with_the_reason(uri):
    """A component id is one byte (1..255) and OpenFileRO carries the path in one 239-byte payload:
    anything else could not be packed into a MAVLink message, and the fetch ends there instead."""
    fetch = cm.MetadataFetch(1, 1)
    fetch.start(0)
    assert fetch.on_component_metadata(uri, 0) == []
    assert fetch.stage == "failed" and ("1..255" in fetch.error or "239" in fetch.error)
    assert fetch.next_due_ns() is None
    assert cm.ftp_path("mftp://[;comp=255]" + "e" * cm.FTP_DATA_MAX)[0] == 255  # the limits pass


def test_a_long_events_path_in_the_general_metadata_fails_the_fetch_without_retries():
    """The events URI comes from a file the autopilot serves: too long a path there ends the
    fetch with its reason, and nothing stays due (a fetch with nothing to resend used to stay due
    for ever, and the node's loop ticked without sleeping)."""
    server = FakeFtpServer({"etc/general.json": general("mftp://" + "e" * 300)})
    fetch = run_fetch(server, "mftp://etc/general.json")
    assert fetch.stage == "failed" and "239" in fetch.error and fetch.next_due_ns() is None


def test_a_read_with_nothing_to_resend_fails_instead_of_staying_due():
    fetch = cm.MetadataFetch(1, 1)
    fetch.start(0)
    fetch.on_component_metadata("mftp://etc/general.json", 0)
    assert fetch._read is not None
    fetch._read._pending = None  # as a handler that failed half way would leave it
    assert fetch.tick(cm.REPLY_TIMEOUT_NS) == [] and fetch.stage == "failed"
    assert fetch.next_due_ns() is None


# -- the core --------------------------------------------------------------------------------------------


def wire(msg: Any) -> Any:
    tx = mavlink.MAVLink(None, srcSystem=1, srcComponent=1)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def test_core_asks_px4_for_its_metadata_and_rates_and_ignores_unknown_messages():
    core = VehicleIoCore(VehicleIoConfig(autopilot="auto"), ThrusterLimits(75.0, 75.0, 0.0),
                         Now(0, 0))
    hb = wire(mavlink.MAVLink_heartbeat_message(10, 12, 1, MANUAL, 4, 3))
    out = core.on_mavlink(hb, Now(0, 0), ("127.0.0.1", 14580))
    assert cm.SendRequestMessage(1, 1, cm.MSG_ID_COMPONENT_METADATA) in out
    assert any(isinstance(o, SendCommandLong) and o.command == 511 for o in out)  # rates
    unknown = mavlink.MAVLink_unknown(436, b"\x01\x02")
    core.on_mavlink(unknown, Now(1, 1), ("127.0.0.1", 14580))
    assert core.refusals.total == 0 and core.counts.get("UNKNOWN") == 1
    off = VehicleIoCore(VehicleIoConfig(autopilot="auto", autopilot_events=False),
                        ThrusterLimits(75.0, 75.0, 0.0), Now(0, 0))
    assert not any(isinstance(o, cm.SendRequestMessage)
                   for o in off.on_mavlink(hb, Now(0, 0), ("127.0.0.1", 14580)))


def test_an_autopilot_without_metadata_ends_the_fetch_at_its_ack():
    """Seaway's simulator answers REQUEST_MESSAGE(COMPONENT_METADATA) UNSUPPORTED: no retries."""
    fetch = cm.MetadataFetch(1, 1)
    fetch.start(0)
    fetch.on_request_ack(0)  # ACCEPTED: the message is coming
    assert not fetch.finished
    fetch.on_request_ack(3)
    assert fetch.stage == "failed" and fetch.unsupported and "result 3" in fetch.error


def test_metadata_that_unpacks_beyond_the_limit_is_refused():
    bomb = lzma.compress(b" " * (cm.MAX_UNPACKED_BYTES + 1))
    with pytest.raises(lzma.LZMAError, match="larger than"):
        cm.unpack_file(bomb)
    with pytest.raises(MetadataError, match="neither JSON nor xz"):
        EventCatalog.from_bytes(bomb)


def test_events_lost_on_the_link_are_asked_for_again_once_the_catalog_reads_them():
    """A radio fade: PX4's failsafe EVENTs went out while the link was down. The next sequence
    heard (an EVENT, or CURRENT_EVENT_SEQUENCE), across a reconnection too, shows the gap; it is
    asked for with REQUEST_EVENT once the catalog is there, again after a second while some have
    not come (three times at most), and not at all after a reboot (the count restarted)."""
    from seaway_vehicle_io.events_channel import ASKS, EventsChannel, SendRequestEvent

    ch = EventsChannel(resume_after=40)  # the connection before this one heard up to 40
    ch.connect(1, 1, 0)
    assert ch.on_current_sequence(44, 0, 1) == []  # no catalog yet: nothing it could read
    ch.tracker.catalog = CATALOG
    ch.fetch = None
    sends, _ = ch.tick(2)
    assert sends == [SendRequestEvent(1, 1, 41, 43)]
    assert ch.tick(3)[0] == []  # asked: not again at once
    ev = type("M", (), {"id": eid(133277), "arguments": b"", "log_levels": 0x62, "sequence": 42})
    got, more = ch.on_event(ev, 4)
    assert got is not None and more == [] and ch.tracker.missing == {41, 43}
    asked = [ch.tick(k * 1_000_000_000 + 5)[0] for k in range(1, 6)]
    assert asked[:ASKS - 1] == [[SendRequestEvent(1, 1, 41, 43)]] * (ASKS - 1)
    assert all(a == [] for a in asked[ASKS - 1:])
    # A reboot: the count restarts (RESET flag, or far back): nothing is asked for.
    rebooted = EventsChannel(resume_after=500)
    rebooted.connect(1, 1, 0)
    rebooted.tracker.catalog, rebooted.fetch = CATALOG, None
    assert rebooted.on_current_sequence(3, 1, 1) == [] and rebooted.tracker.missing == set()
    assert rebooted.on_current_sequence(5, 0, 2) == [SendRequestEvent(1, 1, 4, 4)]
    far = EventsChannel(resume_after=500)
    far.connect(1, 1, 0)
    far.tracker.catalog, far.fetch = CATALOG, None
    assert far.on_current_sequence(7, 0, 1) == [] and far.tracker.missing == set()
