"""``seaway bench recorder --lockstep``: the recorder's own cost per lockstep period, in this process.

A lockstep recorder hears one bundle a period from each member (``seaway.contract.bundle``), writes
the messages they carry on their own channels with the derived Foxglove channels, and answers the
period once it is on disk (``LockstepWitness``: a chunk ended and flushed). Composed
(``seaway launch sim-batch --composed``), every millisecond of that holds the GIL the sim, the
estimator and the controller wait for; here it is measured alone.

The bundles are the ones a real mission's recorder heard, rebuilt from its recording (``--recording``,
else paper condition #1 flown composed first, about 20 s): read in file order (the order they were
written in), each member's messages up to its answer make its bundle again, byte for byte. They are
published, period by period, on an in-memory bus (``seaway.runtime.memory_bus``) to a
``RecorderNode`` as ``seaway record`` builds it in lockstep (queue, witness, writer, the run's logs
tailed), whose ``tick`` runs after each bundle, as the bundle's arrival wakes it. Its own answers
come back to it on the bus and are written, as in a run. Figures: wall and CPU time per period
(median, p90, mean), the messages and chunks written.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader
from seaway.contract import bundle, keys
from seaway.recording.timebase import RecordingTime
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.memory_bus import MemoryHub
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median, percentile
from seaway_recorder.core import RecordingWriter
from seaway_recorder.logtail import LogTail
from seaway_recorder.node import KeptKeys, RecorderNode, SampleQueue, Tails, lockstep_exprs

from seaway_lab.bench.common import BenchResult, free_rendezvous

SCENARIO = "paper-c1"
CONTROLLER = "cc-empc"
EPOCH_NS = 1_796_484_800_000_000_000
FLUSH_S = 0.05
"""The recorder's default flush interval (``seaway record``): the tails are copied this often."""

Sample = tuple[str, bytes, str]
"""(key, payload, Zenoh encoding) of one bus sample."""


def periods_of(recording: Path) -> tuple[str, list[list[Sample]]]:
    """(vessel, the bus samples the recorder heard, one list per period from the sim's bundle on),
    rebuilt from a lockstep ``recording``: the recorder's own answers and log lines, the derived
    channels and the launcher's events are its own doing, left out."""
    pending: dict[str, list[tuple[str, bytes]]] = {}
    periods: list[list[Sample]] = [[]]
    vessel = ""
    with open(recording, "rb") as fh:
        for _schema, channel, msg in make_reader(fh).iter_messages(log_time_order=False):
            parts = channel.topic.split("/", 2)
            if len(parts) != 3 or parts[0] != keys.ROOT:
                continue
            vessel, suffix = parts[1], parts[2]
            service = bundle.service_of(channel.topic)
            if service is not None:
                if service == "recorder":
                    continue
                if service == "sim" and periods[-1]:
                    periods.append([])
                periods[-1].append((channel.topic, bundle.encode(msg.data, pending.pop(service, [])),
                                    bundle.ENCODING))
                continue
            spec = keys.spec_for_suffix(suffix)
            member = bundle.bundled_by(spec) if spec is not None else None
            if member is not None:
                pending.setdefault(member, []).append((suffix, msg.data))
            elif spec is not keys.LOG_LINE:
                periods[-1].append((channel.topic, msg.data,
                                    channel.metadata.get("zenoh_encoding", "application/json")))
    if not vessel:
        raise ValueError(f"{recording}: no seaway/<vessel>/... message in it")
    return vessel, [p for p in periods if p]


def fly(run_dir: Path) -> Path:
    """Paper condition #1 flown composed into ``run_dir``; its recording."""
    env = dict(os.environ, **{ENV_RENDEZVOUS: free_rendezvous(),
                              ENV_STACKS_DIR: str(run_dir.parent / "stacks")})
    env.pop(ENV_CONFIG, None)
    cmd = [str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
           SCENARIO, "--controller", CONTROLLER, "--run-dir", str(run_dir), "--no-report",
           "--composed"]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} ended with {out.returncode}:\n{out.stderr[-2000:]}")
    return run_dir / "recording.mcap"


