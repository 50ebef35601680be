"""The replay part of ``seaway bench groundstation``: a recording of about ``--replay-mb`` opened
through the HTTP API the page's replay view uses, as it uses it.

The recording: a real lockstep run (``seaway launch sim-batch``, paper condition #1 flown by
CC-EMPC; sim, estimator, controller and the recorder as processes) whose recorded bus messages are
written again, one repetition after another on the recording's clock, by the recorder's own
writer (``RecordingWriter``, a chunk per control period as the lockstep recorder ends one) until
the file is that large: a long run of the same stack without waiting for it. ``--recording FILE``
replays an ``.mcap`` of your own instead.

Each repetition of the measurement opens its own name for the file (a hard link in a run folder of
its own), so the ground station reads it afresh: ``GET /api/recording``, then
``/api/recording/frames`` from where the last answer was whole, the first request 2 s of recorded
time and each after it 120 s, every answer parsed as the page parses it. Figures: the time to the
first frame (target <= 3 s) and to the whole timeline (target <= 10 s), median and largest over
the repetitions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

from seaway.contract import keys
from seaway.runtime.stacks import ENV_STACKS_DIR
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.vessel.metrics import median

from seaway_lab.bench.common import BenchResult, free_rendezvous

TARGET_FIRST_FRAME_S = 3.0
TARGET_TIMELINE_S = 10.0
FIRST_WINDOW_S, WINDOW_S = 2.0, 120.0
"""The page's requests (``static/js/replay.js``): the first span, then each after it [s]."""
PERIOD_NS = 100_000_000
"""A chunk per this much recorded time, as the lockstep recorder ends one per control period."""
SCENARIO, CONTROLLER = "paper-c1", "cc-empc"


def lockstep_run(run_dir: Path, env: dict[str, str]) -> Path:
    """A real run of the stack in lockstep into ``run_dir``; its recording."""
    env = {k: v for k, v in env.items() if k not in (ENV_CONFIG,)}
    env[ENV_RENDEZVOUS] = free_rendezvous()
    env[ENV_STACKS_DIR] = str(run_dir.parent / "stacks")
    subprocess.run([str(Path(sys.executable).parent / "seaway"), "launch", "sim-batch", "--scenario",
                    SCENARIO, "--controller", CONTROLLER, "--run-dir", str(run_dir)],
                   env=env, check=True, capture_output=True, timeout=1800)
    return run_dir / "recording.mcap"


def repeat_recording(src: Path, dst: Path, target_bytes: int) -> tuple[int, int]:
    """Write the bus messages of ``src`` again and again into ``dst`` with the recorder's writer,
    each repetition after the last on the log-time clock, until ``dst`` holds ``target_bytes``;
    (repetitions, messages written)."""
    from seaway.recording import reader
    from seaway_recorder.core import RecordingWriter

    files = reader.open_paths([src])
    msgs = [(m.log_time_ns, m.topic, m.data) for m in reader.iter_messages(files)
            if (spec := keys.spec_for_key(m.topic)) is not None and spec.message is not None]
    if not msgs:
        raise SystemExit(f"seaway bench groundstation: {src} has no bus messages to replay")
    encodings = {t: f"application/json;{keys.spec_for_key(t).message.SCHEMA}"  # type: ignore[union-attr]
                 for t in {t for _, t, _ in msgs}}
    t0, span = msgs[0][0], msgs[-1][0] - msgs[0][0] + 1_000_000_000
    w = RecordingWriter(dst, foxglove=False, validate=False)
    w.open(t0)
    reps = written = 0
    while True:
        shift = reps * span
        last_flush = t0 + shift
        for log_ns, topic, data in msgs:
            at = log_ns + shift
            if at - last_flush >= PERIOD_NS:
                w.flush()
                last_flush = at
            w.write(topic, data, encodings[topic], at)
            written += 1
        reps += 1
        w.flush()
        if dst.stat().st_size >= target_bytes:
            break
    w.close(t0 + reps * span)
    return reps, written


def _get(url: str) -> dict:
    with urllib.request.urlopen(url, timeout=120) as r:
        return json.loads(r.read())


def open_like_the_page(base: str, ref: str) -> tuple[float, float, int, float]:
    """(first frame [s], whole timeline [s], frames, recorded duration [s]) of one open."""
    t0 = time.perf_counter()
    detail = _get(f"{base}api/recording?id={ref}")
    end = detail["duration_s"] + 1
    loaded, frames, first, requests = 0.0, 0, None, 0
    while loaded < end:
        span = WINDOW_S if requests else FIRST_WINDOW_S
        requests += 1
        w = _get(f"{base}api/recording/frames?id={ref}&start_s={loaded}&end_s={loaded + span}")
        frames += len(w["frames"])
        if first is None and w["frames"]:
            first = time.perf_counter() - t0
        loaded = max(loaded, w["loaded_to_s"])
    whole = time.perf_counter() - t0
    return (whole if first is None else first), whole, frames, detail["duration_s"]


Serve = Callable[[Path], tuple[str, Callable[[], None]]]


def measure(res: BenchResult, base_url_of: Serve, tmp: Path, env: dict[str, str], size_mb: float,
            repeat: int, recording_dir: Path | None) -> None:
    """Add the replay figures to ``res``. ``base_url_of(runs_dir)``: starts a ground station on
    that runs folder and returns (its base URL, a function that stops it)."""
    runs = tmp / "replay-runs"
    runs.mkdir()
    made = time.perf_counter()
    if recording_dir is None:
        base_run = lockstep_run(tmp / "lockstep-run", env)
        src = runs / "source" / "recording.mcap"
        src.parent.mkdir()
        reps, written = repeat_recording(base_run, src, int(size_mb * 1e6))
        how = (f"a lockstep run of {SCENARIO} ({CONTROLLER}) written {reps} times over by the "
               f"recorder's writer ({written:,} messages)")
    else:
        src, how = recording_dir, str(recording_dir)
    res.meta["replay_recording_made_s"] = round(time.perf_counter() - made, 1)
    size = src.stat().st_size
    for i in range(repeat):
        (runs / f"open-{i}").mkdir()
        os.link(src, runs / f"open-{i}" / "recording.mcap")
    base, stop = base_url_of(runs)
    firsts, wholes = [], []
    try:
        for i in range(repeat):
            first, whole, frames, duration = open_like_the_page(base, f"open-{i}")
            firsts.append(first)
            wholes.append(whole)
    finally:
        stop()
    res.add("replay_recording_mb", size / 1e6, note=how)
    res.add("replay_first_frame_s", median(firsts), f"<= {TARGET_FIRST_FRAME_S:g}",
            median(firsts) <= TARGET_FIRST_FRAME_S,
            note=f"median of {repeat}; largest {max(firsts):.2f} s; open to the first frame")
    res.add("replay_timeline_s", median(wholes), f"<= {TARGET_TIMELINE_S:g}",
            median(wholes) <= TARGET_TIMELINE_S,
            note=f"median of {repeat}; largest {max(wholes):.2f} s; {frames:,} frames over "
                 f"{duration:.0f} s recorded")
    res.meta.update(replay_repeat=repeat, replay_frames=frames, replay_duration_s=round(duration, 1))
