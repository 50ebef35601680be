"""MAVLink 2 signing in the simulator: the signature check (pure), and the sim's link with a key
(real UDP on loopback): what it accepts, what it refuses and counts, what moves its peer, what it
signs; the command line refuses a bad key file. Also the link's bounded receive under a flood."""

from __future__ import annotations

import logging
import socket
import time

import pytest
from pymavlink.dialects.v20 import common as ml
from seaway.mavlink.signing import (
    ACCEPTED,
    BAD_SIGNATURE,
    NEW_STREAM_MAX_AGE,
    REPLAYED,
    UNSIGNED,
    SignatureVerifier,
    keep_up,
    signing_timestamp,
)
from seaway.mavlink.wire import frame_ids
from seaway_sim.main import main as sim_main
from seaway_sim.mavlink_link import MAX_DATAGRAMS_PER_RECEIVE, MavlinkLink

KEY = bytes(range(1, 33))
OTHER_KEY = bytes(range(101, 133))
T0 = signing_timestamp(1_800_000_000 * 10**9)


def packer(key: bytes | None, sysid: int = 255, compid: int = 191, timestamp: int = T0,
           link_id: int = 1) -> ml.MAVLink:
    tx = ml.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    if key is not None:
        tx.signing.secret_key, tx.signing.sign_outgoing = key, True
        tx.signing.link_id, tx.signing.timestamp = link_id, timestamp
    return tx


def heartbeat(tx: ml.MAVLink) -> bytes:
    return ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(tx)


def arm(tx: ml.MAVLink, on: bool = True) -> bytes:
    return ml.MAVLink_command_long_message(1, 1, 400, 0, 1 if on else 0, 0, 0, 0, 0, 0, 0).pack(tx)


# =============================================================================================
# SignatureVerifier (pure)
# =============================================================================================


def test_verdicts():
    v = SignatureVerifier(KEY)
    tx = packer(KEY)
    first, second = heartbeat(tx), heartbeat(tx)
    assert v.check(first, T0) == ACCEPTED
    assert v.check(first, T0) == REPLAYED  # the same frame again
    assert v.check(second, T0) == ACCEPTED  # pymavlink counts the timestamp up per frame
    assert v.check(heartbeat(packer(None)), T0) == UNSIGNED
    assert v.check(heartbeat(packer(OTHER_KEY)), T0) == BAD_SIGNATURE
    tampered = bytearray(heartbeat(tx))
    tampered[12] ^= 1  # one payload bit
    assert v.check(bytes(tampered), T0) == BAD_SIGNATURE


def test_mavlink1_and_short_frames_are_unsigned():
    v = SignatureVerifier(KEY)
    v1 = ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3).pack(packer(KEY), force_mavlink1=True)
    assert v.check(v1, T0) == UNSIGNED
    assert v.check(b"\xfd\x01", T0) == UNSIGNED


def test_new_stream_may_be_at_most_a_minute_old_and_streams_are_separate():
    v = SignatureVerifier(KEY)
    now = T0 + NEW_STREAM_MAX_AGE + 1
    assert v.check(heartbeat(packer(KEY, timestamp=T0)), now) == REPLAYED
    assert v.check(heartbeat(packer(KEY, timestamp=T0 + 1)), now) == ACCEPTED
    # another link id, or another component, is another stream with its own timestamp
    assert v.check(heartbeat(packer(KEY, timestamp=T0 + 1, link_id=2)), now) == ACCEPTED
    assert v.check(heartbeat(packer(KEY, compid=190, timestamp=T0 + 1)), now) == ACCEPTED


def test_a_forged_frame_cannot_poison_a_streams_timestamp():
    """pymavlink's own check stores the timestamp before checking the signature: one forged frame
    with a huge timestamp would lock the genuine sender out. Ours only learns from authentic
    frames."""
    v = SignatureVerifier(KEY)
    forged = heartbeat(packer(OTHER_KEY, timestamp=2**48 - 2))  # same stream ids, wrong key
    assert v.check(forged, T0) == BAD_SIGNATURE
    assert v.check(heartbeat(packer(KEY)), T0) == ACCEPTED
    pym = ml.MAVLink(None)
    pym.signing.secret_key, pym.signing.timestamp = KEY, T0
    pym.robust_parsing = True
    pym.parse_buffer(forged)
    (genuine,) = pym.parse_buffer(heartbeat(packer(KEY)))
    assert genuine.get_type() == "BAD_DATA"  # what the check above protects against


def test_key_length_and_frame_ids():
    with pytest.raises(ValueError, match="32 bytes"):
        SignatureVerifier(b"short")
    assert frame_ids(heartbeat(packer(None, sysid=7, compid=9))) == (7, 9)
    assert frame_ids(b"garbage") == (None, None)


# =============================================================================================
# The sim's link with a key (real UDP)
# =============================================================================================


@pytest.fixture
def link():
    lk = MavlinkLink("udpin:127.0.0.1:0", sysid=1, compid=1, signing_key=KEY)
    yield lk
    lk.close()


@pytest.fixture
def socks():
    out = []
    for _ in range(3):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        s.settimeout(1.0)
        out.append(s)
    yield out
    for s in out:
        s.close()


def receive(link: MavlinkLink, datagrams: int) -> list:
    """Every message accepted from the next ``datagrams`` datagrams (they are all sent first)."""
    got: list = []
    deadline = time.monotonic() + 5.0
    seen = lambda: (link.counters["rx_messages"] + sum(  # noqa: E731
        v for k, v in link.counters.items() if k.startswith("refused_")))
    while seen() < datagrams and time.monotonic() < deadline:
        got += link.receive(0.05)
    return got


