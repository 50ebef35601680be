"""The in-memory bus's own promises: synchronous delivery, Zenoh's key matching, timeouts, closing.

What it shares with the Zenoh bus (typed refusals, malformed payloads, replies, health tokens) is
tested against both in tests/contract/test_bus_contract.py.
"""

from __future__ import annotations

import threading
import time

import pytest
from seaway.contract import keys
from seaway.contract.messages import ArmRequest, Reply, ThrustCommand
from seaway.runtime.bus import Bus, iterate
from seaway.runtime.memory_bus import MemoryBus, MemoryHub, intersects


def thrust(seq: int) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=seq, thrust_port_n=1.0, thrust_starboard_n=2.0, seq=seq)


def test_delivery_is_done_when_put_returns() -> None:
    bus = MemoryBus("vessel1")  # one bus hears itself, as one Zenoh session does
    fifo = bus.subscribe(keys.THRUST, mode="fifo")
    heard: list[tuple[str, ThrustCommand]] = []
    bus.subscribe(keys.THRUST, callback=lambda k, m: heard.append((k, m)))
    bus.publisher(keys.THRUST).put(thrust(1))
    assert fifo.drain() == [thrust(1)]
    assert heard == [("seaway/vessel1/ctrl/thrust", thrust(1))]
    assert isinstance(bus, Bus) and not hasattr(bus, "session")  # no Zenoh-only shortcuts here


def test_buses_on_one_hub_are_separate_processes_on_one_network() -> None:
    hub = MemoryHub()
    boat1, boat2, shore = hub.bus("boat1"), hub.bus("boat2"), hub.bus("boat1")
    mine = shore.subscribe(keys.THRUST, mode="fifo")
    every = shore.subscribe(keys.THRUST, mode="fifo", vessel="*")
    boat1.publisher(keys.THRUST).put(thrust(1))
    boat2.publisher(keys.THRUST).put(thrust(2))
    assert [m.seq for m in mine.drain()] == [1]
    assert [m.seq for m in every.drain()] == [1, 2]
    assert (boat1.stats.published, shore.stats.received, MemoryBus("boat1").stats.received) == (1, 3, 0)


def test_fifo_overflow_is_counted_and_latest_keeps_one() -> None:
    bus = MemoryBus()
    fifo = bus.subscribe(keys.THRUST, mode="fifo", capacity=2)
    latest = bus.subscribe(keys.THRUST)
    pub = bus.publisher(keys.THRUST)
    for seq in (1, 2, 3):
        pub.put(thrust(seq))
    assert fifo.dropped_overflow == 1 and [m.seq for m in fifo.drain()] == [2, 3]
    assert latest.dropped_overflow == 0 and latest.latest() == thrust(3)
    assert fifo.get(0.0) is None and fifo.get(0.01) is None


def test_a_failing_callback_reaches_neither_the_publisher_nor_other_subscribers() -> None:
    bus = MemoryBus()

    def broken(_key: str, _msg: ThrustCommand) -> None:
        raise RuntimeError("bug in a handler")

    raw: list[bytes] = []
    bus.subscribe(keys.THRUST, callback=broken)
    bus.subscribe_raw(keys.THRUST.key("vessel1"), lambda s: (_ for _ in ()).throw(RuntimeError("raw")))
    bus.subscribe_raw(keys.THRUST.key("vessel1"), lambda s: raw.append(s.payload))
    bus.publisher(keys.THRUST).put(thrust(1))  # does not raise
    assert raw == [thrust(1).encode()] and bus.stats.received == 1


def test_undeclared_and_closed_buses_hear_nothing() -> None:
    hub = MemoryHub()
    a, b = hub.bus(), hub.bus()
    sub = b.subscribe(keys.THRUST, mode="fifo")
    other = b.subscribe(keys.THRUST, mode="fifo")
    pub = a.publisher(keys.THRUST)
    sub.undeclare()
    pub.put(thrust(1))
    assert sub.drain() == [] and other.drain() == [thrust(1)]
    b.queryable(keys.VEHICLE_ARM, lambda req: Reply.accept(1, "ok"))
    b.close()
    b.close()  # idempotent
    pub.put(thrust(2))
    assert other.drain() == []
    r = a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True), timeout_s=0.1)
    assert not r.accepted and r.reason.startswith("no reply from seaway/vessel1/vehicle/arm")
    with pytest.raises(RuntimeError, match="closed"):
        b.publisher(keys.THRUST)
    a.close()
    with pytest.raises(RuntimeError, match="closed"):
        pub.put(thrust(3))


