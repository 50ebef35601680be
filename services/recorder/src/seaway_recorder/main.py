"""``seaway record``: every sample on ``seaway/**`` into MCAP; ``seaway record recover IN OUT``.

The process (also ``seaway-recorder``) subscribes to the bus; Zenoh's delivery threads only append
``(key, bytes, encoding, receive time)`` to a bounded queue (a full queue drops the sample and counts
it), and one writer thread drains the queue into ``RecordingWriter``. The writer flushes at least every
``--flush-interval`` (default 50 ms: a SIGKILL loses less than 100 ms), rotates files on
``--max-bytes`` / ``--max-seconds``, logs counts every ``--status-interval`` and, on SIGINT or SIGTERM,
writes what is queued and finishes a fully indexed file. The last line on stdout is a JSON summary.
It also copies the launcher's events (``--events``) and the run's log files (``--logs``) into the
recording as they grow. Log times follow ``timebase`` (sim time on the run's epoch in lockstep).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import logging
import os
import socket
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from seaway.contract import keys
from seaway.contract.config import ConfigError
from seaway.recording import runinfo
from seaway.recording.recover import recover, tail_of
from seaway.recording.timebase import RecordingTime, parse_epoch
from seaway.runtime import memory
from seaway.runtime import run as runs
from seaway.runtime.argtypes import positive_float, positive_int
from seaway.runtime.bus import REJOIN_HISTORY_S
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.node import run_node
from seaway.runtime.run import RunDescription
from seaway.runtime.service import base_parser, configure_logging, resolve_run, run_service
from seaway.runtime.zenoh_bus import ENV_CONFIG
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin

from seaway_recorder import attachments
from seaway_recorder.logtail import FileTail, LogTail
from seaway_recorder.node import LATE_NS, KeptKeys, RecorderNode, SampleQueue, Tails, lockstep_exprs
from seaway_recorder.writer import LIBRARY, RUN_METADATA, AttachmentSpec, RecordingWriter

log = logging.getLogger("seaway.recorder")
DEFAULT_FLUSH_S = 0.05


def default_out() -> Path:
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path("runs") / stamp / "recording.mcap"


def out_path(text: str | None) -> Path:
    if not text:
        return default_out()
    p = Path(text)
    return p if p.suffix == ".mcap" else p / "recording.mcap"


def parse_meta(items: Sequence[str]) -> dict[str, str]:
    out = {}
    for item in items:
        k, sep, v = item.partition("=")
        if not sep or not k:
            raise SystemExit(f"seaway record: --meta wants KEY=VALUE, got {item!r}")
        out[k] = v
    return out


def parse_size(text: str) -> int:
    units = {"k": 1 << 10, "m": 1 << 20, "g": 1 << 30}
    t = text.strip().lower().removesuffix("b").removesuffix("i")
    mult = units.get(t[-1:], 1)
    return int(float(t[:-1] if t[-1:] in units else t) * mult)


def parser() -> argparse.ArgumentParser:
    p = base_parser(
        "recorder", prog="seaway record [run]",
        description="Two commands. 'seaway record [run] [options]' (the default) records every "
                    "sample on the bus to MCAP until Ctrl-C: bytes unchanged, with their JSON "
                    "Schemas, flushed at least every --flush-interval so a crash loses little; the "
                    "launcher starts it as the recorder. 'seaway record recover IN [OUT]' rebuilds a "
                    "fully indexed file from one a crash cut short (seaway record recover --help).")
    p.add_argument("--out", default=None,
                   help="output folder or .mcap file (default runs/<UTC time>/recording.mcap)")
    p.add_argument("--vessels", default="",
                   help="comma-separated vessels to record (default: every vessel, seaway/**)")
    p.add_argument("--key-expr", action="append", default=[],
                   help="record this key expression instead (repeatable)")
    p.add_argument("--profile", default=None, help="launcher profile (name or file) to attach")
    p.add_argument("--mission", default=None, help="mission file to attach (MissionRequest JSON or TOML)")
    p.add_argument("--attach", action="append", default=[], metavar="[ROLE=]FILE",
                   help=f"attach a file (repeatable); roles: {', '.join(runinfo.ROLES)} (default config)")
    p.add_argument("--meta", action="append", default=[], metavar="KEY=VALUE",
                   help="add to the seaway.run metadata record (repeatable)")
    p.add_argument("--flush-interval", type=positive_float, default=DEFAULT_FLUSH_S,
                   help=f"seconds between flushes, at most 0.1 (default {DEFAULT_FLUSH_S})")
    p.add_argument("--max-bytes", type=parse_size, default=None, help="rotate after this size (e.g. 512M)")
    p.add_argument("--max-seconds", type=positive_float, default=None, help="rotate after this many seconds")
    p.add_argument("--compression", choices=["zstd", "lz4", "none"], default="zstd",
                   help="chunk compression (default zstd; none writes fastest, files are larger)")
    p.add_argument("--chunk-size", type=parse_size, default=4 << 20,
                   help="end a chunk early past this many bytes (default 4M)")
    p.add_argument("--queue", type=positive_int, default=200_000,
                   help="samples buffered between Zenoh and the writer before drops (default 200000)")
    p.add_argument("--no-validate", action="store_true",
                   help="do not check samples against their types (faster; nothing counts as malformed)")
    p.add_argument("--no-foxglove", action="store_true",
                   help="do not add the derived Foxglove channels (map positions, mission, frames, "
                        "3D scene); log lines (--logs) are still recorded")
    p.add_argument("--status-interval", type=positive_float, default=5.0, help="seconds between status lines")
    p.add_argument("--events", type=Path, default=None, metavar="FILE",
                   help="a launcher's events log (events.jsonl) to copy into the recording as it "
                        "grows, on launcher/events")
    p.add_argument("--logs", action="append", default=[], metavar="GLOB|DIR",
                   help="log files to copy into the recording as they grow, each line a "
                        "foxglove.Log on foxglove/log (repeatable; a folder means its *.log; the "
                        "launcher's profiles pass '<run>/logs/*.log')")
    p.add_argument("--sim-epoch", default=None, metavar="TIME",
                   help="lockstep: the wall-clock time simulated time 0 is logged at, ISO 8601 "
                        "(2026-05-01T09:00:00Z) or Unix seconds (default: when the run started, "
                        "i.e. the --run file was written, else now; whole seconds)")
    return p


def newest_recording(base: Path) -> Path | None:
    """The newest of ``base`` and its ``.restart-<k>`` siblings (``writer.free_path``) that exists:
    the recording a recorder restarted into the same run folder takes over from."""
    found = [p for p in [base, *base.parent.glob(f"{base.stem}.restart-*{base.suffix}")] if p.is_file()]
    return max(found, key=lambda p: p.stat().st_mtime_ns) if found else None


def key_exprs(args: argparse.Namespace) -> list[str]:
    if args.key_expr:
        return list(args.key_expr)
    vessels = [v.strip() for v in args.vessels.split(",") if v.strip()]
    return [keys.vessel_wildcard(v) for v in vessels] or [keys.vessel_wildcard()]


def build_run_info(args: argparse.Namespace, exprs: list[str], run: RunDescription):
    """Attachments (the run description, its scenario, vessel files, ...) and metadata of a recording."""
    atts = [AttachmentSpec(runinfo.RUN_ATTACHMENT, "application/json", run.encode(), time.time_ns())]
    origin = None
    scenario_name = ""
    if run.scenario:
        s_atts, scenario = attachments.scenario_attachments(run.scenario, with_vessel=False)
        atts += s_atts
        scenario_name = scenario.name
    if run.origin is not None:
        origin = GeoOrigin.from_degrees(run.origin.lat_deg, run.origin.lon_deg, run.origin.alt_m)
    atts.append(attachments.attachment("vessel", runinfo.vessel_path(run.model_vessel_file)))
    if run.plant_vessel_file is not None:
        atts.append(attachments.attachment("plant-vessel", runinfo.vessel_path(run.plant_vessel_file)))
    if args.profile:
        atts.append(attachments.attachment("profile", runinfo.profile_path(args.profile)))
    if args.mission:
        atts.append(attachments.attachment("mission", Path(args.mission)))
    zcfg = args.zenoh_config or os.environ.get(ENV_CONFIG)
    if zcfg:
        atts.append(attachments.attachment("zenoh", Path(zcfg)))
    atts += [attachments.parse_attach_arg(a) for a in args.attach]
    meta = {
        "recorder": LIBRARY,
        "started_utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"),
        "host": socket.gethostname(),
        "key_exprs": ",".join(exprs),
        "scenario": scenario_name,
        "run_id": run.run_id,
        "control_period_s": f"{run.control_period_s:g}",
        "clock": run.clock,
        "profile": Path(args.profile).stem if args.profile else "",
        "flush_interval_s": f"{args.flush_interval:g}",
        "command": " ".join(sys.argv),
        "attachments": ",".join(a.name for a in atts),
        **parse_meta(args.meta),
    }
    return atts, {RUN_METADATA: meta}, origin


def recording_time(args: argparse.Namespace, run: RunDescription, now_ns: int) -> RecordingTime:
    """The recording's time convention (``timebase``): the run's clock and, in lockstep, its epoch:
    ``--sim-epoch``, else when the run started (the launcher writes ``--run`` then, and a restarted
    recorder reads the same file), else ``now_ns``; whole seconds."""
    if not run.lockstep:
        return RecordingTime.real_time()
    if args.sim_epoch:
        epoch_ns, source = parse_epoch(args.sim_epoch), "--sim-epoch"
    elif (started := runs.started_ns(args.run)) is not None:
        epoch_ns, source = started, f"run started ({args.run} written)"
    else:
        epoch_ns, source = now_ns, "recorder started"
    return RecordingTime(lockstep=True, epoch_ns=epoch_ns - epoch_ns % 1_000_000_000,
                         epoch_source=source, gap_ns=run.control_period_ns)


def run(argv: Sequence[str]) -> int:
    args = parser().parse_args(list(argv))
    if not 0 < args.flush_interval <= 0.1:
        raise SystemExit("seaway record: --flush-interval must be in (0, 0.1] s")
    exprs = key_exprs(args)
    run = resolve_run(args, "recorder", load_scenario)
    try:
        atts, meta, origin = build_run_info(args, exprs, run)
        rec_time = recording_time(args, run, time.time_ns())
    except (ConfigError, ValueError, OSError) as err:
        print(f"seaway record: {err}", file=sys.stderr)
        return 2
    writer = RecordingWriter(out_path(args.out), chunk_size=args.chunk_size, compression=args.compression,
                             max_bytes=args.max_bytes, max_seconds=args.max_seconds, attachments=atts,
                             metadata=meta, validate=not args.no_validate, foxglove=not args.no_foxglove,
                             default_origin=origin, time=rec_time)
    queue = SampleQueue(args.queue)
    # The recorder records whatever runs (a shore recorder sees a boat launched elsewhere), so it
    # does not take part in the run agreement; its run only describes the recording.
    with run_service("recorder", args, run=run, agree=False) as ctx:
        started_ns = time.time_ns()
        previous = None if run.lockstep or writer.rotating else newest_recording(writer.base)
        path = writer.open(started_ns)
        print(f"recording {', '.join(exprs)} to {path}", flush=True)
        # In lockstep the recorder is a member: the sim does not move on until it is on disk.
        witness = None
        kept = KeptKeys(exprs)
        if run.lockstep:
            exprs = lockstep_exprs(exprs, args.vessel)
            witness = LockstepWitness(ctx.bus, args.vessel, exprs)
            if witness.member.timeline.marks is not None:
                queue.timeline = witness.member.timeline
        if previous is not None:
            # Restarted into a run folder: what the publishers' caches give back that the
            # predecessor wrote already is not written twice; the time nothing can be asked for
            # is said in the file (schemas.RESTART_SCHEMA).
            asked_from_ns = started_ns - round(REJOIN_HISTORY_S * 1e9)
            tail = tail_of(previous, asked_from_ns - LATE_NS)
            queue.already = tail.messages
            writer.write_restart({
                "stamp_ns": started_ns, "previous_file": previous.name,
                "previous_last_ns": tail.last_log_ns, "asked_from_ns": asked_from_ns,
                "gap_unrecovered_s": max(0, asked_from_ns - tail.last_log_ns) / 1e9}, started_ns)
            log.info("restarted after %s (last message at %.3f s before this start): asking the "
                     "publishers for their last %.0f s", previous.name,
                     (started_ns - tail.last_log_ns) / 1e9, REJOIN_HISTORY_S)
        for e in exprs:
            # Real time: also what was published up to REJOIN_HISTORY_S before (the publishers'
            # caches), which a recorder restarted by the launcher was away for.
            ctx.bus.subscribe_raw(e, queue.on_sample, inline=run.lockstep,
                                  history_s=0.0 if run.lockstep else REJOIN_HISTORY_S)
        tails = Tails(FileTail(args.events) if args.events else None,
                      LogTail(args.logs) if args.logs else None,
                      ctx.bus.publisher(keys.LOG_LINE).put if args.logs else None)
        node = RecorderNode(writer, queue, args.flush_interval, args.status_interval, witness,
                            tails, kept)
        run_node(ctx, node, args.flush_interval)
        failed = node.failed is not None
        writer.count_dropped(queue.dropped - writer.stats.dropped)
        try:
            files = writer.close()
        except OSError as err:
            log.error("could not finish %s: %s (try 'seaway record recover')", writer.path, err)
            return 1
    summary = {"files": files, **writer.stats.as_metadata(), "by_topic": dict(writer.stats.by_topic),
               "repeats_not_written": queue.repeats}
    log.info("recorder finished: %s", writer.stats.line())
    print(f"recording finished: {', '.join(files)}", flush=True)
    print(json.dumps(summary), flush=True)
    return 1 if failed else 0


def cmd_recover(argv: Sequence[str]) -> int:
    p = argparse.ArgumentParser(prog="seaway record recover",
                                description="Rebuild a fully indexed MCAP file from a truncated one.")
    p.add_argument("input", type=Path, help="the truncated .mcap file (it is not changed)")
    p.add_argument("output", type=Path, nargs="?", default=None,
                   help="where to write the repaired file (default: INPUT with .recovered.mcap)")
    args = p.parse_args(list(argv))
    out = args.output or args.input.with_suffix(".recovered.mcap")
    try:
        res = recover(args.input, out)
    except (OSError, ValueError) as err:
        print(f"seaway record recover: {err}", file=sys.stderr)
        return 2
    print(f"{res.line()}\nwrote {out}")
    print(json.dumps({"output": str(out), "messages": res.messages, "chunks": res.chunks,
                      "complete": res.complete, "reason": res.reason, "topics": res.topics}))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    # First, before any thread: the recorder hears every message of the run on the transport's
    # threads for as long as it lasts, off the control path (seaway.runtime.memory says why).
    memory.cap_malloc_arenas()
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv and argv[0] == "recover":
        configure_logging("recorder")
        return cmd_recover(argv[1:])
    if argv and argv[0] == "run":
        argv = argv[1:]
    return run(argv)


if __name__ == "__main__":
    raise SystemExit(main())
