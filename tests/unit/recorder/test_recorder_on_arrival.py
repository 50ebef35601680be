"""A lockstep recorder writes each period on the thread that delivers it (``RecorderNode``'s
``write_on_arrival``): composed, the period is on disk and answered before the sim's put returns,
and the writer's loop is not woken for it.

Before: every period was handed to the loop's thread (``SampleQueue.arrived``), two thread switches
a period, and a composed sim waited for them. The real recorder parts on the in-memory bus (its
queue, node, ``LockstepWitness``, ``RecordingWriter``, the MCAP file).
"""

from __future__ import annotations

import threading
import time
from pathlib import Path
from types import SimpleNamespace

from seaway.contract import keys
from seaway.contract.messages import PeriodDone
from seaway.recording import reader
from seaway.recording.timebase import RecordingTime
from seaway.runtime.lockstep import Period
from seaway.runtime.lockstep_member import Member
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.memory_bus import MemoryHub
from seaway_recorder.core import RecordingWriter
from seaway_recorder.node import KeptKeys, RecorderNode, SampleQueue

from tests.unit.recorder.test_recorder_repeats import EPOCH_NS, EXPRS, P, V, clock


class Recorder:
    """A lockstep recorder node on ``hub``, its loop never run; ``looping``: after its first tick
    (it joined just before, as the driver makes it: ``Node.joining``)."""

    def __init__(self, hub: MemoryHub, folder: Path, looping: bool = True) -> None:
        self.writer = RecordingWriter(folder / "recording.mcap", compression="none",
                                      time=RecordingTime(lockstep=True, epoch_ns=EPOCH_NS))
        self.writer.open(time.time_ns())
        self.queue = SampleQueue(10_000)
        bus = hub.bus(V)
        witness = LockstepWitness(bus, V, EXPRS)
        bus.subscribe_raw(f"seaway/{V}/**", self.queue.on_sample, inline=True)
        self.node = RecorderNode(self.writer, self.queue, flush_s=60.0, status_s=60.0,
                                 witness=witness, kept=KeptKeys(EXPRS))
        self.node.attach(SimpleNamespace(stop=threading.Event()))
        self.node.joining()
        if looping:
            self.node.tick(time.monotonic_ns(), None)  # nothing heard yet
        self.answers: list[int] = []
        hub.bus(V).subscribe_raw(keys.LOCKSTEP_RECORDER.key(V), lambda s: self.answers.append(
            PeriodDone.decode(s.payload).stamp_ns))


def test_a_period_is_on_disk_and_answered_before_the_sims_put_returns(tmp_path: Path) -> None:
    hub = MemoryHub()
    rec = Recorder(hub, tmp_path)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    for k in range(4):
        flushes = rec.writer.stats.flushes
        sim.answer(Period(0, k * P), P, [(keys.SIM_CLOCK, clock(k * P))], members=["recorder"])
        # Returned: the recorder answered this period, after its flush, and no loop was woken.
        assert rec.answers[-1] == k * P
        assert rec.writer.stats.flushes == flushes + 1
        assert not rec.queue.arrived.is_set()
        assert not rec.queue.items
    rec.writer.close()
    dec = reader.decode_vessel(reader.open_paths([tmp_path]), V, [keys.SIM_CLOCK.suffix])
    assert [m.stamp_ns for m in dec.get(keys.SIM_CLOCK.suffix)] == [k * P for k in range(4)]


def test_the_loop_writes_what_arrives_while_it_is_writing(tmp_path: Path) -> None:
    """A period that arrives while the loop holds the writer (its flush, or the chain the loop's
    own answer set off) is left to the loop, which is woken for it: nothing waits on the writer
    and nothing is lost."""
    hub = MemoryHub()
    rec = Recorder(hub, tmp_path)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    with rec.node._writing:
        sim.answer(Period(0, 0), P, [(keys.SIM_CLOCK, clock(0))], members=["recorder"])
    assert rec.answers == [] and rec.queue.arrived.is_set() and rec.queue.items
    rec.node.tick(time.monotonic_ns(), None)
    # Written and answered; only that answer, heard on the loop's own thread, waits its turn.
    assert rec.answers == [0]
    assert [key for key, *_ in rec.queue.items] == [keys.LOCKSTEP_RECORDER.key(V)]


def test_before_its_loop_has_ticked_the_loop_is_woken_as_before(tmp_path: Path) -> None:
    hub = MemoryHub()
    rec = Recorder(hub, tmp_path, looping=False)
    Member(hub.bus(V), "sim", watched=(), subscribe=False).answer(
        Period(0, 0), P, [(keys.SIM_CLOCK, clock(0))], members=["recorder"])
    assert rec.queue.arrived.is_set() and rec.queue.items and rec.writer.stats.messages == 0
    rec.node.tick(time.monotonic_ns(), None)  # the loop's first tick writes it
    assert rec.answers == [0] and rec.writer.stats.messages > 0
    rec.writer.close()


def test_once_stopping_a_delivery_writes_nothing(tmp_path: Path) -> None:
    """A sample that passed the queue's check just before ``finish``: its delivery leaves it to the
    loop (which has finished) instead of writing into a writer about to be closed."""
    hub = MemoryHub()
    rec = Recorder(hub, tmp_path)
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)
    sim.answer(Period(0, 0), P, [(keys.SIM_CLOCK, clock(0))], members=["recorder"])
    rec.node.finish()
    written = rec.writer.stats.messages
    rec.queue.items.append((keys.SIM_CLOCK.key(V), clock(P).encode(), "application/json",
                            time.time_ns(), None))
    rec.node.write_on_arrival()
    assert rec.writer.stats.messages == written and rec.queue.items
    rec.writer.close()
