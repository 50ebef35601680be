"""``seaway record``: every sample on ``seaway/**`` into MCAP; ``seaway record recover IN OUT``.

The process (also ``seaway-recorder``) subscribes to the bus; Zenoh's delivery threads only append
``(key, bytes, encoding, receive time)`` to a bounded queue (a full queue drops the sample and counts
it), and one writer thread drains the queue into ``RecordingWriter`` (in lockstep, the thread that
delivers a member's answer writes its period: ``node.RecorderNode.write_on_arrival``). The writer
flushes at least every ``--flush-interval`` (default 50 ms: a SIGKILL loses less than 100 ms),
rotates files on ``--max-bytes`` / ``--max-seconds``, logs counts every ``--status-interval`` and, on
SIGINT or SIGTERM, writes what is queued and finishes a fully indexed file. The last line on stdout
is a JSON summary. It also copies the launcher's events (``--events``) and the run's log files
(``--logs``) into the recording as they grow. Log times follow ``timebase`` (sim time on the run's
epoch in lockstep).
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
from seaway.recording.recover import recover
from seaway.recording.tail import tail_of
from seaway.recording.timebase import RecordingTime, parse_epoch
from seaway.runtime import memory
from seaway.runtime import run as runs
from seaway.runtime.bus_raw import REJOIN_HISTORY_S
from seaway.runtime.config import parse_service_args, service_parser
from seaway.runtime.lockstep_witness import LockstepWitness
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import configure_logging, resolve_run, run_service
from seaway.runtime.zenoh_bus import ENV_CONFIG
from seaway.simkit.scenario import load_scenario
from seaway.vessel.frames import GeoOrigin

from seaway_recorder import attachments
from seaway_recorder.config import RecorderConfig, parse_meta
from seaway_recorder.core import RUN_METADATA, AttachmentSpec, RecordingWriter
from seaway_recorder.logtail import FileTail, LogTail
from seaway_recorder.node import LATE_NS, KeptKeys, RecorderNode, SampleQueue, Tails, lockstep_exprs
from seaway_recorder.openfile import LIBRARY
from seaway_recorder.syncer import Syncer

log = logging.getLogger("seaway.recorder")


def default_out() -> Path:
    stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path("runs") / stamp / "recording.mcap"


def out_path(text: str | None) -> Path:
    if not text:
        return default_out()
    p = Path(text)
    return p if p.suffix == ".mcap" else p / "recording.mcap"


def parser() -> argparse.ArgumentParser:
    return service_parser(
        "recorder", prog="seaway record [run]", model=RecorderConfig,
        description="Two commands. 'seaway record [run] [options]' (the default) records every "
                    "sample on the bus to MCAP until Ctrl-C: bytes unchanged, with their JSON "
                    "Schemas, flushed at least every --flush-interval so a crash loses little; the "
                    "launcher starts it as the recorder. 'seaway record recover IN [OUT]' rebuilds a "
                    "fully indexed file from one a crash cut short (seaway record recover --help).")


def newest_recording(base: Path) -> Path | None:
    """The newest of ``base`` and its ``.restart-<k>`` siblings (``openfile.free_path``) that exists:
    the recording a recorder restarted into the same run folder takes over from."""
    found = [p for p in [base, *base.parent.glob(f"{base.stem}.restart-*{base.suffix}")] if p.is_file()]
    return max(found, key=lambda p: p.stat().st_mtime_ns) if found else None


def key_exprs(cfg: RecorderConfig) -> list[str]:
    if cfg.key_expr:
        return list(cfg.key_expr)
    vessels = [v.strip() for v in cfg.vessels.split(",") if v.strip()]
    return [keys.vessel_wildcard(v) for v in vessels] or [keys.vessel_wildcard()]


def build_run_info(args: argparse.Namespace, cfg: RecorderConfig, exprs: list[str],
                   run: RunDescription):
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
    if cfg.profile:
        atts.append(attachments.attachment("profile", runinfo.profile_path(cfg.profile)))
    if cfg.mission:
        atts.append(attachments.attachment("mission", Path(cfg.mission)))
    zcfg = args.zenoh_config or os.environ.get(ENV_CONFIG)
    if zcfg:
        atts.append(attachments.attachment("zenoh", Path(zcfg)))
    atts += [attachments.parse_attach_arg(a) for a in cfg.attach]
    meta = {
        "recorder": LIBRARY,
        "started_utc": dt.datetime.now(dt.UTC).isoformat(timespec="milliseconds"),
        "host": socket.gethostname(),
        "key_exprs": ",".join(exprs),
        "scenario": scenario_name,
        "run_id": run.run_id,
        "control_period_s": f"{run.control_period_s:g}",
        "clock": run.clock,
        "profile": Path(cfg.profile).stem if cfg.profile else "",
        "flush_interval_s": f"{cfg.flush_interval_s:g}",
        "command": " ".join(sys.argv),
        "attachments": ",".join(a.name for a in atts),
        **parse_meta(cfg.meta),
    }
    return atts, {RUN_METADATA: meta}, origin


def recording_time(args: argparse.Namespace, cfg: RecorderConfig, run: RunDescription,
                   now_ns: int) -> RecordingTime:
    """The recording's time convention (``timebase``): the run's clock and, in lockstep, its epoch:
    ``--sim-epoch``, else when the run started (the launcher writes ``--run`` then, and a restarted
    recorder reads the same file), else ``now_ns``; whole seconds."""
    if not run.lockstep:
        return RecordingTime.real_time()
    if cfg.sim_epoch:
        epoch_ns, source = parse_epoch(cfg.sim_epoch), "--sim-epoch"
    elif (started := runs.started_ns(args.run)) is not None:
        epoch_ns, source = started, f"run started ({args.run} written)"
    else:
        epoch_ns, source = now_ns, "recorder started"
    return RecordingTime(lockstep=True, epoch_ns=epoch_ns - epoch_ns % 1_000_000_000,
                         epoch_source=source, gap_ns=run.control_period_ns)


def run(argv: Sequence[str]) -> int:
    args, cfg = parse_service_args(parser(), argv, RecorderConfig)
    exprs = key_exprs(cfg)
    run = resolve_run(args, "recorder", load_scenario)
    try:
        atts, meta, origin = build_run_info(args, cfg, exprs, run)
        rec_time = recording_time(args, cfg, run, time.time_ns())
    except (ConfigError, ValueError, OSError) as err:
        print(f"seaway record: {err}", file=sys.stderr)
        return 2
    writer = RecordingWriter(out_path(cfg.out), chunk_size=cfg.chunk_size_bytes,
                             compression=cfg.compression, max_bytes=cfg.max_bytes,
                             max_seconds=cfg.max_seconds, attachments=atts, metadata=meta,
                             validate=cfg.validate_samples, foxglove=cfg.foxglove,
                             default_origin=origin, time=rec_time,
                             durable=cfg.sync_interval_s > 0)
    queue = SampleQueue(cfg.queue)  # and at most node.DEFAULT_QUEUE_BYTES of payloads
    # The recorder records whatever runs (a shore recorder sees a boat launched elsewhere), so it
    # does not take part in the run agreement; its run only describes the recording.
    with run_service("recorder", args, run=run, agree=False) as ctx:
        started_ns = time.time_ns()
        previous = None if run.lockstep or writer.rotating else newest_recording(writer.base)
        try:
            path = writer.open(started_ns)
        except OSError as err:  # a folder that cannot be made or written: said, not a traceback
            print(f"seaway record: --out {cfg.out}: cannot write a recording there: {err}",
                  file=sys.stderr)
            return 2
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
            tail = tail_of(previous, started_ns - round(REJOIN_HISTORY_S * 1e9) - LATE_NS)
            queue.already = tail.messages
            # The caches are asked once subscribed, below, after the predecessor's file was read
            # (its records walked, its last chunks opened): for the REJOIN_HISTORY_S before now,
            # not before the start. What fell between is the gap said in the file.
            asked_from_ns = time.time_ns() - round(REJOIN_HISTORY_S * 1e9)
            read_s = (asked_from_ns - started_ns) / 1e9 + REJOIN_HISTORY_S
            if read_s > 1.0:
                log.warning("reading %s took %.1f s before recording could go on", previous.name,
                            read_s)
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
        tails = Tails(FileTail(cfg.events) if cfg.events else None,
                      LogTail(cfg.logs) if cfg.logs else None,
                      ctx.bus.publisher(keys.LOG_LINE).put if cfg.logs else None)
        syncer = Syncer(cfg.sync_interval_s)
        node = RecorderNode(writer, queue, cfg.flush_interval_s, cfg.status_interval_s, witness,
                            tails, kept, syncer)
        run_node(ctx, node, cfg.flush_interval_s)
        syncer.close()
        failed = node.failed is not None
        writer.count_dropped(queue.dropped - writer.stats.dropped)
        try:
            files = writer.close()
        except OSError as err:
            log.error("could not finish %s: %s (try 'seaway record recover')", writer.path, err)
            return 1
    summary = {"files": files, **writer.stats.as_metadata(), "by_topic": dict(writer.stats.by_topic),
               "repeats_not_written": queue.repeats, "dropped_bytes": queue.dropped_bytes,
               **syncer.figures()}
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
