"""The launcher's private files in the stacks folder carry its pid (``authority.private_name``), and
a launcher removes those of launchers that are gone (``remove_stale``), never a live one's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.runtime import credentials
from seaway.tools.launch import authority


@pytest.fixture
def folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("SEAWAY_STACKS_DIR", str(tmp_path))
    monkeypatch.delenv(credentials.ENV_CREDENTIALS, raising=False)  # the launcher makes its own
    return tmp_path


def test_the_private_name_is_the_run_and_this_launchers_pid(folder: Path) -> None:
    assert authority.private_name("paper-c1-nmpc") == f"paper-c1-nmpc.{os.getpid()}"
    assert authority.mavlink_key_path("run") == folder / f"run.{os.getpid()}.mavlink.key"


def test_only_the_files_of_launchers_that_are_gone_are_removed(folder: Path) -> None:
    """Before a launcher makes its own: a live launcher's stay; a gone one's go, this pid's too (a
    gone launcher's with the same pid: a new key may not overwrite its key file)."""
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    alive = os.getppid()
    for pid in (gone.pid, alive, os.getpid()):
        (folder / f"run.{pid}.credentials").mkdir()
        (folder / f"run.{pid}.credentials" / "ca.pem").write_text("x")
        (folder / f"run.{pid}.mavlink.key").write_text("k")
    (folder / "tcp-127.0.0.1-7447.json").write_text("{}")  # a registry entry: not ours to judge
    removed = authority.remove_stale()
    assert sorted(p.name for p in removed) == sorted(
        f"run.{pid}.{kind}" for pid in (gone.pid, os.getpid()) for kind in ("credentials",
                                                                            "mavlink.key"))
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f"run.{alive}.credentials", f"run.{alive}.mavlink.key", "tcp-127.0.0.1-7447.json"])


def test_a_launcher_with_a_gone_launchers_pid_makes_its_files(folder: Path) -> None:
    """A launcher killed left its files; a new one with the same pid and run name starts."""
    from seaway.tools.launch.profile import load_profile

    (folder / f"run.{os.getpid()}.mavlink.key").write_text("old")
    (folder / f"run.{os.getpid()}.credentials").mkdir()
    auth = authority.credentials_for(load_profile("sim-batch"), "run")
    try:
        assert auth.mavlink_key is not None and auth.mavlink_key.read_bytes() != b"old"
        assert auth.credentials is not None and auth.credentials.folder.is_dir()
    finally:
        auth.release()
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("writes", [False, True])
def test_a_launch_with_ros2_writes_lets_the_face_ask_the_missions_requests(folder: Path,
                                                                         writes: bool) -> None:
    """--ros2 --ros2-writes: the per-run rules are access.acl(ros2_writes=True); without, not."""
    from seaway.contract import access
    from seaway.tools.launch.profile import load_profile, with_ros2

    profile = with_ros2(load_profile("sim"), ["tcp/127.0.0.1:7447"], 3, writes=writes)
    assert profile.ros2_writes() is writes
    auth = authority.credentials_for(profile, "run")
    try:
        assert auth.credentials is not None
        assert auth.credentials.access_rules() == access.acl(profile.producers(), ros2_writes=writes)
    finally:
        auth.release()
