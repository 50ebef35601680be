"""The bus interface: the in-memory bus and the Zenoh bus pass the same behavioural tests.

Each test gets two buses on one network, ``a`` and ``b``, as two processes would have: a
``MemoryHub`` for the in-memory bus, or two Zenoh sessions meeting at a private rendezvous port. A
test waits for ``b``'s declarations to be known to ``a`` the way the launcher does: ``b`` declares a
health token after them, and ``a`` waits to see it (Zenoh sends declarations in order).
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator

import pytest
from seaway.contract import keys
from seaway.contract.messages import (
    ArmRequest,
    Reply,
    ScenarioRequest,
    StateEstimate,
    ThrustCommand,
    message_encoding,
)
from seaway.runtime.bus import Bus
from seaway.runtime.bus_raw import RAW_ENCODING, RawSample
from seaway.runtime.memory_bus import MemoryBus, MemoryHub
from seaway.runtime.zenoh_bus import ZenohBus

from tests.conftest import wait_for

VESSEL = "vessel1"


@pytest.fixture(params=["memory", pytest.param("zenoh", marks=pytest.mark.system)])
def buses(request: pytest.FixtureRequest) -> Iterator[tuple[Bus, Bus]]:
    if request.param == "memory":
        hub = MemoryHub()
        a, b = hub.bus(VESSEL), hub.bus(VESSEL)
        assert isinstance(a, MemoryBus)
    else:
        request.getfixturevalue("zenoh_env")  # a private rendezvous port for this test's sessions
        a, b = Bus.open(VESSEL), Bus.open(VESSEL)
        assert isinstance(a, ZenohBus)
    try:
        yield a, b
    finally:
        a.close()
        b.close()


def ready(a: Bus, b: Bus, name: str = "recorder") -> None:
    """``b`` has declared what it serves; wait until ``a`` knows (b's health token is visible)."""
    b.declare_alive(name)
    wait_for(lambda: name in a.alive_services(timeout_s=0.5), 10, what=f"{name}'s health token")


def thrust(seq: int, port_n: float = 1.0) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=seq, thrust_port_n=port_n, thrust_starboard_n=0.0, seq=seq)


def test_typed_messages_in_order_and_latest_only(buses) -> None:
    a, b = buses
    fifo = b.subscribe(keys.THRUST, mode="fifo")
    latest = b.subscribe(keys.THRUST, mode="latest")
    ready(a, b)
    pub = a.publisher(keys.THRUST)
    for seq in range(1, 21):
        pub.put(thrust(seq))
    got = [fifo.get(5.0) for _ in range(20)]
    assert [m.seq for m in got if m is not None] == list(range(1, 21))
    # The two subscriptions are delivered independently (on Zenoh, possibly later than the fifo's
    # last sample): wait until the latest-only one has seen the 20th, then it holds only that one.
    last = latest.get(5.0)
    while last is not None and last.seq < 20:
        last = latest.get(5.0)
    assert last == thrust(20) and latest.latest() is None
    assert (a.stats.published, b.stats.received) == (20, 40)  # two subscriptions, each counts


def test_newest_decodes_only_the_sample_it_is_asked_for(buses) -> None:
    a, b = buses
    newest = b.newest(keys.THRUST)
    fifo = b.subscribe(keys.THRUST, mode="fifo")  # to know when every sample has arrived
    ready(a, b)
    assert newest.get() is None
    pub = a.publisher(keys.THRUST)
    for seq in range(1, 11):
        pub.put(thrust(seq))
    got = [fifo.get(5.0) for _ in range(10)]
    assert [m.seq for m in got if m is not None] == list(range(1, 11))
    received = b.stats.received
    wait_for(lambda: newest.get() == thrust(10), 5, what="the newest sample")
    # The nine before it were never decoded: one more received, not ten.
    assert b.stats.received == received + 1
    assert newest.get() == thrust(10) and b.stats.received == received + 1  # decoded once
    # A malformed newest sample is counted when read; the last good message stays the answer.
    fifo.undeclare()  # (it would count the malformed sample too)
    a.raw_publisher(keys.THRUST.key(VESSEL), message_encoding(ThrustCommand)).put(b'{"seq": "x"}')
    wait_for(lambda: newest.get() is not None and b.stats.malformed == 1, 5,
             what="the malformed sample counted when read")
    assert newest.get() == thrust(10) and b.stats.malformed == 1
    pub.put(thrust(11))
    wait_for(lambda: newest.get() == thrust(11), 5, what="a good sample after it")


