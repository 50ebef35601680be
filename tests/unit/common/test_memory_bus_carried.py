"""In one process the in-memory bus hands along what a sample's bytes were encoded from
(``RawSample.carried``): a receiver takes the publisher's own (frozen) message and decodes nothing.
Bytes that carry nothing (a raw publisher, anything from another process) are decoded and, when
malformed, refused and counted, as on Zenoh."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from seaway.contract import bundle, keys
from seaway.contract.messages import ClockTick, Message, PeriodDone, ThrustCommand
from seaway.runtime.bus_raw import RawSample
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.memory_bus import MemoryBus, MemoryHub

P = 100_000_000
V = "vessel1"


@pytest.fixture
def decodes(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """The names of the message types decoded from bytes meanwhile (every ``Message.decode``,
    which ``PeriodDone.decode`` ends in)."""
    seen: list[str] = []
    real = Message.decode.__func__  # type: ignore[attr-defined]

    def counting(cls: type[Message], data: bytes) -> Message:
        seen.append(cls.__name__)
        return real(cls, data)  # type: ignore[no-any-return]

    monkeypatch.setattr(Message, "decode", classmethod(counting))
    yield seen


@pytest.fixture
def splits(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[bytes]]:
    """The bundles whose bytes were split into lines meanwhile (``bundle.split``)."""
    seen: list[bytes] = []
    real = bundle.split

    def counting(payload: bytes) -> tuple[bytes, list[tuple[str, bytes]]]:
        seen.append(payload)
        return real(payload)

    monkeypatch.setattr(bundle, "split", counting)
    yield seen


def thrust(stamp_ns: int) -> ThrustCommand:
    return ThrustCommand.make(stamp_ns=stamp_ns, thrust_port_n=1.5, thrust_starboard_n=-2.0, seq=3)


def test_a_subscriber_gets_the_publishers_message_itself_and_decodes_nothing(
        decodes: list[str]) -> None:
    hub = MemoryHub()
    heard: list[ThrustCommand] = []
    rx = hub.bus(V)
    rx.subscribe(keys.THRUST, callback=lambda _k, m: heard.append(m))
    raw: list[RawSample] = []
    rx.subscribe_raw(keys.THRUST.key(V), raw.append)
    sent = thrust(7)
    hub.bus(V).publisher(keys.THRUST).put(sent)
    assert heard == [sent] and heard[0] is sent
    assert decodes == []
    assert raw[0].payload == sent.encode()  # the bytes travel all the same (a recorder's)
    assert rx.stats.received == 1


def test_bytes_that_carry_nothing_are_decoded_and_malformed_ones_refused(decodes: list[str]) -> None:
    """A raw publisher's bytes (as a Zenoh sample's: nothing carried) are decoded: a new message
    equal to what was encoded, and a malformed payload is counted and dropped."""
    hub = MemoryHub()
    rx = hub.bus(V)
    heard: list[ThrustCommand] = []
    rx.subscribe(keys.THRUST, callback=lambda _k, m: heard.append(m))
    tx = hub.bus(V).raw_publisher(keys.THRUST.key(V))
    sent = thrust(7)
    tx.put(sent.encode())
    assert heard == [sent] and heard[0] is not sent and decodes == ["ThrustCommand"]
    tx.put(b'{"stamp_ns": 8, "thrust_port_n": "lots"}')
    assert len(heard) == 1 and rx.stats.malformed == 1
    assert "thrust_port_n" in rx.stats.last_error


def test_a_carried_object_of_another_type_is_not_taken(decodes: list[str]) -> None:
    """Only a message of the key's own type is taken as it is; anything else, the bytes decide."""
    bus = MemoryBus(V)
    heard: list[ThrustCommand] = []
    bus.subscribe(keys.THRUST, callback=lambda _k, m: heard.append(m))
    sent = thrust(7)
    pub = bus.raw_publisher(keys.THRUST.key(V))
    pub.put_carrying(sent.encode(), ClockTick(stamp_ns=7, lockstep=True))  # type: ignore[attr-defined]
    assert heard == [sent] and decodes == ["ThrustCommand"]
    pub.put_carrying(b"{not json", sent)  # type: ignore[attr-defined]
    assert heard == [sent, sent] and decodes == ["ThrustCommand"]  # in process, trusted as sent


def test_a_member_takes_a_bundles_answer_and_messages_as_sent(decodes: list[str],
                                                              splits: list[bytes]) -> None:
    """The estimator hears the sim's bundle: its answer and the messages it lists are the sim's
    own objects, and the bundle's lines as the sim framed them (its bytes are not split again);
    a subscriber of one of its keys (a display) gets the sim's object too."""
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched={keys.SIM_CLOCK.suffix}, hears=("sim",))
    taken: list[ClockTick] = []
    est.deliver = lambda _key, msg: (taken.append(msg), est.saw(keys.SIM_CLOCK.suffix, msg.stamp_ns))
    display: list[ClockTick] = []
    hub.bus(V).subscribe(keys.SIM_CLOCK, callback=lambda _k, m: display.append(m))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    tick = ClockTick(stamp_ns=P, lockstep=True)
    done = sim.answer(Period(0, P), P, [(keys.SIM_CLOCK, tick)])
    assert taken[0] is tick and display[0] is tick
    assert est.ledger.answer("sim") is done
    assert decodes == [] and splits == []
    again = sim.repeat()  # a repeat carries its objects too
    assert again is not None and est.ledger.answers["sim"] is again and decodes == []
    assert splits == []


