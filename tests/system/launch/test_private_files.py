"""Least exposure (#56 item 23), through the real launcher and processes: the stacks registry, the
run folder and everything in it (recording, logs, events, run description) are the user's alone,
whatever umask the launch was started under."""

from __future__ import annotations

import os
import stat

import pytest

from tests.system.recorder.test_foxglove_recording import launch

pytestmark = pytest.mark.system


def test_a_launch_writes_its_registry_0700_and_its_run_files_0600(tmp_path, zenoh_env) -> None:
    old = os.umask(0o022)  # the common default, which the launch inherits
    try:
        path = launch("sim-batch", tmp_path, zenoh_env, timeout_s=300)
    finally:
        os.umask(old)
    registry = tmp_path / "stacks"  # zenoh_env's SEAWAY_STACKS_DIR
    run_dir = path.parent
    assert registry.is_dir()
    wide = {}
    for p in [registry, run_dir, *run_dir.rglob("*")]:
        want = 0o700 if p.is_dir() else 0o600
        if stat.S_IMODE(p.stat().st_mode) != want:
            wide[str(p.relative_to(tmp_path))] = oct(stat.S_IMODE(p.stat().st_mode))
    assert wide == {}
    names = {p.name for p in run_dir.rglob("*")}
    assert {"recording.mcap", "logs", "events.jsonl", "run.json"} <= names
    assert any(p.suffix == ".log" for p in (run_dir / "logs").iterdir())
