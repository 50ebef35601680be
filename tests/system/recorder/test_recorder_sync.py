"""The recording is synced to the disk as it goes, so a power loss loses about ``--sync-interval``
of it: seen from outside, by ``strace`` attached to a real recorder process (the syscalls it makes),
not by the recorder's own counts. And ``--sync-interval 0`` syncs nothing while recording."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import time

import pytest

from tests.system.recorder.test_recorder_crash import start

pytestmark = pytest.mark.system
WATCH_S = 3.5


def fdatasyncs(pid: int, watch_s: float) -> int:
    """fdatasync calls the process ``pid`` (every thread) makes in ``watch_s``, seen by strace."""
    out = subprocess.run(["timeout", "-s", "INT", str(watch_s), "strace", "-f", "-qq", "-e",
                          "trace=fdatasync", "-p", str(pid)], capture_output=True, text=True,
                         check=False)
    if "Operation not permitted" in out.stderr:
        pytest.skip(f"strace may not attach here: {out.stderr.strip()[:200]}")
    return out.stderr.count("fdatasync(")


@pytest.fixture
def strace() -> None:
    if shutil.which("strace") is None:
        pytest.skip("strace is not installed (.ci/run installs it)")


@pytest.mark.parametrize("interval_s", [0.5, 0.0])
def test_the_recording_is_synced_every_interval(procs, zenoh_env, tmp_path, strace,
                                                interval_s: float) -> None:
    out = tmp_path / "rec.mcap"
    rec, pub = start(procs, zenoh_env, out, "--sync-interval", str(interval_s))
    time.sleep(0.5)
    seen = fdatasyncs(rec.pid, WATCH_S)
    procs.stop(rec, signal.SIGTERM, timeout_s=10)
    procs.stop(pub, signal.SIGKILL)
    assert rec.returncode == 0, procs.log(rec)[-2000:]
    final = json.loads(procs.log(rec).strip().splitlines()[-1])
    print(f"--sync-interval {interval_s}: {seen} fdatasync in {WATCH_S} s under strace; "
          f"summary: syncs {final['syncs']}, slowest {final['sync_slowest_s']} s")
    if interval_s == 0:
        assert seen == 0 and final["syncs"] == 0
        return
    # About one a half second; strace slows the process, so the bound below is loose.
    assert seen >= 3, f"{seen} syncs in {WATCH_S} s with --sync-interval {interval_s}"
    assert final["syncs"] >= seen
