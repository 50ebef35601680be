"""Who may speak for the autopilot: the source lock, refusal counting, signing, the bounded read.

The core is driven with real MAVLink messages (packed, with or without a signature, and parsed) and
with addresses and time passed in; the link's bounded read and its signing run on real UDP sockets
on loopback; key files are real files.
"""

from __future__ import annotations

import logging
import os
import socket
import stat
import time
from typing import Any

import pytest
from seaway.contract.config import ConfigError, parse_config
from seaway.contract.messages import ThrustCommand, VehicleStatus
from seaway.contract.units import NS_PER_S
from seaway.mavlink import signing as mavlink_signing
from seaway.mavlink.signing import (
    KeyFileError,
    SignatureVerifier,
    read_key,
    signing_timestamp,
    write_key,
)
from seaway.runtime.run import resolve
from seaway_vehicle_io import authority
from seaway_vehicle_io.authority import (
    BAD_SIGNATURE,
    FOREIGN_SOURCE,
    MAX_SOURCES,
    OTHER,
    REPLAYED,
    UNSIGNED,
    Refusals,
    SourcePolicy,
)
from seaway_vehicle_io.config import SOURCE_SYSTEM, VehicleIoConfig
from seaway_vehicle_io.core import (
    LockPeer,
    Now,
    Publish,
    SendHeartbeat,
    SendManualControl,
    VehicleIoCore,
)
from seaway_vehicle_io.link import MAX_DATAGRAMS_PER_READ, MavlinkLink
from seaway_vehicle_io.main import build_parser, load, signing_setup
from seaway_vehicle_io.mav import mavlink
from seaway_vehicle_io.signing import SigningClock, SigningSetup
from seaway_vehicle_io.thrust import ThrusterLimits

S = NS_PER_S
MS = 1_000_000
WALL0 = 1_800_000_000 * S
LIM = ThrusterLimits(75.0, 75.0, 10.0)
AUTOPILOT = ("127.0.0.1", 14580)
INTRUDER = ("127.0.0.1", 40000)
KEY = bytes(range(1, 33))
OTHER_KEY = bytes(range(101, 133))
PX4_MANUAL = 1 << 16
PX4_HOLD = (4 << 16) | (3 << 24)


def at(t_ns: int) -> Now:
    return Now(WALL0 + t_ns, t_ns)


def wire(msg: Any, sysid: int = 1, compid: int = 1, key: bytes | None = None,
         t_ns: int = 0, link_id: int = 0) -> Any:
    """``msg`` as received from (sysid, compid): packed (signed with ``key`` at time ``t_ns`` on
    this file's clock), then decoded by a parser without a key, as vehicle_io's link does."""
    tx = mavlink.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        tx.signing.secret_key, tx.signing.sign_outgoing = key, True
        tx.signing.link_id, tx.signing.timestamp = link_id, signing_timestamp(WALL0 + t_ns)
    return mavlink.MAVLink(None).decode(bytearray(msg.pack(tx)))


def heartbeat(armed: bool = True, custom_mode: int = PX4_MANUAL, sysid: int = 1, compid: int = 1,
              **kw: Any) -> Any:
    base = 1 | (128 if armed else 0)
    return wire(mavlink.MAVLink_heartbeat_message(10, 12, base, custom_mode, 4, 3), sysid, compid,
                **kw)


def attitude(sysid: int = 1, **kw: Any) -> Any:
    return wire(mavlink.MAVLink_attitude_message(1000, 0.0, 0.0, 0.5, 0.0, 0.0, 0.1), sysid, **kw)


def make(key: bytes | None = None, **cfg: Any) -> VehicleIoCore:
    return VehicleIoCore(VehicleIoConfig(check_failsafe_params=False, **cfg), LIM, at(0), key)


def locked(core: VehicleIoCore, address=AUTOPILOT, t_ns: int = MS, **kw: Any) -> list:
    outs = core.on_mavlink(heartbeat(**kw), at(t_ns), address)
    assert core.link.ok and core.link.target_address == address
    return outs


def thrusting(core: VehicleIoCore, t_ns: int) -> SendManualControl:
    (mc,) = [o for o in core.on_thrust(ThrustCommand.make(stamp_ns=WALL0 + t_ns, thrust_port_n=30.0,
                                                          thrust_starboard_n=30.0), at(t_ns))
             if isinstance(o, SendManualControl)]
    return mc


