"""The sim's MAVLink UDP link: endpoint parsing, per-datagram garbage counting, last-peer replies."""

from __future__ import annotations

import socket

import pytest
from pymavlink.dialects.v20 import common as ml
from seaway_sim.mavlink_link import MavlinkLink, parse_endpoint

GCS = ml.MAVLink(None, 255, 190)


def frame(msg) -> bytes:
    return msg.pack(GCS)


HEARTBEAT = ml.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)


@pytest.fixture
def link():
    lk = MavlinkLink("udpin:127.0.0.1:0", sysid=1, compid=1)
    yield lk
    lk.close()


@pytest.fixture
def client():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    s.settimeout(1.0)
    yield s
    s.close()


@pytest.mark.parametrize("bad", ["udp:127.0.0.1:14580", "udpin:14580", "udpin:127.0.0.1:x",
                                 "udpin:127.0.0.1:70000", "tcp:localhost:5760"])
def test_endpoint_must_be_udpin_host_port(bad: str) -> None:
    with pytest.raises(ValueError, match="udpin:HOST:PORT"):
        parse_endpoint(bad)


def test_endpoint_parses() -> None:
    assert parse_endpoint("udpin:0.0.0.0:14580") == ("0.0.0.0", 14580)


def test_garbage_is_counted_per_datagram_and_good_frames_beside_it_still_count(link, client):
    good = frame(HEARTBEAT)
    client.sendto(b"\x00junk" + good + good[:7], link.address)  # junk, good, truncated
    msgs = link.receive(1.0)
    assert [m.get_type() for m in msgs] == ["HEARTBEAT"]
    assert link.garbage == 1 and link.counters["truncated_frames"] == 1
    assert link.peer == client.getsockname()


def test_a_datagram_of_garbage_never_moves_the_peer_and_nothing_is_sent_before_a_peer(link, client):
    link.send([HEARTBEAT])  # no peer yet: dropped silently
    assert link.counters["tx_messages"] == 0
    client.sendto(frame(HEARTBEAT), link.address)
    link.receive(1.0)
    other = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    other.bind(("127.0.0.1", 0))
    try:
        other.sendto(b"\xfe\x09garbage-garbage", link.address)
        assert link.receive(1.0) == []
        assert link.peer == client.getsockname() and link.garbage == 1
        link.send([ml.MAVLink_heartbeat_message(10, 12, 1, 0x10000, 3, 3)])
        data, _ = client.recvfrom(65535)
        (hb,) = ml.MAVLink(None).parse_buffer(data)
        assert (hb.get_srcSystem(), hb.custom_mode) == (1, 0x10000)
        assert data[0] == 0xFD  # MAVLink 2 framing
    finally:
        other.close()


def test_receive_times_out_empty(link) -> None:
    assert link.receive(0.01) == []
