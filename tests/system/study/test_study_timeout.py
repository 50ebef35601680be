"""`seaway study`: a run over its wall-time limit is stopped, reported, and leaves no process behind."""

from __future__ import annotations

from pathlib import Path

import psutil
import pytest
from seaway_lab.study import execute as ex
from seaway_lab.study.definitions import RunSpec

pytestmark = pytest.mark.system


@pytest.mark.timeout(120)
def test_a_run_over_its_time_is_stopped(tmp_path: Path, zenoh_env: dict[str, str]) -> None:
    out = ex.run_one(RunSpec("paper-c1", "cc-empc", "#1", "cc-empc"), tmp_path / "run", timeout_s=6.0)
    assert not out.ok
    assert out.error.startswith("timed out after 6 s")
    assert out.timing["wall_s"] < 40
    assert (tmp_path / "run" / "launch.log").is_file()
    # the services (in sessions of their own, so not found by process group) are gone too
    left = [p.info for p in psutil.process_iter(["pid", "cmdline"])
            if any(str(tmp_path) in a for a in (p.info["cmdline"] or []))]
    assert left == []