def status(core: VehicleIoCore, t_ns: int) -> VehicleStatus:
    return core.status(at(t_ns))


# =============================================================================================
# Source lock (the core)
# =============================================================================================


def test_first_autopilot_heartbeat_locks_system_component_and_address():
    core = make()
    outs = locked(core)
    assert LockPeer(AUTOPILOT) in outs  # the link is told, to refuse the rest before parsing
    assert (core.link.target_system, core.link.target_component) == (1, 1)


def test_forged_heartbeat_from_the_autopilots_ids_but_another_address_changes_nothing():
    core = make()
    locked(core, armed=True)
    assert not thrusting(core, 2 * MS).neutral
    forged = heartbeat(armed=False, custom_mode=PX4_HOLD)  # "disarmed, HOLD", system 1 component 1
    for k in range(5):
        assert core.on_mavlink(forged, at((3 + k) * MS), INTRUDER) == []
    assert core.link.armed and core.link.mode == "MANUAL"
    assert not thrusting(core, 10 * MS).neutral  # still commanding thrust
    assert status(core, 11 * MS).refused_messages == {FOREIGN_SOURCE: 5}
    assert core.refusals.by_source == {(FOREIGN_SOURCE, (1, 1, INTRUDER)): 5}


def test_other_system_at_the_autopilots_address_and_telemetry_from_elsewhere_are_refused():
    core = make()
    locked(core)
    assert core.on_mavlink(attitude(sysid=1), at(2 * MS), INTRUDER) == []  # right ids, wrong place
    assert core.on_mavlink(attitude(sysid=9), at(3 * MS), AUTOPILOT) == []  # right place, wrong id
    assert core.on_mavlink(heartbeat(sysid=9), at(4 * MS), AUTOPILOT) == []
    assert core.refusals.by_source == {(FOREIGN_SOURCE, (1, 1, INTRUDER)): 1,
                                       (FOREIGN_SOURCE, (9, 1, AUTOPILOT)): 2}
    assert any(isinstance(o, Publish) for o in core.on_mavlink(attitude(), at(5 * MS), AUTOPILOT))


def test_other_components_of_the_autopilots_system_do_not_speak_for_it():
    """A gimbal (154), a smart battery (180) or a companion computer (191) behind the autopilot's
    router share its system id and address: their position, texts, battery and ACKs are refused,
    counted per source; the autopilot's own (component 1) still count."""
    core = make()
    locked(core)
    gimbal_fix = wire(mavlink.MAVLink_global_position_int_message(
        1000, 473977420, 85455940, 488_000, 0, 150, -50, 0, 0), compid=154)
    critical = wire(mavlink.MAVLink_statustext_message(2, b"Battery 1 is critical"), compid=191)
    arm_ack = wire(mavlink.MAVLink_command_ack_message(400, 0), compid=191)
    for k, msg in enumerate([gimbal_fix, critical, arm_ack, heartbeat(compid=154)]):
        assert core.on_mavlink(msg, at((2 + k) * MS), AUTOPILOT) == []
    assert core.refusals.by_source == {(FOREIGN_SOURCE, (1, 154, AUTOPILOT)): 2,
                                       (FOREIGN_SOURCE, (1, 191, AUTOPILOT)): 2}
    assert status(core, 10 * MS).failsafe_latched is None
    assert any(isinstance(o, Publish) for o in core.on_mavlink(attitude(), at(11 * MS), AUTOPILOT))


def test_ftp_replies_come_from_the_component_the_metadata_uri_names():
    """COMPONENT_METADATA may point the events file at another component ([;comp=N]): its MAVLink
    FTP replies are taken, and nothing else from it."""
    core = make()
    locked(core)
    core.events.connect(1, 1, 0)
    assert core.events.fetch is not None
    core.events.fetch.on_component_metadata("mftp://[;comp=100]general.json", 0)
    ftp = wire(mavlink.MAVLink_file_transfer_protocol_message(0, SOURCE_SYSTEM, 191, [0] * 251),
               compid=100)
    core.on_mavlink(ftp, at(2 * MS), AUTOPILOT)
    assert core.refusals.total == 0 and core.counts.get("FILE_TRANSFER_PROTOCOL") == 1
    core.on_mavlink(attitude(compid=100), at(3 * MS), AUTOPILOT)
    assert core.refusals.by_source == {(FOREIGN_SOURCE, (1, 100, AUTOPILOT)): 1}


