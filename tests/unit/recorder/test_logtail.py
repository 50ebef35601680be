"""The recorder's log tails look at the run's log folder every flush interval: a folder that has not
changed is not listed again, and a file made in it later is still found."""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest
from seaway_recorder import logtail
from seaway_recorder.logtail import SETTLED_NS, LogTail


def test_a_settled_log_folder_is_listed_again_only_when_it_changes(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    (logs / "sim.log").write_text("first\n")
    settled = time.time_ns() - 10 * SETTLED_NS
    os.utime(logs, ns=(settled, settled))
    listed: list[str] = []
    real_glob = logtail.glob.glob
    monkeypatch.setattr(logtail.glob, "glob", lambda p: listed.append(p) or real_glob(p))
    tail = LogTail([str(logs)])
    assert [(p, line.message) for p, line in tail.poll(1)] == [("sim", "first")]
    with open(logs / "sim.log", "a") as f:  # a file known already: read without listing
        f.write("second\n")
    assert [(p, line.message) for p, line in tail.poll(2)] == [("sim", "second")]
    for _ in range(3):
        assert tail.poll(3) == []
    assert len(listed) == 1
    (logs / "controller.log").write_text("READY\n")  # the folder changes
    assert [(p, line.message) for p, line in tail.poll(4)] == [("controller", "READY")]
    assert len(listed) == 2
    tail.close()
