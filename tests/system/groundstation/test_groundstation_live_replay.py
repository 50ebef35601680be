"""Several readers at once of a recording still being written, through the real ground station
process over real HTTP: the recorder's own writer appends to the run folder's MCAP file (flushing
chunks as the recorder does) while four threads open it and ask for its frames.

Each reader used to repair the unfinished file into the same ``recording.recovered.mcap`` beside it
in the live run folder, and read it while another reader was rewriting it: 19 of 54 requests were
500s or 422s. Now every request succeeds and nothing is written into the run folder."""

from __future__ import annotations

import os
import re
import signal
import threading
import time
from pathlib import Path

import pytest
from seaway.contract import keys
from seaway.contract.messages import StateEstimate
from seaway_recorder.core import RecordingWriter

from tests.conftest import BIN, wait_for
from tests.system.groundstation.helpers import http

pytestmark = pytest.mark.system
VESSEL = "boat7"
T0_NS = 1_700_000_000_000_000_000
PERIOD_NS = 100_000_000
READERS = 4
REQUESTS_EACH = 3
MAX_MESSAGES = 20_000
"""The recording grows at most this far (each open reads it all)."""


def _state(i: int) -> StateEstimate:
    return StateEstimate(
        stamp_ns=T0_NS + i * PERIOD_NS, u_mps=1.0, v_mps=0.0, r_radps=0.0, x_m=0.1 * i, y_m=0.5, psi_rad=0.0
    )


def test_concurrent_reads_of_a_live_recording_all_succeed(procs, zenoh_env, tmp_path: Path) -> None:
    run = tmp_path / "runs" / "live"
    run.mkdir(parents=True)
    writer = RecordingWriter(run / "recording.mcap", foxglove=False, chunk_size=8 * 1024)
    writer.open(T0_NS)
    stop = threading.Event()
    written = [0]

    def record() -> None:  # the recorder at 200 messages/s, flushing every 20 (its interval)
        i = 0
        while not stop.is_set() and i < MAX_MESSAGES:
            msg = _state(i)
            writer.write(
                keys.NAV_STATE.key(VESSEL), msg.encode(), f"application/json;{msg.SCHEMA}", msg.stamp_ns
            )
            i += 1
            if i % 20 == 0:
                writer.flush()
                written[0] = i
                time.sleep(0.1)

    recorder = threading.Thread(target=record, daemon=True)
    recorder.start()
    env = {**zenoh_env, "SEAWAY_REPAIR_DIR": str(tmp_path / "repairs")}
    gs = procs.start(
        [str(BIN / "seaway-groundstation"), "--port", "0", "--runs-dir", str(tmp_path / "runs")],
        env,
        "groundstation",
    )
    try:
        line = wait_for(
            lambda: re.search(r"groundstation: (http://127\.0\.0\.1:\d+/)", procs.log(gs)),
            30,
            what="the ground station's address line",
        )
        base = line.group(1)
        wait_for(lambda: written[0] >= 100, 30, what="the first flushed chunks")
        answers: list[tuple[str, int, object]] = []

        def read() -> None:
            for _ in range(REQUESTS_EACH):
                status, body = http("GET", base + "api/recording?id=live", timeout_s=120)
                answers.append(("open", status, body))
                status, frames = http(
                    "GET", base + "api/recording/frames?id=live&start_s=0&end_s=5", timeout_s=120
                )
                answers.append(("frames", status, frames if status != 200 else frames["count"]))

        readers = [threading.Thread(target=read) for _ in range(READERS)]
        for t in readers:
            t.start()
        for t in readers:
            t.join(300)
        assert not any(t.is_alive() for t in readers)
    finally:
        stop.set()
        recorder.join(10)
        writer.close(T0_NS)
    failed = [a for a in answers if a[1] != 200]
    assert not failed, failed[:3]
    assert len(answers) == 2 * READERS * REQUESTS_EACH
    opened = [body for kind, _, body in answers if kind == "open"]
    assert all(b["vessels"] == [VESSEL] and b["message_count"] > 0 for b in opened)  # type: ignore[index]
    assert all(count > 0 for kind, _, count in answers if kind == "frames")  # type: ignore[operator]
    # Nothing was written into the live run folder; the repaired copies went to the cache.
    assert sorted(os.listdir(run)) == ["recording.mcap"]
    assert list((tmp_path / "repairs").glob("*/recording.*.recovered.mcap"))
    procs.stop(gs, signal.SIGTERM, timeout_s=10)
    assert gs.returncode == 0, procs.log(gs)