def test_garbage_from_elsewhere_is_a_refusal_and_from_the_autopilot_a_drop():
    core = make()
    locked(core)
    bad = mavlink.MAVLink_bad_data(bytearray(b"\xfd\x09junk"), "test")
    core.on_mavlink(bad, at(2 * MS), INTRUDER)
    assert (core.refusals.by_reason, core.dropped) == ({FOREIGN_SOURCE: 1}, 0)
    core.on_mavlink(bad, at(3 * MS), AUTOPILOT)
    assert core.dropped == 1


def test_datagrams_the_link_refused_unparsed_are_counted_per_claimed_source():
    core = make()
    locked(core)
    core.on_refused_datagrams({(1, 1, INTRUDER): 700, (None, None, INTRUDER): 300}, at(2 * MS))
    assert status(core, 3 * MS).refused_messages == {FOREIGN_SOURCE: 1000}
    assert core.refusals.by_source[(FOREIGN_SOURCE, (None, None, INTRUDER))] == 300


def test_link_loss_releases_the_lock_and_the_next_autopilot_heartbeat_locks_again():
    core = make(heartbeat_timeout_s=3.0)
    locked(core, t_ns=0)
    outs = core.tick(at(3 * S + MS))
    assert LockPeer(None) in outs and not core.link.ok and core.link.target_address is None
    # udpin (no expected address): the autopilot back from another port locks again.
    relock = core.on_mavlink(heartbeat(sysid=2), at(4 * S), INTRUDER)
    assert LockPeer(INTRUDER) in relock and core.link.target_system == 2


def test_udpout_only_the_address_we_send_to_may_lock_even_after_a_loss():
    core = make(heartbeat_timeout_s=3.0)
    core.set_source_policy(SourcePolicy(expected_address=AUTOPILOT))
    assert core.on_mavlink(heartbeat(), at(0), INTRUDER) == [] and not core.link.ok
    locked(core, t_ns=MS)
    core.tick(at(4 * S))  # lost
    assert core.on_mavlink(heartbeat(), at(5 * S), INTRUDER) == [] and not core.link.ok
    assert core.refusals.by_reason == {FOREIGN_SOURCE: 2}
    locked(core, t_ns=6 * S)


def test_our_own_echo_is_ignored_not_counted():
    core = make()
    locked(core)
    echo = wire(mavlink.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3), sysid=SOURCE_SYSTEM, compid=191)
    assert core.on_mavlink(echo, at(2 * MS), INTRUDER) == []
    assert core.refusals.total == 0


def test_serial_link_has_no_address_and_locks_on_ids_alone():
    core = make()
    locked(core, address=None)
    assert core.on_mavlink(attitude(sysid=9), at(2 * MS), None) == []
    assert core.refusals.by_source == {(FOREIGN_SOURCE, (9, 1, None)): 1}


# =============================================================================================
# Signing (the core)
# =============================================================================================


def test_signing_locks_only_on_a_signed_heartbeat_and_refuses_the_rest_by_reason():
    core = make(key=KEY)
    assert core.on_mavlink(heartbeat(), at(MS), AUTOPILOT) == [] and not core.link.ok  # unsigned
    assert core.on_mavlink(heartbeat(key=OTHER_KEY, t_ns=MS), at(2 * MS), AUTOPILOT) == []
    signed = heartbeat(key=KEY, t_ns=3 * MS)
    core.on_mavlink(signed, at(3 * MS), AUTOPILOT)
    assert core.link.ok
    assert core.on_mavlink(signed, at(4 * MS), AUTOPILOT) == []  # the same frame again: a replay
    assert core.refusals.by_reason == {UNSIGNED: 1, BAD_SIGNATURE: 1, REPLAYED: 1}
    # signed telemetry keeps flowing
    outs = core.on_mavlink(attitude(key=KEY, t_ns=5 * MS), at(5 * MS), AUTOPILOT)
    assert any(isinstance(o, Publish) for o in outs)


