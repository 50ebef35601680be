"""Least exposure (#56 item 23): the stacks registry, run folders, recordings are the user's alone."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import pytest
from seaway.runtime import private, stacks


def mode(p: Path) -> int:
    return stat.S_IMODE(p.stat().st_mode)


@pytest.fixture
def wide_umask():
    old = os.umask(0o022)
    try:
        yield
    finally:
        os.umask(old)


def test_a_registry_first_made_as_a_credentials_parent_is_made_0700(
    tmp_path, monkeypatch, wide_umask
) -> None:
    # What the launcher did: the credentials folder made in the stacks folder first, with parents,
    # which gives the stacks folder the umask's 0755.
    folder = tmp_path / "state" / "stacks"
    monkeypatch.setenv(stacks.ENV_STACKS_DIR, str(folder))
    (folder / "run.1.credentials").mkdir(mode=0o700, parents=True)
    assert mode(folder) == 0o755
    stacks.private_folder()
    assert mode(folder) == 0o700
    os.chmod(folder, 0o755)
    stacks.register(stacks.StackEntry("tcp/127.0.0.1:1", os.getpid(), "sim", "/r", "none", "v1"))
    assert mode(folder) == 0o700


def test_open_private_is_0600_under_any_umask_also_for_an_existing_file(tmp_path, wide_umask) -> None:
    new = tmp_path / "new.mcap"
    with private.open_private(new) as f:
        f.write(b"x")
    assert mode(new) == 0o600
    old = tmp_path / "old.mcap"
    old.write_bytes(b"yy")
    os.chmod(old, 0o644)
    with private.open_private(old) as f:
        f.write(b"z")
    assert mode(old) == 0o600 and old.read_bytes() == b"z"


def test_a_recording_and_its_new_folder_are_private(tmp_path, wide_umask) -> None:
    from seaway_recorder.core import RecordingWriter

    w = RecordingWriter(tmp_path / "run" / "recording.mcap")
    path = w.open(1)
    w.close(2)
    assert mode(path) == 0o600 and mode(path.parent) == 0o700