def test_a_carried_bundle_unpacks_as_its_bytes_do(splits: list[bytes]) -> None:
    """What a recorder writes of a bundle in process (``unpack`` with what it carries) is what it
    writes of the same bytes from another process, and its bytes are not split."""
    tick = ClockTick(stamp_ns=P, lockstep=True)
    answer = PeriodDone(stamp_ns=P, service="sim", episode=0, seq=1, period_ns=P,
                        published={keys.SIM_CLOCK.suffix: [P]})
    payload, carried = bundle.Carried.of(answer, answer.encode(),
                                         [(keys.SIM_CLOCK.suffix, tick.encode())], [tick])
    key = keys.lockstep_spec("sim").key(V)
    assert bundle.unpack(key, payload, carried) and splits == []
    assert bundle.unpack(key, payload, carried) == bundle.unpack(key, payload)
    assert len(splits) == 1
    assert not bundle.is_resent(payload, carried)
    resent = answer.model_copy(update={"resent": True})
    assert bundle.is_resent(*bundle.Carried.of(resent, resent.encode(), [], []))


def test_a_bundle_that_carries_nothing_is_decoded_and_a_malformed_line_refused(
        decodes: list[str]) -> None:
    """The same bundle's bytes alone (from another process) are decoded; a line that does not
    decode is counted and not handed on, and the answer after it is still noted."""
    hub = MemoryHub()
    est = Member(hub.bus(V), "estimator", watched={keys.SIM_CLOCK.suffix}, hears=("sim",))
    taken: list[ClockTick] = []
    est.deliver = lambda _key, msg: (taken.append(msg), est.saw(keys.SIM_CLOCK.suffix, msg.stamp_ns))
    pub = hub.bus(V).raw_publisher(keys.lockstep_spec("sim").key(V), bundle.ENCODING)
    tick = ClockTick(stamp_ns=P, lockstep=True)
    answer = PeriodDone(stamp_ns=P, service="sim", episode=0, seq=1, period_ns=P,
                        published={keys.SIM_CLOCK.suffix: [P]})
    pub.put(bundle.encode(answer.encode(), [(keys.SIM_CLOCK.suffix, tick.encode())]))
    assert taken == [tick] and taken[0] is not tick
    assert est.ledger.answer("sim") == answer
    assert sorted(decodes) == ["ClockTick", "PeriodDone"]
    bad = answer.model_copy(update={"stamp_ns": 2 * P, "seq": 2,
                                    "published": {keys.SIM_CLOCK.suffix: [2 * P]}})
    malformed_before = est.bus.stats.malformed
    pub.put(bundle.encode(bad.encode(), [(keys.SIM_CLOCK.suffix, b'{"stamp_ns":-1}')]))
    assert taken == [tick] and est.bus.stats.malformed == malformed_before + 1
    assert est.ledger.period == Period(0, 2 * P) and not est.ledger.complete(est.ledger.answer("sim"))


def test_a_composed_launcher_reads_the_answer_carried_not_the_bytes(decodes: list[str]) -> None:
    """The launcher's liveness watch takes each answer's period from the answer the bundle was
    encoded from, where the bus hands one along: no JSON is read (bytes it could not read give the
    carried period); a resent copy is no news either way; bytes alone are still read."""
    from seaway.tools.launch.liveness import answer_period

    answer = PeriodDone(stamp_ns=P, service="sim", episode=2, seq=1, period_ns=P, hold=True,
                        published={})
    carried = bundle.Carried(answer, (), answer.encode(), ())
    assert answer_period(b"not json", carried) == ((2, P), True)
    resent = answer.model_copy(update={"resent": True})
    assert answer_period(b"not json", bundle.Carried(resent, (), resent.encode(), ())) == \
        (None, False)
    assert answer_period(bundle.encode(answer.encode(), [])) == ((2, P), True)
    assert answer_period(b"not json") == (None, False)
    assert decodes == []


def test_is_resent_agrees_with_the_decoded_answer_whatever_its_spelling() -> None:
    """A recorder writes a copy as a copy and a typed subscriber drops only copies: what
    ``is_resent`` says of a bundle's bytes is what decoding its answer says, for our encoder's
    bytes and for any other valid spelling of the same answer."""
    import json

    base = {"stamp_ns": 100_000_000, "service": "sim", "episode": 0, "seq": 3,
            "period_ns": 100_000_000}
    tick = ClockTick(stamp_ns=P, lockstep=True, real_time_factor=0.0).encode()
    ours = PeriodDone(**base)
    answers = [
        ours.encode(),
        ours.model_copy(update={"resent": True}).encode(),
        json.dumps({**base, "resent": True}).encode(),  # json.dumps' spacing
        json.dumps({**base, "resent": False}).encode(),
        json.dumps({**base, "ext": {"resent": True}}, separators=(",", ":")).encode(),
        json.dumps({**base, "note": '"resent":true'}, separators=(",", ":")).encode(),
        json.dumps({**base, "resent": True, "hold": False}, separators=(",", ":")).encode(),
        json.dumps(base, separators=(",", ":")).encode()[:-1] + b',"\\u0072esent":true}',
        json.dumps(base, separators=(",", ":")).encode()[:-1] + b',"resent":true,"resent":false}',
        json.dumps({**base, "resent": 1}).encode(),  # a decoder takes 1 for true
        json.dumps(base, separators=(",", ":")).encode(),  # no field: the default
    ]
    for raw in answers:
        assert bundle.is_resent(bundle.encode(raw, [("sim/clock", tick)])) \
            == PeriodDone.decode(raw).resent, raw
    assert not bundle.is_resent(b'{"stamp_ns":-1,"resent": true}')  # no answer: no copy
