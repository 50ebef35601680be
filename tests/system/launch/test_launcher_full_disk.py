"""The launcher on a disk with no room: its processes are never blocked by their logs, and nothing
the launcher writes raises. On a real, small filesystem (a tmpfs this test mounts; it needs root)
filled by another file, the real supervisor runs a real process that writes far more than a pipe
holds while the disk is full.

Before: the pump that copies a process's output into ``logs/<name>.log`` died on the first write
that found no room; nothing read the pipe any more, and the process blocked on its next line once
the pipe's 64 KiB were full (every service of a run would hang that way).
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import pytest
from seaway.tools.launch.events import EVENTS_FILE
from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec
from seaway.tools.launch.supervisor import Supervised, Supervisor

from tests.conftest import wait_for
from tests.system.small_disk import fill

pytestmark = pytest.mark.system
DURING = 20_000
"""Lines written while the disk is full: about 1.4 MB, twenty pipes' worth."""

CHILD = r"""
import os, sys, time
full, room, done = sys.argv[1:]
for i in range(100):
    print(f"before {i}")
sys.stdout.flush()
while not os.path.exists(full):
    time.sleep(0.01)
for i in range(int(os.environ["DURING"])):
    print(f"during {i} " + "x" * 60)
sys.stdout.flush()
open(done, "w").close()
while not os.path.exists(room):
    time.sleep(0.01)
time.sleep(1.5)  # past the log's next try (logsink.RETRY_S)
for i in range(100):
    print(f"after {i}")
"""


def test_a_full_disk_never_blocks_a_process_on_its_log(small_disk, tmp_path: Path) -> None:
    flags = {k: tmp_path / k for k in ("full", "room", "done")}  # off the small disk
    argv = [sys.executable, "-c", CHILD, *(str(flags[k]) for k in ("full", "room", "done"))]
    sp = Supervised(ProcessSpec(name="talker", command=argv, env={"DURING": str(DURING)}), argv,
                    "vessel1")
    said: list[str] = []
    sup = Supervisor([sp], small_disk, {}, BackoffPolicy(), echo=said.append)
    sup.spawn(sp)
    log = small_disk / "logs" / "talker.log"
    wait_for(lambda: "before 99" in log.read_text(), 20, what="the first lines logged")

    filler = fill(small_disk)
    flags["full"].touch()
    wait_for(flags["done"].exists, 60, what="the process to write all it had while the disk was full "
             "(it blocks if its output is no longer read)")
    assert sp.popen is not None and sp.popen.poll() is None
    assert any("talker.log" in line for line in said), said  # the terminal was told, once
    # Events on the full disk: kept, never raised (the events file's last page of the filesystem
    # takes a few first).
    hung = 0
    while not sup.events_out.waiting(small_disk / EVENTS_FILE):
        assert hung < 500, "500 events written on a full disk"
        sup._event(sp, "hung", reason=f"event {hung} on a full disk")
        hung += 1
    sup._event(sp, "hung", reason=f"event {hung} on a full disk")
    hung += 1
    assert sup.events_out.waiting(small_disk / EVENTS_FILE) == 2

    filler.unlink()
    flags["room"].touch()
    assert sp.popen.wait(30) == 0
    wait_for(lambda: "after 99" in log.read_text(), 20, what="the log written again with room")
    text = log.read_text()
    during = sum(1 for line in text.splitlines() if line.startswith("during "))
    (marker,) = [line for line in text.splitlines() if line.startswith("--- ") and "lines" in line]
    dropped = int(re.search(r"(\d+) lines", marker).group(1))
    assert during + dropped == DURING, (during, dropped)  # each line written whole, or counted
    assert dropped > DURING // 2
    assert all(f"after {i}" in text for i in range(100))

    sup._event(sp, "exit", code=0)  # room: the waiting event goes out first, then this one
    events = [json.loads(line) for line in (small_disk / EVENTS_FILE).read_text().splitlines()]
    assert [e["event"] for e in events] == ["start", *["hung"] * hung, "exit"]
    assert [e["reason"] for e in events[1:-1]] == [f"event {k} on a full disk" for k in range(hung)]
    assert sup.events_out.waiting(small_disk / EVENTS_FILE) == 0