def test_signed_commands_are_accepted_and_move_the_peer(link, socks):
    vio = socks[0]
    tx = packer(KEY, timestamp=signing_timestamp(time.time_ns()))
    vio.sendto(heartbeat(tx), link.address)
    vio.sendto(arm(tx), link.address)
    assert [m.get_type() for m in receive(link, 2)] == ["HEARTBEAT", "COMMAND_LONG"]
    assert link.peer == vio.getsockname()


def test_unsigned_and_wrongly_signed_commands_are_refused_counted_and_never_move_the_peer(
        link, socks, caplog):
    vio, unsigned, wrong = socks
    now = signing_timestamp(time.time_ns())
    vio.sendto(heartbeat(packer(KEY, timestamp=now)), link.address)
    receive(link, 1)
    with caplog.at_level(logging.WARNING, logger="seaway_sim.mavlink"):
        for _ in range(5):
            unsigned.sendto(arm(packer(None), on=False), link.address)
        for _ in range(5):
            wrong.sendto(arm(packer(OTHER_KEY, timestamp=now), on=False), link.address)
        assert receive(link, 11) == []
    assert link.counters["refused_unsigned"] == 5 and link.counters["refused_bad_signature"] == 5
    assert link.peer == vio.getsockname()
    assert link.refused[("unsigned", unsigned.getsockname(), 255, 191)] == 5
    lines = [r.getMessage() for r in caplog.records if "signing: refused" in r.getMessage()]
    assert len(lines) == 1  # one source logged; the second waits for the once-a-second slot
    assert "refused unsigned COMMAND_LONG from system 255 component 191" in lines[0]


def test_px4s_unsigned_allowlist_is_accepted_but_does_not_move_the_peer(link, socks):
    vio, other, _ = socks
    vio.sendto(heartbeat(packer(KEY, timestamp=signing_timestamp(time.time_ns()))), link.address)
    receive(link, 1)
    other.sendto(heartbeat(packer(None, sysid=200)), link.address)
    assert [m.get_type() for m in receive(link, 2)] == ["HEARTBEAT"]
    assert link.counters["unsigned_allowlisted"] == 1
    assert link.peer == vio.getsockname()


def test_everything_the_sim_sends_is_signed(link, socks):
    vio = socks[0]
    vio.sendto(heartbeat(packer(KEY, timestamp=signing_timestamp(time.time_ns()))), link.address)
    receive(link, 1)
    link.send([ml.MAVLink_heartbeat_message(10, 12, 0, 0, 3, 3)])
    data = vio.recv(2048)
    assert SignatureVerifier(KEY).check(data, signing_timestamp(time.time_ns())) == ACCEPTED


def test_command_line_refuses_a_bad_key_file(tmp_path, capsys):
    bad = tmp_path / "bad.key"
    bad.write_text("0123")
    bad.chmod(0o600)
    assert sim_main(["--signing-key-file", str(bad), "--scenario", "lake"]) == 2
    err = capsys.readouterr().err
    assert "--signing-key-file" in err and "bad.key" in err and "64 hexadecimal" in err


def test_receive_is_bounded_so_a_flood_cannot_hold_back_what_arrived(socks):
    lk = MavlinkLink("udpin:127.0.0.1:0", sysid=1, compid=1)
    lk.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)  # hold all of them
    try:
        n = MAX_DATAGRAMS_PER_RECEIVE + 64  # fits a default socket buffer
        frame = heartbeat(packer(None))
        for _ in range(n):
            socks[0].sendto(frame, lk.address)
        sizes, deadline = [], time.monotonic() + 5.0
        while sum(sizes) < n and time.monotonic() < deadline:
            sizes.append(len(lk.receive(0.05)))
        assert sum(sizes) == n and max(sizes) <= MAX_DATAGRAMS_PER_RECEIVE and len(sizes) >= 2
    finally:
        lk.close()


def test_a_sender_kept_up_with_the_clock_is_taken_by_a_receiver_that_restarted() -> None:
    """pymavlink adds 10 us per frame signed: after a few minutes at 50 frames a second a sender
    lags the wall clock by minutes, and a receiver that restarted (no stream known) refused every
    frame as replayed, for good (an autopilot's reboot, a restarted vehicle_io). ``keep_up`` before
    each send, as both links do, brings the timestamp up to the clock and never back."""
    wall0_ns = 1_800_000_000 * 10**9
    lagging, kept = packer(KEY, timestamp=signing_timestamp(wall0_ns)), packer(KEY, timestamp=T0)
    for k in range(50 * 300):  # five minutes at 50 frames a second
        heartbeat(lagging)
        keep_up(kept.signing, wall0_ns + k * 20_000_000)
        heartbeat(kept)
    now = signing_timestamp(wall0_ns + 300 * 10**9)
    fresh = SignatureVerifier(KEY)  # the receiver just restarted
    assert fresh.check(heartbeat(lagging), now) == REPLAYED
    keep_up(kept.signing, wall0_ns + 300 * 10**9)
    assert fresh.check(heartbeat(kept), now) == ACCEPTED
    ahead = kept.signing.timestamp
    keep_up(kept.signing, wall0_ns)  # a clock stepped back: never back
    assert kept.signing.timestamp == ahead
