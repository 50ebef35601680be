"""The recorder's memory stays flat however many chunks it writes (issue 14, item 15).

A lockstep recorder ends a chunk every period; the mcap Writer kept an index object per chunk in
memory until the file was closed, so the recorder grew by about 17 bytes per message over a long
soak. The indexes now wait in a temporary file; the finished file is the same, fully indexed.
"""

from __future__ import annotations

import time
import tracemalloc
from pathlib import Path

from mcap.reader import make_reader
from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.recording.reader import iter_messages, read_info
from seaway_recorder.core import RecordingWriter

KEY = keys.THRUST.key("vessel1")
ENC = "application/json"


def write_periods(w: RecordingWriter, first: int, periods: int, per_period: int = 6) -> None:
    """``periods`` lockstep-like periods: a few messages, then a flush (one chunk each)."""
    for k in range(first, first + periods):
        for i in range(per_period):
            data = ThrustCommand.make(stamp_ns=k, thrust_port_n=float(i), thrust_starboard_n=1.0,
                                      seq=k).encode()
            w.write(KEY, data, ENC, k * per_period + i)
        w.flush()


def test_memory_does_not_grow_with_the_number_of_chunks(tmp_path: Path) -> None:
    w = RecordingWriter(tmp_path / "r.mcap", foxglove=False)
    w.open(time.time_ns())
    write_periods(w, 0, 500)  # warm: channels, schemas, caches
    tracemalloc.start()
    try:
        before, _ = tracemalloc.get_traced_memory()
        write_periods(w, 500, 4_000)
        after, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    growth = after - before
    # In memory, 4,000 chunk indexes were ~2 MB of Python objects; now a few kB of counters.
    assert growth < 200_000, f"{growth:,} bytes kept for 4,000 chunks"
    files = w.close()

    # The file is whole and fully indexed: every chunk in the summary, every message readable.
    path = Path(files[0])
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and len(summary.chunk_indexes) == 4_500
    assert read_info([path]).message_count == 27_000
    stamps = [m.log_time_ns for m in iter_messages([path])]
    assert stamps == list(range(27_000))
