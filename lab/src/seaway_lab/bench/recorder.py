"""``seaway bench recorder``: how many bus messages per second the recorder stores without a drop.

Three figures in one run:

1. **baseline**: the mcap Writer alone, in this process, writing the same 300-byte messages into a
   file (zstd chunks ended every flush interval, as the recorder does): the ceiling of the library;
   next to it the recorder's own MCAP writer (``seaway_recorder.mcapfile``, the same bytes), and
   both again with a chunk every 20 messages, as a lockstep recorder ends one every period;
2. **core**: ``RecordingWriter`` in this process (the recorder's core: type check, channel lookup,
   MCAP), no bus;
3. **end to end**: the recorder as its own process, a publisher as another process sending
   ``ThrustCommand`` samples of 300 bytes at ``--rate`` for ``--seconds`` on a private rendezvous port.
   The per-second rates are counted from the recording's receive times (whole seconds only); drops are
   the messages sent but not in the file, plus the recorder's own queue drops.

``--lockstep`` measures instead what a lockstep recorder costs per period, the bundles of a real
mission in, the period answered on disk (``seaway_lab.bench.recorder_lockstep``).

Run the publisher alone with ``python -m seaway_lab.bench.recorder publish --rate R --seconds S``.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer
from seaway.contract import keys
from seaway.contract.messages import ThrustCommand
from seaway.contract.units import NS_PER_S
from seaway.runtime.argtypes import positive_float, positive_int
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile
from seaway_recorder.core import RecordingWriter
from seaway_recorder.mcapfile import McapWriter

from seaway_lab.bench import recorder_lockstep
from seaway_lab.bench.common import BenchResult, bench_credentials, free_rendezvous

TARGET_MSG_S = 50_000
LOCKSTEP_PERIOD_MESSAGES = 20
"""Messages a lockstep recorder writes per period, each period a chunk (paper #1: about 18)."""
MESSAGE_BYTES = 300
BENCH_VESSEL = "bench"


def make_payload(seq: int, size: int = MESSAGE_BYTES) -> bytes:
    """A valid ThrustCommand of exactly ``size`` bytes (the ``source`` text pads it)."""
    base = ThrustCommand.make(stamp_ns=1_700_000_000_000_000_000 + seq, thrust_port_n=1.234567,
                              thrust_starboard_n=-2.345678, source="", seq=seq).encode()
    pad = max(0, size - len(base))
    return ThrustCommand.make(stamp_ns=1_700_000_000_000_000_000 + seq, thrust_port_n=1.234567,
                              thrust_starboard_n=-2.345678, source="p" * pad, seq=seq).encode()


def bench_mcap(n: int, flush_every: int, ours: bool = False) -> float:
    """Messages per second through an MCAP writer alone, in this process: the mcap library's
    ``Writer`` (the baseline), or the recorder's own ``mcapfile.McapWriter`` (``ours``), which
    writes the same bytes."""
    payload = make_payload(1)
    buf = io.BytesIO()
    w = (McapWriter(buf, chunk_size=4 << 20) if ours
         else Writer(buf, chunk_size=4 << 20, compression=CompressionType.ZSTD))
    w.start()
    sid = w.register_schema(ThrustCommand.SCHEMA, "jsonschema", ThrustCommand.json_schema_text().encode())
    cid = w.register_channel("seaway/bench/ctrl/thrust", "json", sid)
    t0 = time.perf_counter()
    for i in range(n):
        w.add_message(cid, i, payload, i, i)
        if i % flush_every == flush_every - 1:
            w.flush()
    w.finish()
    return n / (time.perf_counter() - t0)


def bench_core(n: int, flush_every: int, tmp: Path) -> float:
    payloads = [make_payload(i) for i in range(1000)]
    key = keys.THRUST.key(BENCH_VESSEL)
    w = RecordingWriter(tmp / "core.mcap")
    w.open(0)
    t0 = time.perf_counter()
    for i in range(n):
        w.write(key, payloads[i % 1000], "application/json;seaway.v1.ThrustCommand", i)
        if i % flush_every == flush_every - 1:
            w.flush()
    w.close(n)
    return n / (time.perf_counter() - t0)


def _wait_line(p: subprocess.Popen, text: str, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    assert p.stdout is not None
    while time.monotonic() < deadline:
        line = p.stdout.readline()
        if not line:
            if p.poll() is not None:
                raise RuntimeError(f"process exited early ({p.returncode})")
            continue
        if text in line:
            return
    raise RuntimeError(f"no {text!r} within {timeout_s} s")


def bench_end_to_end(rate: float, seconds: float, tmp: Path) -> dict:
    env = dict(os.environ, PYTHONUNBUFFERED="1", **bench_credentials())
    env[ENV_RENDEZVOUS] = free_rendezvous()
    env.pop(ENV_CONFIG, None)
    out = tmp / "e2e.mcap"
    rec = subprocess.Popen([sys.executable, "-m", "seaway_recorder.main", "--out", str(out),
                            "--key-expr", f"seaway/{BENCH_VESSEL}/**", "--log-level", "WARNING",
                            "--vessel", BENCH_VESSEL],
                           env=env, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                           start_new_session=True)
    try:
        _wait_line(rec, "READY", 20)
        pub = subprocess.run([sys.executable, "-m", "seaway_lab.bench.recorder", "publish",
                              "--rate", str(rate),
                              "--seconds", str(seconds)], env=env, capture_output=True, text=True,
                             timeout=seconds + 60)
        if pub.returncode != 0:
            raise RuntimeError(f"publisher failed: {pub.stderr[-2000:]}")
        sent = json.loads(pub.stdout.strip().splitlines()[-1])
        time.sleep(0.5)
        rec.terminate()
        rec_out, _ = rec.communicate(timeout=60)
    finally:
        if rec.poll() is None:
            rec.kill()
            rec.wait()
    summary = json.loads(rec_out.strip().splitlines()[-1])
    per_second: Counter[int] = Counter()
    recorded = 0
    with open(out, "rb") as fh:
        for _schema, _channel, msg in make_reader(fh).iter_messages(topics=[keys.THRUST.key(BENCH_VESSEL)]):
            per_second[msg.log_time // NS_PER_S] += 1
            recorded += 1
    secs = sorted(per_second)
    whole = [per_second[s] for s in secs[1:-1]] or [per_second[s] for s in secs]
    return {
        "sent": sent["sent"], "send_rate": sent["rate"], "recorded": recorded,
        "missing": sent["sent"] - recorded, "queue_drops": int(summary["dropped"]),
        "malformed": int(summary["malformed"]), "rates": whole,
        "file_mib": out.stat().st_size / 2**20,
    }


def publish(argv: list[str]) -> int:
    """The publisher process: ThrustCommand samples of 300 bytes at a steady rate."""
    import zenoh
    from seaway.runtime.zenoh_bus import open_session

    ap = argparse.ArgumentParser(prog="seaway_lab.bench.recorder publish")
    ap.add_argument("--rate", type=positive_float, required=True)
    ap.add_argument("--seconds", type=positive_float, required=True)
    args = ap.parse_args(argv)
    session = open_session()
    pub = session.declare_publisher(keys.THRUST.key(BENCH_VESSEL),
                                    congestion_control=zenoh.CongestionControl.BLOCK)
    deadline = time.monotonic() + 20
    while not pub.matching_status.matching:
        if time.monotonic() > deadline:
            print("no subscriber", file=sys.stderr)
            return 1
        time.sleep(0.05)
    time.sleep(0.5)
    payloads = [make_payload(i) for i in range(1000)]
    n = 0
    t0 = time.monotonic()
    while True:
        el = time.monotonic() - t0
        if el >= args.seconds:
            break
        due = int(el * args.rate)
        while n < due:
            pub.put(payloads[n % 1000])
            n += 1
        time.sleep(0.0005)
    el = time.monotonic() - t0
    time.sleep(0.3)
    session.close()
    print(json.dumps({"sent": n, "rate": n / el}), flush=True)
    return 0


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench recorder", description=__doc__.split("\n\n")[0])
    ap.add_argument("--rate", type=positive_float, default=TARGET_MSG_S, help="publisher rate [msg/s]")
    ap.add_argument("--seconds", type=positive_float, default=6.0, help="publishing time [s]")
    ap.add_argument("--baseline-messages", type=positive_int, default=200_000,
                    help="messages written straight to a file, the baseline of the same run")
    ap.add_argument("--lockstep", action="store_true",
                    help="measure instead the recorder's own cost per lockstep period, in this "
                         "process (seaway_lab.bench.recorder_lockstep; its options: --recording, "
                         "--repeat, --keep)")
    args, rest = ap.parse_known_args(argv)
    if args.lockstep:
        return recorder_lockstep.run(rest)
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    flush_every = max(1, int(args.rate * 0.05))  # what a 50 ms flush interval means at this rate
    res = BenchResult("recorder", f"Recorder throughput, {MESSAGE_BYTES}-byte messages")
    with tempfile.TemporaryDirectory(prefix="seaway-bench-recorder-") as d:
        tmp = Path(d)
        base = bench_mcap(args.baseline_messages, flush_every)
        ours = bench_mcap(args.baseline_messages, flush_every, ours=True)
        # A lockstep recorder ends a chunk every period, about 20 messages.
        base_period = bench_mcap(args.baseline_messages, LOCKSTEP_PERIOD_MESSAGES)
        ours_period = bench_mcap(args.baseline_messages, LOCKSTEP_PERIOD_MESSAGES, ours=True)
        core = bench_core(args.baseline_messages, flush_every, tmp)
        core_unflushed = bench_core(args.baseline_messages, 10**12, tmp)
        e2e = bench_end_to_end(args.rate, args.seconds, tmp)
    rates = e2e["rates"]
    drops = e2e["missing"] + e2e["queue_drops"]
    med = median(rates)
    res.add("baseline_mcap_writer_msg_per_s", round(base), note="mcap Writer alone, in-process, zstd")
    res.add("recorder_mcap_writer_msg_per_s", round(ours),
            note=f"seaway_recorder.mcapfile alone, the same bytes; {ours / base:.2f}x the baseline")
    res.add("baseline_mcap_writer_lockstep_msg_per_s", round(base_period),
            note=f"a chunk every {LOCKSTEP_PERIOD_MESSAGES} messages, as a lockstep recorder")
    res.add("recorder_mcap_writer_lockstep_msg_per_s", round(ours_period),
            note=f"the same; {ours_period / base_period:.2f}x the baseline")
    res.add("core_recording_writer_msg_per_s", round(core), note="type check + MCAP, 50 ms chunks")
    res.add("core_without_periodic_flush_msg_per_s", round(core_unflushed), note="4 MiB chunks only")
    res.add("publisher_rate_msg_per_s", round(e2e["send_rate"]), note="separate process")
    # A publisher that could not offer the target's rate (a Python process on a slow machine) leaves
    # the target untested, not failed by the recorder: the verdict stays "missed", the note says why.
    least = 0.98 * TARGET_MSG_S  # the target less 2 %, as the verdict always allowed
    offered = e2e["send_rate"] >= least
    note = f"{len(rates)} whole seconds"
    if not offered:
        note += (f"; the publisher offered only {e2e['send_rate']:,.0f} msg/s, so the target is not "
                 f"tested (recorded {e2e['recorded']:,} of {e2e['sent']:,} sent)")
    res.add("recorded_rate_median_msg_per_s", round(med), target=f">= {least:,.0f}",
            ok=med >= least, note=note)
    res.add("recorded_rate_p99_msg_per_s", round(percentile(rates, 99)))
    res.add("recorded_rate_p1_msg_per_s", round(percentile(rates, 1)), note="the slowest second")
    res.add("sent", e2e["sent"])
    res.add("recorded", e2e["recorded"])
    res.add("drops", drops, target="0", ok=drops == 0,
            note=f"missing {e2e['missing']}, queue overflow {e2e['queue_drops']}")
    res.add("file_mib", round(e2e["file_mib"], 2), note="zstd")
    res.meta.update({"message_bytes": MESSAGE_BYTES, "cpus": os.cpu_count() or 0,
                     "target_rate_offered": offered,
                     "flush_interval_s": 0.05, "per_second_rates": rates})
    return res


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "publish":
        raise SystemExit(publish(sys.argv[2:]))
    r = run(sys.argv[1:])
    print(r.table())
