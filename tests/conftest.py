"""Shared test fixtures: isolated Zenoh sessions and real processes that are always cleaned up.

Every test that starts processes gets its own rendezvous port (``SEAWAY_ZENOH_RENDEZVOUS``), so
tests never hear each other or a stack the developer is running.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from seaway_vehicle_io.sitl_px4 import udp_port_free  # noqa: F401 - the tests' one

REPO = Path(__file__).resolve().parents[1]
PYTHON = sys.executable
BIN = Path(PYTHON).parent


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--regen", action="store_true",
                     help="re-record tests/replay/data/*.mcap from the live stack, then test against them")
    parser.addoption("--slow", action="store_true",
                     help="also run the tests marked slow (long system tests: browser, soak, real "
                          "autopilot firmware); CI runs them, the default ./test does not")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked ``slow`` run only with ``--slow`` (or when ``-m`` names them), so the default
    ``./test`` stays under about 15 minutes on a 2-core machine."""
    _longest_first(config, items)
    if config.getoption("--slow") or "slow" in (config.getoption("-m") or ""):
        return
    skip = pytest.mark.skip(reason="slow: run with ./test --slow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


DURATIONS_KEY = "seaway/durations"
"""Where the last runs' time per test (setup + call + teardown, seconds) is kept, in pytest's
cache (``.pytest_cache``): the next run starts the longest files first (``_longest_first``)."""
UNKNOWN_SYSTEM_S, UNKNOWN_OTHER_S = 10.0, 0.1
"""What a test not yet timed on this machine is guessed to take: system tests (real processes) are
the long ones, so a fresh clone still starts them before the unit tests."""


def _longest_first(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Order the test files longest first (a file's tests stay together and in their order), so
    that the xdist workers (``-n``, ``--dist worksteal`` in pyproject.toml) end together instead of
    one running the last long file alone. Only the order changes, never what runs."""
    cache = getattr(config, "cache", None)
    known: dict[str, float] = (cache.get(DURATIONS_KEY, {}) if cache is not None else {}) or {}
    per_file: dict[str, float] = {}
    for item in items:
        guess = UNKNOWN_SYSTEM_S if "/system/" in item.nodeid else UNKNOWN_OTHER_S
        file = item.nodeid.split("::", 1)[0]
        per_file[file] = per_file.get(file, 0.0) + float(known.get(item.nodeid, guess))
    # sorted() is stable: files of equal estimate keep their collection order.
    items[:] = sorted(items, key=lambda item: -per_file[item.nodeid.split("::", 1)[0]])


class _Durations:
    """Collects each test's time where the reports arrive (the xdist controller, or the only
    process without ``-n``) and merges them into the cache at the end of the session."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if not report.skipped:
            self.seconds[report.nodeid] = self.seconds.get(report.nodeid, 0.0) + report.duration

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self, session: pytest.Session) -> None:
        cache = getattr(session.config, "cache", None)
        if cache is None or not self.seconds:
            return
        known = cache.get(DURATIONS_KEY, {}) or {}
        known.update({k: round(v, 3) for k, v in self.seconds.items()})
        cache.set(DURATIONS_KEY, known)


def pytest_configure(config: pytest.Config) -> None:
    if not hasattr(config, "workerinput"):  # not an xdist worker: reports arrive here
        config.pluginmanager.register(_Durations(), "seaway-durations")


@pytest.fixture(autouse=True)
def _no_root_handler_on_a_closed_capture() -> Iterator[None]:
    """A test that runs a command's ``main`` in-process (``configure_logging``: ``basicConfig`` on
    ``sys.stderr``, which is then pytest's capture) leaves that handler on the root logger; once the
    capture is closed, any later record (a solver build's thread in another test) is a "Logging
    error ... I/O operation on closed file". Handlers the test added are removed after it."""
    root = logging.getLogger()
    before = set(root.handlers)
    yield
    for h in list(root.handlers):
        if h not in before and type(h) is logging.StreamHandler:
            root.removeHandler(h)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]



