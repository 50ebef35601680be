"""A live lockstep recorder hearing a repeat of the sim (another member rejoined, a stall): the
bundles sent again (``resent``, up to ``lockstep.KEPT_PERIODS`` back) are copies, not news.

Before: the resent sim answer, stamped a period back, made ``RecordingTime`` start an episode, and
every later log time was shifted by the time flown so far (an estimator killed at 120.5 s of a run
put the rest of its recording 120.6 s later in Foxglove). And ``seaway replay --lockstep`` played the
recorded copy as a period of its own that no member takes, sending it again for ever.

The real recorder parts on the in-memory bus (its queue, ``drain``, ``LockstepWitness``,
``RecordingWriter``, the MCAP file) and the real replay of that file.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import ClockTick
from seaway.recording import reader
from seaway.recording.timebase import RecordingTime
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.lockstep_replay import LockstepPacer
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.memory_bus import MemoryHub
from seaway_recorder.core import RecordingWriter
from seaway_recorder.node import KeptKeys, SampleQueue, drain
from seaway_recorder.replay import replay

P = 100_000_000
V = "vessel1"
EPOCH_NS = 10**18
EXPRS = [f"seaway/{V}/**"]


def clock(stamp_ns: int) -> ClockTick:
    return ClockTick(stamp_ns=stamp_ns, lockstep=True, real_time_factor=0.0)


def recorder(hub: MemoryHub, folder: Path) -> tuple[RecordingWriter, Callable[[], None]]:
    """A lockstep recorder's writer on ``folder``, and what writes what it heard since (``drain``)."""
    writer = RecordingWriter(folder / "recording.mcap", compression="none",
                             time=RecordingTime(lockstep=True, epoch_ns=EPOCH_NS))
    writer.open(time.time_ns())
    queue = SampleQueue(10_000)
    bus = hub.bus(V)
    witness = LockstepWitness(bus, V, EXPRS)
    bus.subscribe_raw(f"seaway/{V}/lockstep/*", queue.on_sample)
    return writer, lambda: drain(writer, queue, None, witness, KeptKeys(EXPRS)) and None


def record_a_run_with_a_repeat(folder: Path) -> RecordingWriter:
    """Six periods of a sim whose only other member is the recorder, repeated after the fifth."""
    hub = MemoryHub()
    writer, drain = recorder(hub, folder)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    for k in range(5):
        sim.answer(Period(0, k * P), P, [(keys.SIM_CLOCK, clock(k * P))], members=["recorder"])
        drain()
    sim.repeat(["recorder"])  # the last three periods go again, two of them marked resent
    drain()
    sim.answer(Period(0, 5 * P), P, [(keys.SIM_CLOCK, clock(5 * P))], members=["recorder"])
    drain()
    writer.close()
    return writer


