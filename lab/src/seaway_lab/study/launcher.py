"""One ``seaway launch`` as the study starts it: its command and the options it has, its output
read line by line for the phases of a run (``LauncherLog``, ``_phases``), and the launchers this
process started, stopped all at once on Ctrl-C (``_spawn``, ``stop_all``)."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from seaway.simkit.scenario import load_mission

from seaway_lab.study.definitions import RunSpec
from seaway_lab.study.isolation import stack_env

PROFILE = "sim-batch"
OPTIONAL_FLAGS = ("--no-report",)
"""Launcher flags passed when the launcher has them: its own final report (with plots) is work the
study does not use, since it reads each recording itself."""

DEFAULT_TIMEOUT_S = 300.0
"""Wall time one run may take before its launcher is stopped (start-up, mission, stop, report): the
longest run of the studies (T^w = 0.25 W, ~500 s simulated) takes well under a minute; a mission
that never completes records ~0.7 MB per wall second."""

# The launcher's lines that mark the phases of a run (seaway.tools.launch.main).
_MILESTONES: dict[str, re.Pattern[str]] = {
    "ready": re.compile(r"^all ready in ([0-9.]+) s"),
    "accepted": re.compile(r"^mission .*\baccepted\b"),
    "refused": re.compile(r"^mission .*\bREFUSED\b"),
    "complete": re.compile(r"^mission complete"),
    "stopping": re.compile(r"^stopping\.\.\."),
    "stopped": re.compile(r"^stopped in ([0-9.]+) s"),
}


# -- the launcher's options -----------------------------------------------------------------------

def seaway_command() -> list[str]:
    """The ``seaway`` command of this installation (next to this interpreter)."""
    exe = shutil.which("seaway", path=str(Path(sys.executable).parent))
    return [exe] if exe else [sys.executable, "-m", "seaway.tools.cli"]


_help_lock = threading.Lock()
_launch_options: set[str] | None = None


def launcher_options() -> set[str]:
    """The options ``seaway launch`` accepts (from its ``--help``), asked once per process."""
    global _launch_options
    with _help_lock:
        if _launch_options is None:
            out = subprocess.run([*seaway_command(), "launch", "--help"], capture_output=True, text=True,
                                 timeout=60, check=False).stdout
            _launch_options = set(re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*)", out))
        return _launch_options


def fit_options(spec: RunSpec, supported: set[str]) -> list[str]:
    """The run's launcher options, less those the launcher lacks where they change nothing.

    An option the launcher does not have is left out only when the run asks for what the scenario
    flies anyway (``--controller`` naming the scenario's own); otherwise ValueError, naming it.
    """
    opts = spec.launch_options()
    out: list[str] = []
    i = 0
    while i < len(opts):
        opt = opts[i]
        takes_value = i + 1 < len(opts) and not opts[i + 1].startswith("--")
        value = opts[i + 1] if takes_value else None
        i += 2 if takes_value else 1
        if opt in supported:
            out += [opt] if value is None else [opt, value]
        elif opt == "--controller" and value == load_mission(spec.scenario).controller:
            continue
        else:
            raise ValueError(f"seaway launch has no {opt} option, which run {spec.key} needs")
    return out


# -- its output -----------------------------------------------------------------------------------

class LauncherLog:
    """A launcher's output, read on a thread of its own: kept in ``path`` (each line after the
    seconds since ``t0``) and in ``lines``, with when each milestone (``_MILESTONES``) was first seen
    (``seen``, seconds since ``t0``)."""

    def __init__(self, stream: Iterable[str], path: Path, t0: float) -> None:
        self.t0 = t0
        self.lines: list[str] = []
        self.seen: dict[str, float] = {}
        self.ready_reported_s: float | None = None
        self._ended = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, args=(stream, path), name="launch-log",
                                        daemon=True)
        self._thread.start()

    def _read(self, stream: Iterable[str], path: Path) -> None:
        try:
            with open(path, "w", buffering=1) as log:
                for line in stream:
                    now = time.monotonic() - self.t0
                    log.write(f"{now:8.3f} {line}")
                    with self._cond:
                        self.lines.append(line.rstrip())
                        for name, pat in _MILESTONES.items():
                            m = pat.search(line.strip())
                            if m and name not in self.seen:
                                self.seen[name] = now
                                if name == "ready":
                                    self.ready_reported_s = float(m.group(1))
                        self._cond.notify_all()
        finally:
            with self._cond:
                self._ended = True
                self._cond.notify_all()

    def wait(self, names: Iterable[str], timeout_s: float | None = None) -> str | None:
        """The first of ``names`` seen (in their order), waiting up to ``timeout_s`` (None: until
        the output ends); None if it ended or the time ran out without one."""
        names = list(names)
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._cond:
            while True:
                hit = next((n for n in names if n in self.seen), None)
                if hit is not None or self._ended:
                    return hit
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    return None
                self._cond.wait(left)

    @property
    def ended(self) -> bool:
        """Whether the output ended (the launcher closed it: it exited)."""
        with self._cond:
            return self._ended

    def line_with(self, text: str) -> str:
        with self._cond:
            return next((x for x in self.lines if text in x), "")

    def tail(self, n: int = 20) -> str:
        with self._cond:
            return "\n".join(self.lines[-n:])

    def join(self, timeout_s: float | None = None) -> None:
        self._thread.join(timeout_s)


def _phases(seen: dict[str, float], t_exit: float) -> dict[str, float]:
    ph: dict[str, float] = {}
    if "ready" in seen:
        ph["startup_s"] = seen["ready"]
        if "complete" in seen:
            ph["mission_s"] = seen["complete"] - seen["ready"]
    if "stopping" in seen and "stopped" in seen:
        ph["stop_s"] = seen["stopped"] - seen["stopping"]
    if "stopped" in seen:
        ph["launcher_report_s"] = t_exit - seen["stopped"]
    ph["launch_s"] = t_exit
    return ph


# -- the launchers running ------------------------------------------------------------------------

def _stop_group(p: subprocess.Popen[str], grace_s: float = 15.0) -> None:
    """SIGINT to the launcher's process group (it stops its services), SIGKILL if it lingers.

    The services run in sessions of their own, so a launcher killed outright would leave them: they
    are looked up first and killed with it.
    """
    import psutil

    try:
        children = psutil.Process(p.pid).children(recursive=True)
    except psutil.Error:
        children = []
    with contextlib.suppress(ProcessLookupError):
        os.killpg(p.pid, signal.SIGINT)
    try:
        p.wait(grace_s)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    for c in children:
        with contextlib.suppress(psutil.Error):
            c.kill()


_running_lock = threading.Lock()
_running: set[subprocess.Popen[str]] = set()
"""The launchers this process has started and not yet seen exit (``stop_all`` on Ctrl-C)."""
_stopping = threading.Event()
"""Set by ``stop_all``: no launcher is started after it (a worker that took a run just before)."""


class StudyStoppingError(RuntimeError):
    """A launcher asked for after ``stop_all``: the study is being stopped."""


def stop_all() -> None:
    """Stop every launcher this process started that is still running (each stops its services),
    and start no more."""
    with _running_lock:
        _stopping.set()
        running = list(_running)
    threads = [threading.Thread(target=_stop_group, args=(p,), daemon=True) for p in running]
    for t in threads:
        t.start()
    for t in threads:
        t.join()


def _spawn(command: list[str], port: int | None, *, stdin: Any = subprocess.DEVNULL,
           stderr: Any = subprocess.STDOUT) -> subprocess.Popen[str]:
    """A launcher on its own rendezvous ``port`` (None: a composed one, which has no network), or
    a study worker (``worker``), in a session of its own, its output piped (its errors with it,
    unless ``stderr`` says where)."""
    with _running_lock:
        if _stopping.is_set():
            raise StudyStoppingError("the study is stopping: no more stacks are started")
        env = stack_env(port) if port is not None else {**os.environ, "PYTHONUNBUFFERED": "1"}
        p = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=stderr, stdin=stdin,
                             text=True, start_new_session=True)
        _running.add(p)
    return p