def test_a_slow_handler_is_no_reply_within_the_timeout() -> None:
    hub = MemoryHub()
    a, b = hub.bus(), hub.bus()
    release = threading.Event()

    def slow(req: ArmRequest) -> Reply:
        release.wait(5.0)
        return Reply.accept(1, "too late")

    b.queryable(keys.VEHICLE_ARM, slow)
    t0 = time.monotonic()
    r = a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True), timeout_s=0.2)
    assert 0.2 <= time.monotonic() - t0 < 2.0
    assert not r.accepted and r.reason == ("no reply from seaway/vessel1/vehicle/arm within 0.2 s "
                                           "(is the service running?)")
    release.set()


def test_a_handler_may_use_the_bus_and_its_publications_arrive_before_the_reply() -> None:
    hub = MemoryHub()
    server, client = hub.bus(), hub.bus()
    events = client.subscribe(keys.THRUST, mode="fifo")
    echo = server.publisher(keys.THRUST)

    def on_arm(req: ArmRequest) -> Reply:
        echo.put(thrust(9))
        return Reply.accept(1, "armed")

    server.queryable(keys.VEHICLE_ARM, on_arm)
    assert client.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True)).accepted
    assert events.drain() == [thrust(9)]


def test_health_tokens_count_per_declaration() -> None:
    hub = MemoryHub()
    a, b = hub.bus(), hub.bus()
    seen: list[tuple[str, bool]] = []
    a.watch_health(lambda s, alive: seen.append((s, alive)))
    b.declare_alive("estimator")
    a.declare_alive("estimator")  # a restarted twin: the service stays alive while one is
    b.close()
    assert a.alive_services() == {"estimator"} and seen == [("estimator", True)]
    a.close()
    assert hub.bus().alive_services() == set()
    assert seen == [("estimator", True), ("estimator", False)]


def test_key_expressions_match_as_on_zenoh() -> None:
    assert intersects("seaway/**", "seaway/v1/ctrl/thrust") and intersects("seaway/**", "seaway")
    assert intersects("seaway/*/ctrl/thrust", "seaway/v2/ctrl/thrust")
    assert not intersects("seaway/*/ctrl/thrust", "seaway/v2/x/ctrl/thrust")
    assert not intersects("seaway/v1/**", "seaway/v2/nav/state")
    bus = MemoryBus()
    with pytest.raises(Exception, match="seaway//x"):  # refused when declared, as Zenoh does
        bus.raw_publisher("seaway//x")


def test_iterate_yields_in_order_until_stopped() -> None:
    bus = MemoryBus()
    sub = bus.subscribe(keys.THRUST, mode="fifo")
    pub = bus.publisher(keys.THRUST)
    for seq in (1, 2, 3):
        pub.put(thrust(seq))
    stop = threading.Event()
    got = []
    for msg in iterate(sub, stop, poll_s=0.01):
        got.append(msg.seq)
        if msg.seq == 3:
            stop.set()
    assert got == [1, 2, 3]


def test_a_reaction_reaches_nobody_before_its_cause() -> None:
    """A subscriber that publishes as it is handed a sample: its sample is delivered once the one
    it reacts to has reached every subscriber (a lockstep member's ring holds the sim's bundle
    before the estimator's answer to it comes), and the first put returns once both are."""
    hub = MemoryHub()
    reacting, hearing = hub.bus(), hub.bus()
    heard: list[str] = []
    reaction = reacting.raw_publisher("seaway/vessel1/reaction")
    reacting.subscribe_raw("seaway/vessel1/cause", lambda _s: reaction.put(b"2"))  # first in line
    hearing.subscribe_raw("seaway/vessel1/*", lambda s: heard.append(s.key.rsplit("/", 1)[1]))
    hub.bus().raw_publisher("seaway/vessel1/cause").put(b"1")
    assert heard == ["cause", "reaction"]