def test_wrong_type_and_non_finite_refused_before_the_wire(buses) -> None:
    a, b = buses
    sub = b.subscribe(keys.THRUST, mode="fifo")
    ready(a, b)
    with pytest.raises(TypeError, match="carries StateEstimate, not ThrustCommand"):
        a.publisher(keys.NAV_STATE).put(thrust(1))
    pub = a.publisher(keys.THRUST)
    nan = ThrustCommand.model_construct(stamp_ns=1, thrust_port_n=float("nan"), thrust_starboard_n=0.0,
                                        source="", seq=1)
    with pytest.raises(ValueError, match=r"ThrustCommand\.thrust_port_n: not finite"):
        pub.put(nan)
    pub.put(thrust(2))
    assert sub.get(5.0) == thrust(2) and sub.get(0.2) is None  # nothing else reached the wire
    assert a.stats.published == 1


def test_malformed_payloads_are_counted_and_dropped(buses) -> None:
    a, b = buses
    sub = b.subscribe(keys.THRUST, mode="fifo")
    ready(a, b)
    key = keys.THRUST.key(VESSEL)
    raw = a.raw_publisher(key)
    raw.put(b'{"stamp_ns": 1, "thrust_port_n": NaN, "thrust_starboard_n": 0}')
    raw.put(b"\x00\x01garbage")
    a.publisher(keys.THRUST).put(thrust(3))
    assert sub.get(5.0) == thrust(3) and sub.get(0.2) is None
    assert (b.stats.malformed, b.stats.malformed_by_key, b.stats.received) == (2, {key: 2}, 1)
    assert b.stats.last_error.startswith(f"{key}: ThrustCommand")


def test_requests_are_answered_refused_or_reported_missing(buses) -> None:
    a, b = buses

    def on_arm(req: ArmRequest) -> Reply:
        if req.force:
            raise RuntimeError("handler bug")
        if req.arm:
            return Reply.accept(7, "armed", by="test")
        return Reply.refuse(7, "disarm refused by test")

    b.queryable(keys.VEHICLE_ARM, on_arm)
    ready(a, b)
    ok = a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True), timeout_s=3)
    assert (ok.accepted, ok.reason, ok.detail) == (True, "armed", {"by": "test"})
    no = a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=False), timeout_s=3)
    assert (no.accepted, no.reason) == (False, "disarm refused by test")
    bug = a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True, force=True), timeout_s=3)
    assert not bug.accepted and bug.reason == "internal error: RuntimeError: handler bug"
    with pytest.raises(TypeError, match="vehicle/arm takes ArmRequest, not ThrustCommand"):
        a.request(keys.VEHICLE_ARM, thrust(1))

    # Malformed and empty requests are refused (and counted) by the server, which goes on serving.
    key = keys.VEHICLE_ARM.key(VESSEL)
    bad = [Reply.decode(r.payload) for r in a.query_raw(key, b"{not json", timeout_s=3)]
    assert len(bad) == 1 and not bad[0].accepted and bad[0].reason.startswith("malformed request: ")
    empty = [Reply.decode(r.payload) for r in a.query_raw(key, None, timeout_s=3)]
    assert "empty request" in empty[0].reason
    assert b.stats.malformed_by_key == {key: 2}
    assert a.request(keys.VEHICLE_ARM, ArmRequest.make(stamp_ns=1, arm=True), timeout_s=3).accepted

    # Nobody serving: a refusal that says so, never an exception.
    r = a.request(keys.SIM_SCENARIO, ScenarioRequest.make(stamp_ns=1, action="restart"), timeout_s=0.3)
    assert not r.accepted and r.reason == ("no reply from seaway/vessel1/sim/scenario within 0.3 s "
                                           "(is the service running?)")


def test_every_queryable_answers_a_census(buses) -> None:
    a, b = buses
    for bus, name in ((a, "sim"), (b, "estimator")):
        key = keys.run_description_key(VESSEL, name)
        bus.queryable_raw(key, lambda _payload, name=name: json.dumps({"service": name}).encode())
    ready(a, b)
    got = {r.key: json.loads(r.payload) for r in a.query_raw(keys.run_description_wildcard(VESSEL),
                                                            timeout_s=3, every=True)}
    assert got == {keys.run_description_key(VESSEL, n): {"service": n} for n in ("sim", "estimator")}


