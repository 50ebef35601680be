"""What the recorder does with well-formed but absurd input from publishers the rules allow, and with
its file taken away while it writes: stamps at 0 and at 2**63-1 ns, samples of a megabyte offered
faster than they are written, the recording deleted, truncated or moved under it. The file stays
valid MCAP whose JSON channels validate against the schemas they carry (``jsonschema``), memory
stays bounded, and nothing after the event is lost."""

from __future__ import annotations

import json
import os
import threading
from pathlib import Path
from types import SimpleNamespace

from mcap.reader import make_reader
from seaway.contract import keys
from seaway.contract.messages import SimTruth, ThrustCommand
from seaway.runtime.bus_raw import RawSample
from seaway_recorder.core import SUMMARY_METADATA, RecordingWriter
from seaway_recorder.node import RecorderNode, SampleQueue, drain

from tests.unit.recorder.foxglove_check import invalid_messages

V = "v1"
THRUST = keys.THRUST.key(V)
ENC = "application/json"
RECEIVED_NS = 1_770_000_000_000_000_000


def thrust(i: int, pad: int = 0) -> bytes:
    doc = json.loads(ThrustCommand.make(stamp_ns=i, thrust_port_n=1.0, thrust_starboard_n=-1.0,
                                        seq=i).encode())
    if pad:
        doc["pad"] = "x" * pad  # an unknown field: decodes, and the bytes are kept whole
    return json.dumps(doc).encode()


def truth(stamp_ns: int) -> bytes:
    return SimTruth.make(stamp_ns=stamp_ns, u_mps=0.5, v_mps=0.0, r_radps=0.0, x_m=1.0, y_m=2.0,
                         psi_rad=0.0, thrust_port_n=1.0, thrust_starboard_n=1.0,
                         energy_j=0.0).encode()


def read(path: Path) -> tuple[list[tuple[str, bytes, int]], dict[str, dict[str, str]], object]:
    """(topic, bytes, log time) of every message, the metadata, the statistics; the file's
    JSON channels checked against their own schemas."""
    checked, errors = invalid_messages(path)
    assert errors == {}
    with open(path, "rb") as fh:
        r = make_reader(fh)
        stats = r.get_summary().statistics
        msgs = [(c.topic, bytes(m.data), m.log_time) for _, c, m in r.iter_messages()]
        meta = {m.name: dict(m.metadata) for m in r.iter_metadata()}
    assert checked == len([t for t, _, _ in msgs if not t.startswith("foxglove/")])
    return msgs, meta, stats


def test_stamps_at_0_and_int64_max_are_recorded_at_their_receive_time(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "r.mcap")
    w.open(RECEIVED_NS)
    stamps = [0, 2**63 - 1, 1, 2**32 * 10**9]
    for k, s in enumerate(stamps):
        assert w.write(keys.SIM_TRUTH.key(V), truth(s), ENC, RECEIVED_NS + k)
    w.close(RECEIVED_NS + 10)
    msgs, meta, stats = read(tmp_path / "r.mcap")
    got = [(d, t) for topic, d, t in msgs if topic == keys.SIM_TRUTH.key(V)]
    assert got == [(truth(s), RECEIVED_NS + k) for k, s in enumerate(stamps)]
    # The timeline spans the receive times, not 1970 to 2262.
    assert (stats.message_start_time, stats.message_end_time) == (RECEIVED_NS, RECEIVED_NS + 3)
    # The two stamps a Foxglove timestamp cannot hold get no view, counted; the others one each.
    assert (w.stats.underived, meta[SUMMARY_METADATA]["underived"]) == (2, "2")


