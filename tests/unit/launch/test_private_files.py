"""The launcher's private files in the stacks folder carry its pid (``authority.private_name``), and
a launcher removes those of launchers that are gone (``remove_stale``), never a live one's."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from seaway.tools.launch import authority


@pytest.fixture
def folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("SEAWAY_STACKS_DIR", str(tmp_path))
    return tmp_path


def test_the_private_name_is_the_run_and_this_launchers_pid(folder: Path) -> None:
    assert authority.private_name("paper-c1-nmpc") == f"paper-c1-nmpc.{os.getpid()}"
    assert authority.mavlink_key_path("run") == folder / f"run.{os.getpid()}.mavlink.key"


def test_only_the_files_of_launchers_that_are_gone_are_removed(folder: Path) -> None:
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    alive = os.getppid()
    for pid in (gone.pid, alive, os.getpid()):
        (folder / f"run.{pid}.credentials").mkdir()
        (folder / f"run.{pid}.credentials" / "ca.pem").write_text("x")
        (folder / f"run.{pid}.mavlink.key").write_text("k")
    (folder / "tcp-127.0.0.1-7447.json").write_text("{}")  # a registry entry: not ours to judge
    removed = authority.remove_stale()
    assert sorted(p.name for p in removed) == [f"run.{gone.pid}.credentials",
                                               f"run.{gone.pid}.mavlink.key"]
    assert sorted(p.name for p in folder.iterdir()) == sorted(
        [f"run.{alive}.credentials", f"run.{alive}.mavlink.key", f"run.{os.getpid()}.credentials",
         f"run.{os.getpid()}.mavlink.key", "tcp-127.0.0.1-7447.json"])