def test_health_tokens_come_and_go(buses) -> None:
    a, b = buses
    seen: list[tuple[str, bool]] = []
    changed = threading.Event()

    def on_health(service: str, alive: bool) -> None:
        seen.append((service, alive))
        changed.set()

    a.declare_alive("controller")
    a.watch_health(on_health)
    wait_for(lambda: ("controller", True) in seen, 5, what="the current tokens first")
    b.declare_alive("estimator")
    wait_for(lambda: ("estimator", True) in seen, 10, what="estimator's token")
    assert a.alive_services(timeout_s=1) == {"controller", "estimator"}
    b.close()
    wait_for(lambda: ("estimator", False) in seen, 10, what="estimator's token gone")
    assert a.alive_services(timeout_s=1) == {"controller"}


def test_raw_samples_keep_bytes_keys_and_encodings(buses) -> None:
    a, b = buses
    samples: list[RawSample] = []
    b.subscribe_raw(keys.vessel_wildcard(), samples.append)
    ready(a, b)
    msg = thrust(4)
    a.publisher(keys.THRUST).put(msg)
    a.raw_publisher(f"seaway/{VESSEL}/shore/heartbeat", "text/plain", block=True).put(b"\x00beat")
    a.raw_publisher(f"seaway/{VESSEL}/x").put(b"{}")
    wait_for(lambda: len(samples) >= 3, 5, what="three raw samples")
    assert [s._replace(published_ns=None, carried=None) for s in samples] == [
        RawSample(keys.THRUST.key(VESSEL), msg.encode(), message_encoding(ThrustCommand)),
        RawSample(f"seaway/{VESSEL}/shore/heartbeat", b"\x00beat", "text/plain"),
        RawSample(f"seaway/{VESSEL}/x", b"{}", RAW_ENCODING),
    ]
    # In one process the typed publisher's message rides along with its bytes; from Zenoh (another
    # process) only bytes come, and raw bytes never carry anything.
    assert samples[0].carried is (msg if isinstance(b, MemoryBus) else None)
    assert [s.carried for s in samples[1:]] == [None, None]
    # Zenoh stamps each sample where it is published; the in-memory bus has no such clock.
    for s in samples:
        assert s.published_ns is None or abs(s.published_ns - time.time_ns()) < 60 * 10**9
    assert message_encoding(StateEstimate) == "application/json;seaway.v1.StateEstimate"


@pytest.mark.system
def test_a_late_subscriber_with_history_gets_what_a_topic_published_before_it(zenoh_env) -> None:
    # A recorder restarted in real time (#56 item 20): a topic's publisher keeps its last samples,
    # a subscriber that asks for history gets them, stamped with their publication time, then the
    # live ones; one without history does not.
    with Bus.open(VESSEL) as a, Bus.open(VESSEL) as b:
        pub = a.publisher(keys.THRUST)
        t0 = time.time_ns()
        for seq in range(1, 6):
            pub.put(thrust(seq))
        recalled: list[RawSample] = []
        plain: list[RawSample] = []
        b.subscribe_raw(keys.THRUST.key(VESSEL), recalled.append, history_s=10.0)
        wait_for(lambda: len(recalled) >= 5, 10, what="the five published before")
        # Only now: a put before a peer knows the other's subscriptions may be sent to it anyway
        # (Zenoh's initial interest), and arrive later; the cache's replies follow the puts on the
        # same link, so once the five are recalled none is still on its way. Declared before the
        # wait, on a loaded machine this subscriber got all six.
        b.subscribe_raw(keys.THRUST.key(VESSEL), plain.append)
        ready(b, a, "controller")
        pub.put(thrust(6))
        wait_for(lambda: len(recalled) >= 6 and plain, 10, what="the live one")
    assert [json.loads(s.payload)["seq"] for s in recalled] == [1, 2, 3, 4, 5, 6]
    assert [json.loads(s.payload)["seq"] for s in plain] == [6]
    assert all(t0 <= s.published_ns <= time.time_ns() for s in recalled)  # type: ignore[operator]
