"""``seaway bench restart``: how long a restarted recorder reads its predecessor's file before it
records again.

A real-time recorder the launcher restarts first reads the file the killed one left
(``seaway.recording.tail.tail_of``), so as not to write twice what the publishers' caches send
again; the launcher kills a restart that is not ready within its ``ready_timeout_s``. The file is
made here as a real-time recorder writes one: the recorder's own MCAP writer, ``--rate`` messages a
second of 300 bytes over 25 topics for ``--hours``, a zstd chunk ended every flush interval, and no
summary (killed). Timed in the same run, on the same file:

1. **baseline**: the mcap library's ``StreamReader`` over every record, each chunk broken up into
   its messages (what a reader that parses the whole file costs; ``tail_of`` did that before);
2. **tail_of**: the walk over the records that opens only the last chunks, ``--repeat`` times
   (median and p99).

Both must find the same messages from 10.5 s before the end. From the rate, the figures say how
many hours of recording ``tail_of`` reads within the launcher's default ready timeout. Target: a
day of recording within it (a boat recording round the clock).
"""

from __future__ import annotations

import argparse
import contextlib
import tempfile
import time
from pathlib import Path

from mcap.exceptions import EndOfFile
from mcap.records import Channel, Chunk, DataEnd, Footer, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from seaway.contract.units import NS_PER_S
from seaway.recording.tail import tail_of
from seaway.runtime.argtypes import positive_float, positive_int
from seaway.tools.launch.profile import DEFAULT_READY_TIMEOUT_S
from seaway.vessel.metrics import median, percentile
from seaway_recorder.config import DEFAULT_FLUSH_S
from seaway_recorder.mcapfile import McapWriter

from seaway_lab.bench.common import BenchResult
from seaway_lab.bench.recorder import make_payload

TOPICS = 25
REAL_TIME_RATE_MSG_S = 190.0
"""What a real-time single-vessel run records [messages/s] (the sim profile's lake mission)."""
TARGET_HOURS = 24.0
SINCE_BEFORE_END_NS = 10_500_000_000
"""How far before the last message the restart asks for what is already there (10 s of the
publishers' caches and the recorder's lateness margin)."""
START_NS = 1_800_000_000_000_000_000


def make_killed_recording(path: Path, hours: float, rate_msg_s: float) -> tuple[int, int]:
    """Write ``path`` as a real-time recorder killed after ``hours`` leaves it; return (messages,
    last log time [ns])."""
    n = round(hours * 3600.0 * rate_msg_s)
    per_chunk = max(1, round(rate_msg_s * DEFAULT_FLUSH_S))
    step_ns = round(NS_PER_S / rate_msg_s)
    payloads = [make_payload(i) for i in range(TOPICS)]  # each message numbered in front
    t = START_NS
    with open(path, "wb") as f:
        w = McapWriter(f, chunk_size=4 * 1024 * 1024, compression="zstd")
        w.start()
        schema = w.register_schema("seaway.bench.v1.Payload", "jsonschema", b"{}")
        channels: dict[int, int] = {}
        for i in range(n):
            k = (i * 7) % TOPICS
            if k not in channels:
                channels[k] = w.register_channel(f"seaway/bench/topic{k}", "json", schema)
            w.add_message(channels[k], log_time=t, data=b"%d " % i + payloads[k], publish_time=t,
                          sequence=i)
            t += step_ns
            if (i + 1) % per_chunk == 0:
                w.flush()
        w.flush()  # ended with its last chunk: no summary, no footer
    return n, t - step_ns


def read_everything(path: Path, since_ns: int) -> set[tuple[str, bytes]]:
    """The baseline: every record through the mcap library's reader."""
    topics: dict[int, str] = {}
    found: set[tuple[str, bytes]] = set()
    with open(path, "rb") as f, contextlib.suppress(EndOfFile):  # no data end: it was killed
        for record in StreamReader(f, emit_chunks=True, record_size_limit=1 << 31).records:
            inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else [record]
            for r in inner:
                if isinstance(r, Channel):
                    topics[r.id] = r.topic
                elif isinstance(r, Message) and r.log_time >= since_ns:
                    found.add((topics[r.channel_id], bytes(r.data)))
            if isinstance(record, DataEnd | Footer):
                break
    return found


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench restart", description=__doc__.split("\n\n")[0])
    ap.add_argument("--hours", type=positive_float, default=1.0, help="hours of recording in the file")
    ap.add_argument("--rate", type=positive_float, default=REAL_TIME_RATE_MSG_S,
                    help="messages recorded per second")
    ap.add_argument("--repeat", type=positive_int, default=5, help="timed reads with tail_of")
    args = ap.parse_args(argv)
    res = BenchResult("restart", f"A restarted recorder's read of {args.hours:g} h of recording "
                                 f"at {args.rate:g} messages/s")
    with tempfile.TemporaryDirectory(prefix="seaway-bench-restart-") as tmp:
        path = Path(tmp) / "recording.mcap"
        n, last_ns = make_killed_recording(path, args.hours, args.rate)
        since_ns = last_ns - SINCE_BEFORE_END_NS
        t0 = time.perf_counter()
        expected = read_everything(path, since_ns)
        base_s = time.perf_counter() - t0
        times = []
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            tail = tail_of(path, since_ns)
            times.append(time.perf_counter() - t0)
            if tail.messages != expected or tail.last_log_ns != last_ns:
                raise RuntimeError(f"tail_of found {len(tail.messages)} messages up to "
                                   f"{tail.last_log_ns}; the library's reader {len(expected)} up "
                                   f"to {last_ns}")
        size_mb = path.stat().st_size / 1e6
    tail_s = median(times)
    rate_msg_s = n / tail_s
    hours_in_timeout = DEFAULT_READY_TIMEOUT_S * rate_msg_s / (args.rate * 3600.0)
    res.add("messages", n)
    res.add("file_mb", round(size_mb, 1))
    res.add("tail_messages", len(expected), note="from 10.5 s before the end: the same in both")
    res.add("baseline_s", base_s, note="mcap StreamReader, every record")
    res.add("tail_median_s", tail_s)
    res.add("tail_p99_s", percentile(times, 99), note=f"over {args.repeat} reads")
    res.add("baseline_over_tail", base_s / tail_s, note="speed-up ratio")
    res.add("tail_messages_per_s", rate_msg_s)
    res.add("hours_within_ready_timeout", hours_in_timeout, f">= {TARGET_HOURS:g}",
            hours_in_timeout >= TARGET_HOURS,
            f"recording at {args.rate:g}/s read within {DEFAULT_READY_TIMEOUT_S:g} s")
    return res