def record(vessel: str, periods: list[list[Sample]], out: Path, logs: Path | None) -> dict:
    """Publish ``periods`` to a lockstep ``RecorderNode`` writing ``out``; per period its wall and
    CPU time [ms], and what it wrote. ``logs``: a folder of ``*.log`` it tails, as in a run."""
    hub = MemoryHub()
    bus = hub.bus(vessel)
    exprs = [keys.vessel_wildcard(vessel)]
    writer = RecordingWriter(out, time=RecordingTime(lockstep=True, epoch_ns=EPOCH_NS,
                                                     epoch_source="bench"))
    writer.open(time.time_ns())
    queue = SampleQueue(200_000)
    kept = KeptKeys(exprs)
    exprs = lockstep_exprs(exprs, vessel)
    witness = LockstepWitness(bus, vessel, exprs)
    for e in exprs:
        bus.subscribe_raw(e, queue.on_sample, inline=True)
    tails = Tails(None, LogTail([str(logs)]) if logs is not None else None)
    node = RecorderNode(writer, queue, FLUSH_S, 3600.0, witness, tails, kept)
    with contextlib.redirect_stdout(io.StringIO()):  # READY
        node.tick(0, None)
    publishers = {}
    wall_ms: list[float] = []
    cpu_ms: list[float] = []
    t0_wall, t0_cpu = time.perf_counter(), time.process_time()
    for period in periods:
        w0, c0 = time.perf_counter_ns(), time.thread_time_ns()
        for key, payload, encoding in period:
            pub = publishers.get(key)
            if pub is None:
                pub = publishers[key] = bus.raw_publisher(key, encoding)
            pub.put(payload)
            if queue.wake_on_any or "/lockstep/" in key:  # what wakes a lockstep recorder
                node.tick(0, None)
        wall_ms.append((time.perf_counter_ns() - w0) / 1e6)
        cpu_ms.append((time.thread_time_ns() - c0) / 1e6)
    node.finish()
    total_wall, total_cpu = time.perf_counter() - t0_wall, time.process_time() - t0_cpu
    writer.close()
    if node.failed is not None:
        raise node.failed
    with open(out, "rb") as fh:
        stats = make_reader(fh).get_summary().statistics  # type: ignore[union-attr]
    return {"wall_ms": wall_ms, "cpu_ms": cpu_ms, "total_wall_s": total_wall,
            "total_cpu_s": total_cpu, "messages": stats.message_count,
            "chunks": stats.chunk_count, "answers": witness.member.last_answer is not None}


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench recorder --lockstep",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--recording", type=Path, default=None,
                    help="a lockstep recording to take the bundles from (default: fly paper-c1 "
                         "composed first); its run folder's logs/ are tailed if there")
    ap.add_argument("--repeat", type=int, default=3, help="times the periods are recorded")
    ap.add_argument("--keep", type=Path, default=None,
                    help="keep the last recording written here (to compare two versions' files)")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        raise SystemExit(f"--repeat must be >= 1, got {args.repeat}")
    res = BenchResult("recorder-lockstep", "Recorder's own cost per lockstep period")
    with tempfile.TemporaryDirectory(prefix="seaway-bench-recorder-lockstep-") as d:
        tmp = Path(d)
        source = args.recording or fly(tmp / "run")
        logs = source.parent / "logs"
        vessel, periods = periods_of(source)
        runs = [record(vessel, periods, tmp / f"out-{i}.mcap", logs if logs.is_dir() else None)
                for i in range(args.repeat)]
        if args.keep is not None:
            shutil.copyfile(tmp / f"out-{args.repeat - 1}.mcap", args.keep)
    wall = [median(r["wall_ms"]) for r in runs]
    cpu = [median(r["cpu_ms"]) for r in runs]
    n = len(periods)
    res.add("periods", n, note=f"from {source.name if args.recording else SCENARIO + ' composed'}")
    res.add("period_wall_median_ms", round(median(wall), 4),
            note=f"median over {args.repeat} runs of each run's median: "
                 + ", ".join(f"{w:.4f}" for w in wall))
    res.add("period_wall_p90_ms", round(median([percentile(r["wall_ms"], 90) for r in runs]), 4))
    res.add("period_wall_mean_ms", round(median([r["total_wall_s"] * 1e3 / n for r in runs]), 4),
            note="the whole run over its periods (the tails and the close included)")
    res.add("period_cpu_median_ms", round(median(cpu), 4), note="this thread's CPU time")
    res.add("period_cpu_mean_ms", round(median([r["total_cpu_s"] * 1e3 / n for r in runs]), 4))
    res.add("messages_written", runs[-1]["messages"])
    res.add("chunks_written", runs[-1]["chunks"], note="one per answer of the recorder")
    res.meta.update({"cpus": os.cpu_count() or 0, "repeat": args.repeat,
                     "period_wall_medians_ms": wall, "period_cpu_medians_ms": cpu})
    return res


if __name__ == "__main__":
    print(run(sys.argv[1:]).table())