@pytest.fixture
def zenoh_env(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> dict[str, str]:
    """Environment for processes (and this test's own sessions) on a private rendezvous port, with
    the test's own credentials: every service is its own identity, this test (and any process it
    starts that is not a service) is the harness, which may do everything; a launcher started
    here uses them too. Stacks register in the test's own folder."""
    from seaway.runtime import credentials

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    monkeypatch.setenv("SEAWAY_ZENOH_RENDEZVOUS", endpoint)
    monkeypatch.delenv("SEAWAY_ZENOH_CONFIG", raising=False)
    folder = credentials.create(tmp_path / "credentials", harness=True).folder
    monkeypatch.setenv(credentials.ENV_CREDENTIALS, str(folder))
    monkeypatch.setenv(credentials.ENV_IDENTITY, "harness")
    monkeypatch.setenv("SEAWAY_STACKS_DIR", str(tmp_path / "stacks"))
    env = dict(os.environ)
    env["PYTHONUNBUFFERED"] = "1"
    return env


class Procs:
    """Starts real processes in their own process groups and kills whatever is left at the end."""

    def __init__(self, tmp: Path) -> None:
        self.tmp = tmp
        self.procs: list[subprocess.Popen] = []

    def start(self, args: list[str], env: dict[str, str], name: str | None = None) -> subprocess.Popen:
        name = name or Path(args[0]).name
        log = open(self.tmp / f"{name}.log", "wb")  # noqa: SIM115 - closed with the process
        p = subprocess.Popen(args, env=env, stdout=log, stderr=subprocess.STDOUT,
                             start_new_session=True, cwd=REPO)
        p.log_path = self.tmp / f"{name}.log"  # type: ignore[attr-defined]
        self.procs.append(p)
        return p

    def launch(self, env: dict[str, str], *args: str, name: str = "launcher") -> subprocess.Popen:
        """``seaway launch ARGS`` (this interpreter's CLI) under ``env``, its output in ``name``'s
        log."""
        return self.start([PYTHON, "-m", "seaway.tools.cli", "launch", *args], env, name)

    def launch_ready(self, env: dict[str, str], *args: str, timeout_s: float = 240.0
                     ) -> subprocess.Popen:
        """``launch`` and wait until the launcher says all its processes are ready; a launcher
        that exits first fails the test with its output."""
        import pytest

        launcher = self.launch(env, *args)

        def ready() -> bool:
            if launcher.poll() is not None:
                pytest.fail(f"the launcher exited ({launcher.returncode}):\n"
                            f"{self.log(launcher)[-3000:]}")
            return "all ready in" in self.log(launcher)

        wait_for(ready, timeout_s, interval_s=0.2, what=f"seaway launch {' '.join(args)} ready")
        return launcher

    @staticmethod
    def log(p: subprocess.Popen) -> str:
        return Path(p.log_path).read_text(errors="replace")  # type: ignore[attr-defined]

    def stop(self, p: subprocess.Popen, sig: int = signal.SIGTERM, timeout_s: float = 5.0) -> float:
        """Signal ``p`` and return how long it took to exit (raises if it did not)."""
        t0 = time.monotonic()
        if p.poll() is None:
            p.send_signal(sig)
            p.wait(timeout_s)
        return time.monotonic() - t0

    def cleanup(self) -> None:
        for p in self.procs:
            if p.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(p.pid, signal.SIGKILL)
                p.wait(5)


@pytest.fixture
def procs(tmp_path: Path) -> Iterator[Procs]:
    ps = Procs(tmp_path)
    try:
        yield ps
    finally:
        ps.cleanup()


def wait_for(predicate, timeout_s: float, interval_s: float = 0.05, what: str = "condition"):
    """Poll ``predicate`` until it returns a truthy value; fail the test with ``what`` on timeout."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval_s)
    pytest.fail(f"timed out after {timeout_s} s waiting for {what}")


def stack_credentials(rendezvous: str | None = None, timeout_s: float = 60.0):
    """The credentials of the stack ``seaway launch`` registered on ``rendezvous`` (default: this
    environment's), waiting for it to register."""
    from seaway.runtime import stacks

    rendezvous = rendezvous or os.environ["SEAWAY_ZENOH_RENDEZVOUS"]
    entry = wait_for(lambda: stacks.lookup(rendezvous), timeout_s, what=f"a stack on {rendezvous}")
    return entry.session_credentials()


def solver_built(kind: str, vessel: str) -> None:
    """The controller's generated solver for ``kind`` on ``vessel`` (the default horizon and
    period), compiled into the cache the stack reads, as on any machine after its first run: a
    machine's first run flies the fallbacks while it is made (tests/system/launch/test_first_start.py
    checks that), which a test of a normal run must not count."""
    from seaway.vessel.model import load_vessel
    from seaway_controller.core import ControllerCore

    ControllerCore(load_vessel(vessel)).prepare((kind,))  # the controller's own way to its solver
