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


def test_a_runs_own_authority_has_no_end_of_validity(folder: Path) -> None:
    """A boat that boots at 1970 makes its run's credentials then: valid for 30 days from that
    moment, they were expired once GPS time came, and no process restarted after could join."""
    from cryptography import x509
    from seaway.tools.launch.profile import load_profile

    auth = authority.credentials_for(load_profile("sim"), "run")
    try:
        assert auth.credentials is not None
        pems = [auth.credentials.folder / "ca.pem", *auth.credentials.folder.glob("controller.pem")]
        assert len(pems) == 2
        for pem in pems:
            cert = x509.load_pem_x509_certificate(pem.read_bytes())
            assert cert.not_valid_before_utc.year == 1970, pem
            assert cert.not_valid_after_utc == credentials.NO_END, pem
        assert not [n for n in auth.notes if "WARNING" in n]
    finally:
        auth.release()


@pytest.mark.parametrize(("days", "warned"), [(3, True), (8, False)])
def test_a_launch_on_credentials_that_end_within_a_week_warns(folder: Path, monkeypatch, days: int,
                                                             warned: bool) -> None:
    """Every link closes as its certificate ends: a boat's set that ends mid-mission ends the
    stack. The launcher says when, while there is time to make new ones."""
    from seaway.tools.launch.profile import load_profile

    given = credentials.create(folder / "boat", days=days)
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, str(given.folder))
    auth = authority.credentials_for(load_profile("sim"), "run")
    try:
        warnings = [n for n in auth.notes if "WARNING" in n]
        assert bool(warnings) is warned, auth.notes
        if warned:  # names the end and the folder
            end = given.ends("launcher")
            assert f"{end:%Y-%m-%d}" in warnings[0] and str(given.folder) in warnings[0]
    finally:
        auth.release()
