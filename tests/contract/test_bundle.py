"""Lockstep bundles (``seaway.contract.bundle``): one sample per member per period, its answer and
the messages it lists; who may carry what; and that a subscriber of a key hears it in a bundle as
if it had been published alone (both transports: ``test_bus_contract``'s ``buses`` fixture)."""

from __future__ import annotations

import pytest
from seaway.contract import bundle, keys
from seaway.contract.messages import (
    Attitude,
    ClockTick,
    MessageError,
    PeriodDone,
    StateEstimate,
    ThrustCommand,
    message_encoding,
)
from seaway.runtime.bus import Bus
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryHub

from tests.conftest import wait_for
from tests.contract.test_bus_contract import VESSEL, buses, ready  # noqa: F401 - the fixture

P = 100_000_000


def answer(service: str, k: int, **kw) -> PeriodDone:
    return PeriodDone(stamp_ns=k * P, service=service, episode=0, seq=k + 1, period_ns=P, **kw)


def attitude(stamp_ns: int, yaw: float = 0.5) -> Attitude:
    return Attitude.make(stamp_ns=stamp_ns, roll_rad=0.0, pitch_rad=0.0, yaw_rad=yaw,
                         roll_rate_radps=0.0, pitch_rate_radps=0.0, yaw_rate_radps=0.01)


def thrust(stamp_ns: int) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=1.0, thrust_starboard_n=2.0, seq=1)


def test_each_member_carries_exactly_the_keys_it_publishes_in_lockstep() -> None:
    """What each member's loop puts in its answer (services/sim/README.md, the protocol), and no
    key of anybody else: a wrapped key of another member is refused (authority)."""
    assert bundle.suffixes_of("sim") == {
        "sensors/gnss", "sensors/attitude", "sensors/local_position", "vehicle/battery",
        "sim/truth", "sim/disturbance", "sim/clock"}
    assert bundle.suffixes_of("estimator") == {"nav/state", "nav/origin"}
    assert bundle.suffixes_of("controller") == {
        "ctrl/thrust", "ctrl/solve", "mission/status", "mission/accepted", "mission/energy",
        "area/active"}
    assert bundle.suffixes_of("recorder") == frozenset()
    assert bundle.bundled_by(keys.VEHICLE_STATUS) is None  # vehicle_io is no member
    assert bundle.bundled_by(keys.LOCKSTEP_SIM) is None
    with pytest.raises(MessageError, match="estimator carries 'ctrl/thrust', which it does not "
                                           "produce \\(its keys: nav/origin, nav/state\\)"):
        bundle.check_line("estimator", "ctrl/thrust")