def test_a_repeat_starts_no_episode_and_moves_no_log_time(tmp_path: Path) -> None:
    writer = record_a_run_with_a_repeat(tmp_path)
    assert writer.time.episode == 0 and writer.time.offset_ns == EPOCH_NS
    dec = reader.decode_vessel(reader.open_paths([tmp_path]), V,
                                  [keys.SIM_CLOCK.suffix, keys.LOCKSTEP_SIM.suffix])
    ticks = dec.get(keys.SIM_CLOCK.suffix)
    assert [m.stamp_ns for m in ticks] == [k * P for k in range(6)]  # each once
    assert dec.log_ns[keys.SIM_CLOCK.suffix] == [EPOCH_NS + k * P for k in range(6)]
    # The copies of the sim's answers are kept, each at its own period's time.
    answers = dec.get(keys.LOCKSTEP_SIM.suffix)
    assert all(t == EPOCH_NS + a.stamp_ns
               for t, a in zip(dec.log_ns[keys.LOCKSTEP_SIM.suffix], answers, strict=True))
    assert sorted(a.stamp_ns // P for a in answers if a.resent) == [2, 3]


def test_a_lockstep_replay_of_it_plays_no_copy(tmp_path: Path) -> None:
    record_a_run_with_a_repeat(tmp_path)
    hub = MemoryHub()
    stop = threading.Event()
    pacer = LockstepPacer(hub.bus(V), stop, stall_s=0.3)
    est = Member(hub.bus(V), "estimator", watched=(), hears=("sim",))

    def answer() -> None:
        with est.changed:
            period, last = est.ledger.period, est.last_answer
        if period is not None and (last is None or Period.of(last) != period):
            est.answer(period, P)

    est.on_ready = answer
    est.join()
    files = reader.open_paths([tmp_path])
    t = threading.Thread(target=replay, args=(reader.iter_messages(files), hub.bus(V),
                                              lambda _key: True, None, stop), kwargs={"pacer": pacer})
    t.start()
    t.join(60)  # milliseconds of work; a copy played as a period was sent again for ever
    finished = not t.is_alive()
    stop.set()
    t.join(5)
    # Six periods and the recorded repeat of t_4 (as it was sent: not a copy), none sent again.
    assert finished and (pacer.periods, pacer.repeats) == (7, 0)


def test_a_repeat_of_a_busy_key_is_written_once() -> None:
    """What a repeat carries on one key: up to three periods of it. A key of 20 samples a period
    (attitude at 200 Hz) sends 60 again; the recorder remembered 32 and wrote the rest twice."""
    witness = LockstepWitness(MemoryHub().bus(V), V, EXPRS)
    key = keys.SIM_CLOCK.key(V)  # any key: the filter compares bytes
    sent = [clock(k * P // 20).encode() for k in range(100)]
    assert all(witness.admit(key, p) for p in sent)
    assert not any(witness.admit(key, p) for p in sent[-60:])
    assert witness.repeats_skipped == 60


def test_a_restarted_sims_first_period_is_written_though_its_bytes_repeat(tmp_path: Path) -> None:
    """A sim killed mid-run starts again at t_0, and its first messages are the old run's byte for
    byte (deterministic): the recorder must write them again, in the new episode."""
    hub = MemoryHub()
    writer, drain = recorder(hub, tmp_path)
    for sim, periods in ((Member(hub.bus(V), "sim", watched=(), subscribe=False), 3),
                         (Member(hub.bus(V), "sim", watched=(), subscribe=False), 2)):
        for k in range(periods):
            sim.answer(Period(0, k * P), P, [(keys.SIM_CLOCK, clock(k * P))], members=["recorder"])
            drain()
    writer.close()
    dec = reader.decode_vessel(reader.open_paths([tmp_path]), V, [keys.SIM_CLOCK.suffix])
    assert [m.stamp_ns // P for m in dec.get(keys.SIM_CLOCK.suffix)] == [0, 1, 2, 0, 1]
    assert writer.time.episode == 1


@pytest.mark.parametrize("carried", [False, True], ids=["bytes only", "in process"])
def test_each_answer_is_decoded_once_and_every_period_answered(tmp_path: Path, monkeypatch,
                                                               carried: bool) -> None:
    """The witness reads a member's answer once, for itself and for the writer's type check (it
    was decoded three times: to judge a restart, to check it, to note it). In process, where the
    bus hands the answer it was encoded from along (``RawSample.carried``), not at all."""
    from seaway.contract.messages import PeriodDone

    decoded: list[bytes] = []
    real = PeriodDone.decode.__func__  # type: ignore[attr-defined]

    def counting(cls: type[PeriodDone], payload: bytes) -> PeriodDone:
        decoded.append(bytes(payload))
        return real(cls, payload)

    hub = MemoryHub()
    if not carried:  # bytes alone, as from another process
        publish = hub._publish
        monkeypatch.setattr(hub, "_publish", lambda sample: publish(sample._replace(carried=None)))
    writer, drain = recorder(hub, tmp_path)
    answered: list[Period] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_RECORDER.key(V), lambda s: answered.append(
        Period.of(real(PeriodDone, s.payload.split(b"\n", 1)[0]))))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    monkeypatch.setattr(PeriodDone, "decode", classmethod(counting))
    for k in range(6):
        sim.answer(Period(0, k * P), P, [(keys.SIM_CLOCK, clock(k * P))], members=["recorder"])
        drain()
    monkeypatch.undo()
    writer.close()
    sim_answers = [d for d in decoded if b'"service":"sim"' in d]
    assert len(sim_answers) == (0 if carried else 6) and len(set(sim_answers)) == len(sim_answers)
    assert answered == [Period(0, k * P) for k in range(6)]  # and each period was answered


def test_the_witness_looks_at_its_ledger_only_after_an_answer_is_noted() -> None:
    """The recorder's loop asks the witness after every bundle it drains; only an answer noted since
    the last look can complete a period, so the ledger (under its lock) is looked at only then."""
    hub = MemoryHub()
    witness = LockstepWitness(hub.bus(V), V, EXPRS)
    looks: list[int] = []
    covers = witness.covers
    witness.covers = lambda: looks.append(1) or covers()  # type: ignore[method-assign]
    flushes: list[int] = []
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    for k in range(2):
        witness.written([(keys.lockstep_spec("sim").key(V),
                          sim.answer(Period(0, k * P), P, members=["recorder"]))])
        assert witness.maybe_answer(lambda: flushes.append(1))
        for _ in range(5):
            assert not witness.maybe_answer(lambda: flushes.append(1))
    assert (len(looks), len(flushes)) == (2, 2)
