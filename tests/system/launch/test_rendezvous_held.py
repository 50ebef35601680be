"""Issue 56, item 22: a rendezvous port held by something that is not a stack of this registry.

A Zenoh peer without this stack's credentials on the rendezvous port, or a second stack registered
in another stacks folder on the same port, let every process start and none link: the launch
failed 30 s later with "recorder not ready". Now the launcher's own session, opened with the
stack's credentials, must link to the holder within ``RENDEZVOUS_PROBE_S``; else the launch stops
before starting anything, naming the endpoint and the holder's pid (exit 2).
"""

from __future__ import annotations

import os
import signal
import sys
import time
from pathlib import Path

import pytest
from seaway.runtime import credentials, stacks
from seaway.runtime.bus import Bus
from seaway.tools.launch.authority import port_holder

from tests.conftest import wait_for
from tests.system.launch.test_launcher import proc, write_profile

pytestmark = pytest.mark.system
LAUNCH_S = 60.0  # bounds a failure only: the refusal comes within the probe's 5 s after start-up


def _own_credentials(env: dict[str, str], stacks: Path) -> dict[str, str]:
    """A launcher that makes its own authority for the run (no given credentials), registering in
    ``stacks``."""
    env = dict(env)
    env.pop(credentials.ENV_CREDENTIALS, None)
    env.pop(credentials.ENV_IDENTITY, None)
    env["SEAWAY_STACKS_DIR"] = str(stacks)
    return env


def _launch(procs, env: dict[str, str], tmp: Path, name: str):
    folder = tmp / name
    folder.mkdir()
    profile = write_profile(folder, proc("rec", "recorder"))
    return procs.start(
        [sys.executable, "-m", "seaway.tools.cli", "launch", str(profile), "--run-dir", str(folder / "run")],
        env,
        name,
    )


def _refused_naming(procs, la, holder_pid: int) -> str:
    la.wait(LAUNCH_S)
    out = procs.log(la)
    assert la.returncode == 2, out[-3000:]
    assert "not ready" not in out, out[-3000:]
    line = next((ln for ln in out.splitlines() if "rendezvous endpoint" in ln), "")
    assert f"process {holder_pid} " in line, out[-3000:]
    return out


@pytest.mark.timeout(120)
def test_a_peer_without_credentials_on_the_port_is_named_at_once(
    procs, zenoh_env, tmp_path, monkeypatch
) -> None:
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, credentials.NONE)
    with Bus.open("vessel1", credentials=credentials.NONE):  # this process holds the port
        env = _own_credentials(zenoh_env, tmp_path / "stacks")
        t0 = time.monotonic()
        la = _launch(procs, env, tmp_path, "second")
        out = _refused_naming(procs, la, os.getpid())
        assert time.monotonic() - t0 < LAUNCH_S
    assert not (tmp_path / "second" / "run" / "logs" / "rec.log").exists(), out  # nothing started


@pytest.mark.timeout(180)
def test_a_stack_of_another_registry_on_the_port_is_named(procs, zenoh_env, tmp_path) -> None:
    first = _launch(procs, _own_credentials(zenoh_env, tmp_path / "stacks-a"), tmp_path, "first")
    wait_for(lambda: "all ready" in procs.log(first), 60, what="the first stack ready")
    second = _launch(procs, _own_credentials(zenoh_env, tmp_path / "stacks-b"), tmp_path, "second")
    _refused_naming(procs, second, first.pid)
    assert first.poll() is None  # the first stack runs on, undisturbed
    procs.stop(first, signal.SIGINT, timeout_s=15)
    assert first.returncode == 0, procs.log(first)[-3000:]


@pytest.mark.timeout(120)
def test_a_registered_stack_already_holds_its_rendezvous_port(
    procs, zenoh_env, tmp_path, monkeypatch
) -> None:
    """Whoever finds the stack in the registry and opens a session (a test's operator session, a
    `seaway` command) must find the port held by the launcher: taken by that session instead, the
    stack linked through it and the links refused there went uncounted (`seaway health`)."""
    env = _own_credentials(zenoh_env, tmp_path / "stacks")
    monkeypatch.setenv("SEAWAY_STACKS_DIR", env["SEAWAY_STACKS_DIR"])
    endpoint = env["SEAWAY_ZENOH_RENDEZVOUS"]
    la = _launch(procs, env, tmp_path, "held")
    # Polled tightly: the first look that finds the entry asks who holds the port.
    entry = wait_for(lambda: stacks.lookup(endpoint), LAUNCH_S, 0.01, what="the stack registered")
    holder = port_holder(int(endpoint.rpartition(":")[2]))
    assert entry.pid == la.pid
    assert holder is not None and holder[0] == la.pid, (holder, procs.log(la)[-3000:])
    procs.stop(la, signal.SIGINT, timeout_s=15)
