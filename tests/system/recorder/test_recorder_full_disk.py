"""A disk with no room does not stop the recorder, and loses nothing it can hold: on a real, small
filesystem (a tmpfs this test mounts; it needs root) filled by another file while the recorder
writes.

* Real time, a real recorder process: it keeps running while the disk is full, writes on once
  there is room, and the file holds every message in order; stopped while the disk is still full,
  it exits non-zero and what it wrote before is recovered whole.
* Lockstep, the recorder's real parts on the in-memory bus: a period that found no room is not
  answered (so the sim waits) until there is room, then it is.
"""

from __future__ import annotations

import json
import signal
import subprocess
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
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

from tests.conftest import BIN
from tests.system.recorder.test_recorder_crash import assert_contiguous, read_indexed, start
from tests.system.small_disk import fill
from tests.unit.recorder.test_recorder_repeats import EPOCH_NS, EXPRS, P, V, clock

pytestmark = pytest.mark.system


def summary_of(log_text: str) -> dict:
    return json.loads(log_text.strip().splitlines()[-1])


def size_still(path: Path, for_s: float) -> bool:
    """Whether ``path`` did not grow for ``for_s`` (the recorder found no room to write)."""
    before = path.stat().st_size
    time.sleep(for_s)
    return path.stat().st_size == before


def stops_growing(path: Path, within_s: float = 10.0) -> None:
    """Wait until ``path`` has not grown for a second: a file's last page of the filesystem has
    room for a few more chunks after the disk reads full."""
    deadline = time.monotonic() + within_s
    while not size_still(path, 1.0):
        assert time.monotonic() < deadline, f"{path} still grows on a full disk"


def test_a_full_disk_holds_the_recording_until_there_is_room_and_loses_nothing(
        procs, zenoh_env, small_disk) -> None:
    out = small_disk / "rec.mcap"
    rec, pub = start(procs, zenoh_env, out)
    time.sleep(1.0)
    filler = fill(small_disk)
    stops_growing(out)
    assert size_still(out, 1.0)
    assert rec.poll() is None, "the recorder stopped on a full disk:\n" + procs.log(rec)[-2000:]
    filler.unlink()  # room again: what was held goes out, and the recording goes on
    deadline = time.monotonic() + 10
    while out.stat().st_size == 0 or size_still(out, 0.3):
        assert time.monotonic() < deadline, "the recorder did not write on once there was room"
    time.sleep(0.5)
    procs.stop(rec, signal.SIGTERM, timeout_s=10)
    procs.stop(pub, signal.SIGKILL)
    assert rec.returncode == 0, procs.log(rec)[-2000:]
    final = summary_of(procs.log(rec))
    assert final["dropped"] == "0" and int(final["no_room"]) == 1
    assert float(final["no_room_s"]) >= 1.5  # the two seconds full, less a flush interval
    seqs = [s for s, _ in read_indexed(out)]
    assert_contiguous(seqs)
    assert seqs[0] == 1
    assert len(seqs) >= 500 * 3  # about 3.5 s at 500 Hz, the time full included
    assert int(final["by_topic"]["seaway/crash/ctrl/thrust"]) == len(seqs)


def test_stopped_on_a_full_disk_it_says_so_and_what_it_wrote_is_recovered(
        procs, zenoh_env, small_disk, tmp_path) -> None:
    out = small_disk / "rec.mcap"
    rec, pub = start(procs, zenoh_env, out)
    time.sleep(1.0)
    fill(small_disk)
    stops_growing(out)
    t_full = time.time_ns()
    procs.stop(rec, signal.SIGTERM, timeout_s=10)
    procs.stop(pub, signal.SIGKILL)
    assert rec.returncode == 1, procs.log(rec)[-2000:]
    assert "Traceback" not in procs.log(rec)
    fixed = tmp_path / "fixed.mcap"  # off the full disk
    r = subprocess.run([str(BIN / "seaway"), "record", "recover", str(out), str(fixed)],
                       capture_output=True, text=True, timeout=60, check=False)
    assert r.returncode == 0, r.stderr
    msgs = read_indexed(fixed)
    assert_contiguous([s for s, _ in msgs])
    assert msgs[0][0] == 1 and len(msgs) >= 300  # the second before the disk was full
    assert msgs[-1][1] < t_full


def test_lockstep_a_period_that_finds_no_room_is_answered_once_there_is(small_disk) -> None:
    hub = MemoryHub()
    writer = RecordingWriter(small_disk / "recording.mcap", compression="none",
                             time=RecordingTime(lockstep=True, epoch_ns=EPOCH_NS))
    writer.open(time.time_ns())
    queue = SampleQueue(10_000)
    bus = hub.bus(V)
    witness = LockstepWitness(bus, V, EXPRS)
    bus.subscribe_raw(f"seaway/{V}/**", queue.on_sample, inline=True)
    node = RecorderNode(writer, queue, flush_s=60.0, status_s=60.0, witness=witness,
                        kept=KeptKeys(EXPRS))
    stop = threading.Event()
    node.attach(SimpleNamespace(stop=stop))
    node.joining()
    node.tick(time.monotonic_ns(), None)
    answers: list[int] = []
    hub.bus(V).subscribe_raw(keys.LOCKSTEP_RECORDER.key(V), lambda s: answers.append(
        PeriodDone.decode(s.payload).stamp_ns))
    sim = Member(hub.bus(V), "sim", watched=(), subscribe=False)

    def period(k: int) -> None:
        sim.answer(Period(0, k * P), P, [(keys.SIM_CLOCK, clock(k * P))], members=["recorder"])

    period(0)
    assert answers == [0]
    filler = fill(small_disk)
    # The file's last page of the filesystem still has room for a few periods; then none.
    k = 0
    while len(answers) == k + 1:
        k += 1
        assert k < 200, "the recorder answered 200 periods on a full disk"
        period(k)
    stuck = k
    assert answers == [j * P for j in range(stuck)], "a period answered that is not on disk"
    assert node.no_room is not None and not stop.is_set()
    node.tick(time.monotonic_ns(), None)  # still full (and not yet time to try): no answer
    assert len(answers) == stuck
    filler.unlink()
    node._next_room_try = 0  # not wait ROOM_RETRY_S for the next try
    node.tick(time.monotonic_ns(), None)
    assert answers == [j * P for j in range(stuck + 1)] and node.no_room is None
    period(stuck + 1)
    assert answers[-1] == (stuck + 1) * P
    writer.close()
    assert writer.stats.no_room == 1
    dec = reader.decode_vessel(reader.open_paths([small_disk]), V, [keys.SIM_CLOCK.suffix])
    assert [m.stamp_ns for m in dec.get(keys.SIM_CLOCK.suffix)] == [j * P for j in range(stuck + 2)]
