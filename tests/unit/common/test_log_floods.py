"""Issue 14, item 7: 10,000 malformed samples a second wrote one WARNING each (52 MB on the terminal,
21 MB of recorder log). The typed bus, which every service reads through, now logs a kind of
problem once per key and then at most every few seconds with the count; the counts stay exact.
In memory (the same typed layer as on Zenoh), so the flood is fast and the test deterministic."""

from __future__ import annotations

import logging

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, Reply
from seaway.runtime.memory_bus import MemoryHub

FLOOD = 10_000


def bus_lines(caplog: pytest.LogCaptureFixture, text: str) -> list[logging.LogRecord]:
    return [r for r in caplog.records if r.name == "seaway.runtime.bus" and text in r.getMessage()]


def test_a_flood_of_malformed_samples_is_counted_not_echoed(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.runtime.bus")
    hub = MemoryHub()
    victim, attacker = hub.bus("vessel1"), hub.bus("vessel1")
    heard = []
    victim.subscribe(keys.THRUST, callback=lambda _k, m: heard.append(m))
    raw = attacker.raw_publisher(keys.THRUST.key("vessel1"))
    for i in range(FLOOD):
        raw.put(b'{"stamp_ns": %d, "thrust_port_n": "junk"}' % i)
    assert victim.stats.malformed == FLOOD and heard == []
    lines = bus_lines(caplog, "dropped malformed payload")
    assert 1 <= len(lines) <= 2, len(lines)  # the first, and at most one more in a few seconds
    assert "seaway/vessel1/ctrl/thrust" in lines[0].getMessage()


def test_a_failing_handler_is_one_traceback_not_thousands(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.runtime.bus")
    hub = MemoryHub()
    bus = hub.bus("vessel1")

    def broken(_key: str, _msg: object) -> None:
        raise ValueError("math domain error")

    bus.subscribe(keys.THRUST, callback=broken)
    pub = bus.publisher(keys.THRUST)
    from seaway.contract.messages import ThrustCommand

    for i in range(FLOOD):
        pub.put(ThrustCommand(stamp_ns=i, thrust_port_n=0.0, thrust_starboard_n=0.0))
    lines = bus_lines(caplog, "handler for seaway/vessel1/ctrl/thrust failed")
    assert 1 <= len(lines) <= 2 and lines[0].exc_info is not None


def test_a_flood_of_malformed_requests_is_refused_each_time_and_logged_once(caplog) -> None:
    caplog.set_level(logging.INFO, "seaway.runtime.bus")
    hub = MemoryHub()
    server, client = hub.bus("vessel1"), hub.bus("vessel1")
    server.queryable(keys.VEHICLE_ARM, lambda req: Reply.accept(1))
    key = keys.VEHICLE_ARM.key("vessel1")
    for _ in range(1000):
        (r,) = list(client.query_raw(key, b'{"stamp_ns": 1, "junk": 2}', 1.0))
        assert not Reply.decode(r.payload).accepted
    assert server.stats.malformed == 1000
    assert 1 <= len(bus_lines(caplog, "refused malformed request")) <= 2
    assert client.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True)).accepted