def test_signing_a_stream_minutes_behind_is_a_replay_until_it_catches_up():
    core = make(key=KEY)
    old = heartbeat(key=KEY, t_ns=0)
    assert core.on_mavlink(old, at(2 * 60 * S), AUTOPILOT) == []
    assert core.refusals.by_reason == {REPLAYED: 1}
    core.on_mavlink(heartbeat(key=KEY, t_ns=2 * 60 * S), at(2 * 60 * S + MS), AUTOPILOT)
    assert core.link.ok


# =============================================================================================
# Refusal bookkeeping
# =============================================================================================


def test_each_source_is_logged_once_and_new_ones_at_most_once_a_second(caplog):
    r = Refusals()
    a, b = (1, 1, INTRUDER), (1, 1, ("127.0.0.1", 40001))
    with caplog.at_level(logging.WARNING, logger="seaway.vehicle_io"):
        for k in range(100):
            r.add(FOREIGN_SOURCE, a, 1, k * MS)
        r.add(FOREIGN_SOURCE, b, 1, 200 * MS)  # new, but a line went out < 1 s ago: waits
        assert len(caplog.records) == 1
        r.flush(900 * MS)
        assert len(caplog.records) == 1
        r.flush(1001 * MS)
    lines = [rec.getMessage() for rec in caplog.records]
    assert len(lines) == 2 and "127.0.0.1:40000" in lines[0] and "127.0.0.1:40001" in lines[1]
    assert r.by_reason == {FOREIGN_SOURCE: 101}


def test_a_flood_of_new_sources_is_bounded_in_memory():
    r = Refusals()
    for port in range(10_000):
        r.add(FOREIGN_SOURCE, (None, None, ("127.0.0.1", port)), 1, port * MS)
    assert len(r.by_source) == MAX_SOURCES + 1
    assert r.by_source[(FOREIGN_SOURCE, OTHER)] == 10_000 - MAX_SOURCES
    assert r.total == 10_000
    assert "further sources" in r.summary()


def test_source_descriptions():
    assert authority.describe((1, 1, ("10.0.0.2", 5))) == "system 1 component 1 at 10.0.0.2:5"
    assert authority.describe((None, None, None)) == "system ? component ? on the link"


# =============================================================================================
# The link: bounded read, refusal before parsing, signing (real UDP on loopback)
# =============================================================================================


@pytest.fixture
def link_and_peers(tmp_path):
    """vehicle_io's link listening (udpin), an autopilot socket and an intruder socket."""
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    clock = SigningClock(SigningSetup(KEY, 1, tmp_path / "ts"), time.time_ns(), time.monotonic_ns())
    link = MavlinkLink(f"udpin:127.0.0.1:{port}", 255, 191, signing=clock)
    ap = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for s in (ap, intruder):
        s.bind(("127.0.0.1", 0))
        s.settimeout(2.0)
    try:
        yield link, ap, intruder, ("127.0.0.1", port)
    finally:
        for s in (ap, intruder):
            s.close()
        link.close()


def read_all(link: MavlinkLink, want: int, timeout_s: float = 5.0) -> list:
    """Reads until ``want`` datagrams (messages + refusals) are in, returning each read."""
    reads, got, deadline = [], 0, time.monotonic() + timeout_s
    while got < want and time.monotonic() < deadline:
        if link.wait_readable(0.05):
            r = link.read_available()
            reads.append(r)
            got += len(r.messages) + sum(r.refused.values())
    return reads