def test_megabyte_samples_faster_than_written_stay_within_the_queues_bytes(tmp_path: Path) -> None:
    max_bytes = 16 << 20
    queue = SampleQueue(200_000, max_bytes)
    big = thrust(1, pad=1 << 20)
    for _ in range(2000):  # 2 GB offered before the writer looks: 200,000 would have been taken
        queue.on_sample(RawSample(THRUST, big, ENC))
    queued = queue.in_bytes - queue.out_bytes
    assert queued <= max_bytes
    assert queue.dropped == 2000 - len(queue.items) and queue.dropped_bytes == queue.dropped * len(big)
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=False)
    w.open(RECEIVED_NS)
    kept = drain(w, queue, limit=None)
    assert queue.in_bytes == queue.out_bytes  # the bytes the writer took are taken off again
    queue.on_sample(RawSample(THRUST, thrust(2), ENC))  # the queue takes samples again
    drain(w, queue, limit=None)
    w.count_dropped(queue.dropped)
    w.close(RECEIVED_NS + 1)
    msgs, meta, _ = read(tmp_path / "r.mcap")
    assert [d for _, d, _ in msgs] == [big] * kept + [thrust(2)]
    assert meta[SUMMARY_METADATA]["dropped"] == str(2000 - kept)


def test_one_sample_larger_than_the_queues_bytes_is_still_taken_alone() -> None:
    queue = SampleQueue(100, max_bytes=1000)
    huge = thrust(1, pad=5000)
    queue.on_sample(RawSample(THRUST, huge, ENC))
    queue.on_sample(RawSample(THRUST, thrust(2), ENC))
    assert [item[1] for item in queue.items] == [huge] and queue.dropped == 1


def node_on(writer: RecordingWriter) -> tuple[RecorderNode, SampleQueue]:
    """A real-time recorder node flushing at every tick, its loop never run."""
    queue = SampleQueue(10_000)
    node = RecorderNode(writer, queue, flush_s=0.0, status_s=60.0)
    node.attach(SimpleNamespace(stop=threading.Event()))
    return node, queue


def offer(node: RecorderNode, queue: SampleQueue, first: int, n: int) -> None:
    for i in range(first, first + n):
        queue.on_sample(RawSample(THRUST, thrust(i), ENC))
    node.tick(0, None)


def test_a_recording_deleted_while_written_goes_on_in_a_new_file(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "recording.mcap", foxglove=False)
    w.open(RECEIVED_NS)
    node, queue = node_on(w)
    offer(node, queue, 0, 10)
    os.unlink(tmp_path / "recording.mcap")  # an operator freeing space, a cleanup script
    offer(node, queue, 10, 10)  # before: written into the deleted file, lost at close, unsaid
    offer(node, queue, 20, 10)
    node.finish()
    files = w.close(RECEIVED_NS + 1)
    assert node.failed is None
    assert files == [str(tmp_path / "recording.mcap")] * 2  # the name was free again
    msgs, meta, _ = read(tmp_path / "recording.mcap")
    # What the deleted file held since its last check is gone with it; everything after is here.
    assert [d for _, d, _ in msgs] == [thrust(i) for i in range(10, 30)]
    assert meta[SUMMARY_METADATA]["lost_files"] == "1"
    assert "deleted" in meta[SUMMARY_METADATA]["last_error"]
    assert "seaway.run" in meta or "seaway.time" in meta  # the new file stands alone


def test_a_recording_truncated_while_written_goes_on_in_a_new_file(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "recording.mcap", foxglove=False)
    w.open(RECEIVED_NS)
    node, queue = node_on(w)
    offer(node, queue, 0, 10)
    os.truncate(tmp_path / "recording.mcap", 0)  # ': > recording.mcap'
    offer(node, queue, 10, 10)
    node.finish()
    files = w.close(RECEIVED_NS + 1)
    assert w.stats.lost_files == 1 and len(files) == 2
    msgs, _, _ = read(Path(files[1]))  # the name of a file someone else now holds is not reused
    assert Path(files[1]).name.startswith("recording.restart-")
    assert [d for _, d, _ in msgs] == [thrust(i) for i in range(10, 20)]


def test_a_recording_moved_away_while_written_is_finished_where_it_went(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "recording.mcap", foxglove=False)
    w.open(RECEIVED_NS)
    node, queue = node_on(w)
    offer(node, queue, 0, 10)
    os.rename(tmp_path / "recording.mcap", tmp_path / "kept.mcap")
    offer(node, queue, 10, 10)
    node.finish()
    w.close(RECEIVED_NS + 1)
    assert w.stats.lost_files == 0  # nothing is lost: the file is whole where it went
    msgs, _, _ = read(tmp_path / "kept.mcap")
    assert [d for _, d, _ in msgs] == [thrust(i) for i in range(20)]