def test_a_bundle_unpacks_into_its_messages_then_its_answer_bytes_unchanged() -> None:
    a1, a2 = attitude(P - 50_000_000).encode(), attitude(P).encode()
    clock = ClockTick(stamp_ns=P, lockstep=True).encode()
    done = answer("sim", 1, published={"sensors/attitude": [P // 2, P], "sim/clock": [P]})
    payload = bundle.encode(done.encode(), [("sensors/attitude", a1), ("sensors/attitude", a2),
                                            ("sim/clock", clock)])
    assert payload.count(b"\n") == 3
    key = keys.LOCKSTEP_SIM.key(VESSEL)
    assert bundle.unpack(key, payload) == [
        ("seaway/vessel1/sensors/attitude", a1, message_encoding(Attitude)),
        ("seaway/vessel1/sensors/attitude", a2, message_encoding(Attitude)),
        ("seaway/vessel1/sim/clock", clock, message_encoding(ClockTick)),
        (key, done.encode(), message_encoding(PeriodDone)),
    ]
    assert PeriodDone.decode(payload) == done  # whoever reads only the answer reads the first line
    assert bundle.lines_of(payload, {"sim/clock"}) == [("sim/clock", clock)]


@pytest.mark.parametrize(("payload", "why"), [
    (b'{"a":1}\nsensors/attitude {"stamp_ns":1}', "line 2: not"),
    (b'{"a":1}\n["sensors/attitude",{"stamp_ns":1}', "line 2: not"),
    (b'{"a":1}\n["sensors/attitude"{"stamp_ns":1}]', "line 2: not"),
])
def test_a_badly_framed_bundle_is_refused_naming_the_line(payload: bytes, why: str) -> None:
    with pytest.raises(MessageError, match=why):
        bundle.split(payload)


def test_a_bundle_wrapping_another_members_key_does_not_unpack() -> None:
    payload = bundle.encode(answer("estimator", 1).encode(), [("ctrl/thrust", thrust(P).encode())])
    with pytest.raises(MessageError, match="does not produce"):
        bundle.unpack(keys.LOCKSTEP_ESTIMATOR.key(VESSEL), payload)


def test_a_subscriber_hears_a_key_published_alone_or_in_its_producers_bundle(buses) -> None:  # noqa: F811
    a, b = buses
    heard = b.subscribe(keys.ATTITUDE, mode="fifo")
    newest = b.newest(keys.ATTITUDE)
    ready(a, b)
    a.publisher(keys.ATTITUDE).put(attitude(1, yaw=0.1))  # real time: alone on its key
    assert wait_for(lambda: heard.get(0.1), 10, what="the attitude alone").yaw_rad == 0.1
    sim = Member(a, "sim", watched=(), subscribe=False)
    sim.answer(Period(0, P), P, [(keys.ATTITUDE, attitude(P, yaw=0.2)),
                                 (keys.SIM_CLOCK, ClockTick(stamp_ns=P, lockstep=True))])
    got = wait_for(lambda: heard.get(0.1), 10, what="the attitude in the sim's bundle")
    assert (got.stamp_ns, got.yaw_rad) == (P, 0.2)
    assert wait_for(lambda: (m := newest.get()) is not None and m.stamp_ns == P and m, 10,
                    what="the newest attitude").yaw_rad == 0.2
    assert heard.drain() == []  # once: the bundle's clock is not an attitude


def test_a_member_takes_its_inputs_from_the_bundles_and_never_a_wrapped_foreign_key() -> None:
    hub = MemoryHub()
    taken: list[tuple[str, object]] = []
    ctl = Member(hub.bus(VESSEL), "controller", watched={"nav/state"}, hears=("sim", "estimator"))
    ctl.deliver = lambda key, msg: taken.append((key, msg))
    est_bus: Bus = hub.bus(VESSEL)
    state = StateEstimate.make(stamp_ns=P, x_m=1.0, y_m=2.0, psi_rad=0.0, u_mps=0.5, v_mps=0.0,
                               r_radps=0.0)
    est_bus.raw_publisher(keys.LOCKSTEP_ESTIMATOR.key(VESSEL), bundle.ENCODING).put(bundle.encode(
        answer("estimator", 1, published={"nav/state": [P]}).encode(),
        [("nav/state", state.encode()), ("ctrl/thrust", thrust(P).encode())]))
    assert taken == [("seaway/vessel1/nav/state", state)]
    assert ctl.ledger.answers["estimator"].stamp_ns == P  # then its answer, noted
    assert ctl.bus.stats.malformed == 0  # the foreign line is not one of its inputs: not read
    # ... and one of its inputs that its sender may not carry is refused and counted.
    ctl2 = Member(hub.bus(VESSEL), "controller", watched={"nav/state"}, hears=("sim", "estimator"))
    ctl2.deliver = lambda key, msg: taken.append((key, msg))
    est_bus.raw_publisher(keys.LOCKSTEP_SIM.key(VESSEL), bundle.ENCODING).put(bundle.encode(
        answer("sim", 1).encode(), [("nav/state", state.encode())]))
    assert ctl2.bus.stats.malformed == 1 and len(taken) == 1


def test_a_member_needs_to_hear_the_bundles_its_inputs_come_in() -> None:
    with pytest.raises(ValueError, match="inputs ctrl/thrust come in no bundle it hears"):
        Member(MemoryHub().bus(VESSEL), "estimator", watched={"ctrl/thrust"}, hears=("sim",))


def test_every_sample_of_a_key_is_taken_in_order_alone_or_out_of_bundles(buses) -> None:  # noqa: F811
    """``Bus.every``: what a reader that looks a few times a second must not miss (the launcher's
    energy budgets), held by the transport, in order, however many periods passed between looks."""
    a, b = buses
    every = b.every(keys.THRUST)
    ready(a, b)
    a.publisher(keys.THRUST).put(thrust(1))
    wait_for(lambda: (got := every.take()) and got, 10, what="the command alone")
    ctl = Member(a, "controller", watched=(), subscribe=False)
    for k in range(1, 31):  # no command in every third period
        ctl.answer(Period(0, k * P), P, [(keys.THRUST, thrust(k * P))] if k % 3 else [])
    got: list[ThrustCommand] = []
    wait_for(lambda: (got.extend(every.take()), len(got) >= 20)[1], 10, what="20 commands")
    assert [c.stamp_ns for c in got] == [k * P for k in range(1, 31) if k % 3]