def test_link_refuses_other_addresses_unparsed_and_bounds_each_read(link_and_peers):
    link, ap, intruder, where = link_and_peers
    hb = mavlink.MAVLink_heartbeat_message(10, 12, 1, PX4_MANUAL, 4, 3)
    ap.sendto(hb.pack(mavlink.MAVLink(None, 1, 1)), where)
    (first,) = read_all(link, 1)
    (msg, address), = first.messages
    assert msg.get_type() == "HEARTBEAT" and address == ap.getsockname()
    link.lock_peer(address)
    forged = hb.pack(mavlink.MAVLink(None, 1, 1))
    n = 2 * (MAX_DATAGRAMS_PER_READ // 2 + 32)  # more than one read, fits a default socket buffer
    for k in range(n):
        intruder.sendto(forged if k % 2 else b"\x00garbage", where)
    ap.sendto(hb.pack(mavlink.MAVLink(None, 1, 1)), where)
    reads = read_all(link, n + 1)
    assert all(len(r.messages) <= MAX_DATAGRAMS_PER_READ for r in reads)
    assert all(sum(r.refused.values()) <= MAX_DATAGRAMS_PER_READ for r in reads)
    assert len(reads) >= 2
    refused: dict = {}
    for r in reads:
        for src, c in r.refused.items():
            refused[src] = refused.get(src, 0) + c
    me = intruder.getsockname()
    assert refused == {(1, 1, me): n // 2, (None, None, me): n // 2}
    assert [(m.get_type(), a) for r in reads for m, a in r.messages] == [("HEARTBEAT", address)]
    # udpin answers the locked autopilot only, no longer every address heard
    assert link.conn.clients == {address}


def drain(link: MavlinkLink) -> list:
    """Every read until the link has nothing more (a read that got nothing twice in a row)."""
    reads, idle = [], 0
    while idle < 2:
        r = link.read_available() if link.wait_readable(0.2) else None
        if r is None or not (r.messages or r.refused):
            idle += 1
        else:
            reads.append(r)
            idle = 0
    return reads


def test_a_flood_cannot_crowd_the_locked_autopilot_out_of_the_socket_buffer(link_and_peers):
    """The receive thread kept off the CPU while a flood arrives (here: not reading at all): the
    autopilot's datagrams are all there afterwards, in order, and the flood is counted as far as
    the kernel kept it."""
    flood_while_not_reading(*link_and_peers)


def test_udpout_gives_the_autopilot_its_own_socket_too():
    ap = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    intruder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    for s in (ap, intruder):
        s.bind(("127.0.0.1", 0))
        s.settimeout(2.0)
    link = MavlinkLink(f"udpout:127.0.0.1:{ap.getsockname()[1]}", 255, 191)
    try:
        host, port = link.local_address().rsplit(":", 1)
        flood_while_not_reading(link, ap, intruder, (host, int(port)))
    finally:
        link.close()
        ap.close()
        intruder.close()


def flood_while_not_reading(link: MavlinkLink, ap: socket.socket, intruder: socket.socket,
                            where: tuple[str, int]) -> None:
    tx = mavlink.MAVLink(None, 1, 1)
    ap.sendto(mavlink.MAVLink_heartbeat_message(10, 12, 1, PX4_MANUAL, 4, 3).pack(tx), where)
    (first,) = read_all(link, 1)
    (_msg, address), = first.messages
    link.lock_peer(address)
    assert not link.wait_readable(0.0)  # opens the autopilot's own socket; nothing waiting yet
    assert link.peer_socket_open
    junk = b"\xfd" + bytes(40)
    flood_n = 20_000  # far more than a 1 MiB socket buffer holds (about 1,300 such datagrams)
    for _ in range(flood_n):
        intruder.sendto(junk, where)
    for seq in range(5):
        ap.sendto(mavlink.MAVLink_heartbeat_message(10, 12, 1, PX4_MANUAL, 4, seq).pack(tx), where)
    for _ in range(flood_n):
        intruder.sendto(junk, where)
    reads = drain(link)
    got = [(m.get_type(), m.mavlink_version, a) for r in reads for m, a in r.messages]
    assert got == [("HEARTBEAT", seq, address) for seq in range(5)]
    refused = sum(sum(r.refused.values()) for r in reads)
    assert 0 < refused < 2 * flood_n  # the kernel dropped the rest of the flood, only the flood
    # The lock released (link loss): the socket closes and everyone is heard on one again.
    link.lock_peer(None)
    link.wait_readable(0.0)
    assert not link.peer_socket_open
    intruder.sendto(mavlink.MAVLink_heartbeat_message(10, 12, 1, 0, 4, 3).pack(tx), where)
    (heard,) = read_all(link, 1)
    assert [a for _m, a in heard.messages] == [intruder.getsockname()]


def test_link_signs_what_it_sends(link_and_peers):
    link, ap, _intruder, where = link_and_peers
    ap.sendto(mavlink.MAVLink_heartbeat_message(10, 12, 1, 0, 4, 3)
              .pack(mavlink.MAVLink(None, 1, 1)), where)
    read_all(link, 1)  # udpin learns where to answer
    link.send(SendHeartbeat())
    data = ap.recv(2048)
    now = signing_timestamp(time.time_ns())
    assert SignatureVerifier(KEY).check(data, now) == mavlink_signing.ACCEPTED
    assert SignatureVerifier(OTHER_KEY).check(data, now) == mavlink_signing.BAD_SIGNATURE


def test_udpout_expects_the_autopilot_at_the_address_it_sends_to():
    link = MavlinkLink("udpout:localhost:14999", 255, 191)
    try:
        assert link.policy == SourcePolicy(expected_address=("127.0.0.1", 14999))
        assert link.local_address().split(":")[1] != "0"  # bound at open, so the log names it
    finally:
        link.close()


# =============================================================================================
# Key files, config and command line
# =============================================================================================


def test_write_key_then_read_key(tmp_path):
    path = tmp_path / "k.hex"
    key = write_key(path)
    assert len(key) == 32 and read_key(path) == key
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    with pytest.raises(FileExistsError):
        write_key(path)  # a key is never silently replaced


@pytest.mark.parametrize(("content", "why"), [
    (b"abc", "exactly 64 hexadecimal"),
    (b"zz" * 32, "exactly 64 hexadecimal"),
    (bytes(32), "exactly 64 hexadecimal"),  # the raw bytes are not the format
    (b"00" * 32 + b"\n", "all zeros"),
    (b"\xff\xfe" * 32, "exactly 64 hexadecimal"),
])
def test_bad_key_files_name_the_file_and_what_is_allowed(tmp_path, content, why):
    path = tmp_path / "bad.key"
    path.write_bytes(content)
    path.chmod(0o600)
    with pytest.raises(KeyFileError, match=why) as err:
        read_key(path)
    assert str(path) in str(err.value)


def test_missing_key_file(tmp_path):
    with pytest.raises(KeyFileError, match="cannot read"):
        read_key(tmp_path / "nope.key")


def test_key_file_others_may_read_is_refused(tmp_path):
    path = tmp_path / "k.hex"
    path.write_text(KEY.hex() + "\n")
    path.chmod(0o644)
    with pytest.raises(KeyFileError, match=r"mode 644 .*chmod 600"):
        read_key(path)
    path.chmod(0o600)
    assert read_key(path) == KEY


def test_key_file_module_cli(tmp_path, capsys):
    path = tmp_path / "cli.key"
    assert mavlink_signing.main([str(path)]) == 0
    assert len(read_key(path)) == 32
    assert mavlink_signing.main([str(path)]) == 1  # exists
    assert "exists" in capsys.readouterr().err
    assert mavlink_signing.main([]) == 2


def test_config_signing_key_file_is_validated(tmp_path):
    good = tmp_path / "good.key"
    write_key(good)
    assert parse_config({"signing_key_file": str(good)}, VehicleIoConfig).signing_key_file == good
    bad = tmp_path / "bad.key"
    bad.write_text("not a key")
    bad.chmod(0o600)
    with pytest.raises(ConfigError, match=r"signing_key_file.*bad\.key.*64 hexadecimal"):
        parse_config({"signing_key_file": str(bad)}, VehicleIoConfig, "test")


def test_signing_key_file_flag_overrides_the_config(tmp_path):
    path = tmp_path / "flag.key"
    key = write_key(path)
    args = build_parser().parse_args(["--signing-key-file", str(path), "--vessel-file",
                                      "paper-boat"])
    cfg, _limits = load(args, resolve(args, "vehicle_io"))
    setup = signing_setup(cfg)
    assert cfg.signing_key_file == path and setup is not None and setup.key == key
    assert setup.timestamp_file == tmp_path / "flag.key.timestamp" and setup.link_id == 1
    plain = build_parser().parse_args(["--vessel-file", "paper-boat"])
    cfg, _limits = load(plain, resolve(plain, "vehicle_io"))
    assert signing_setup(cfg) is None
    (tmp_path / "empty.key").write_text("")
    (tmp_path / "empty.key").chmod(0o600)
    bad = build_parser().parse_args(["--signing-key-file", str(tmp_path / "empty.key")])
    with pytest.raises(ConfigError, match=r"empty\.key"):
        load(bad, resolve(bad, "vehicle_io"))
