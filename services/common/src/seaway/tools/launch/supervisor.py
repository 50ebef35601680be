"""The process supervisor behind ``seaway launch``: start, watch, restart and stop a profile.

Processes run in sessions of their own, so a Ctrl-C at the terminal reaches only the launcher, which
then stops them in order: SIGINT to each process group in stop order (recorder last), SIGKILL after
the process's ``stop_timeout_s``. Each child also gets ``PR_SET_PDEATHSIG`` = SIGTERM, so that even a
SIGKILLed launcher leaves no orphans behind on Linux.

Every line a process prints goes to ``<run_dir>/logs/<name>.log``; warnings and errors (or everything,
with ``echo_all``) are also shown on the terminal prefixed with the process name.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from seaway.runtime.credentials import ENV_IDENTITY
from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec, start_order, stop_order

_libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
_prctl = _libc.prctl
PR_SET_PDEATHSIG = 1


def _child_setup() -> None:  # runs in the child between fork and exec: keep it minimal
    _prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)


@dataclass
class Supervised:
    spec: ProcessSpec
    argv: list[str]
    state: str = "pending"  # pending, starting, ready, running, backoff, exited, failed, stopped
    popen: subprocess.Popen | None = None
    restarts: int = 0
    last_exit: int | None = None
    started_at: float | None = None
    ready_at: float | None = None
    next_start_at: float | None = None
    history: list[dict] = field(default_factory=list)

    @property
    def pid(self) -> int | None:
        return self.popen.pid if self.popen else None


class Supervisor:
    def __init__(self, procs: list[Supervised], run_dir: Path, env: dict[str, str],
                 backoff: BackoffPolicy, echo: Callable[[str], None], echo_all: bool = False) -> None:
        self.procs = {p.spec.name: p for p in procs}
        self.run_dir = run_dir
        self.logs = run_dir / "logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        self.env = env
        self.backoff = backoff
        self.echo = echo
        self.echo_all = echo_all
        self.alive_services: set[str] = set()
        self._health_cond = threading.Condition()
        self.stopping = False
        self._events: list[dict] = []

    # -- health ---------------------------------------------------------------------------------

    def on_health(self, service: str, alive: bool) -> None:
        """Liveliness callback (from the launcher's Zenoh session)."""
        with self._health_cond:
            (self.alive_services.add if alive else self.alive_services.discard)(service)
            self._health_cond.notify_all()

    def _wait_ready(self, sp: Supervised, stop: threading.Event) -> bool:
        service = sp.spec.service
        deadline = time.monotonic() + sp.spec.ready_timeout_s
        with self._health_cond:
            while service not in self.alive_services:
                if stop.is_set() or sp.popen is None or sp.popen.poll() is not None:
                    return False
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._health_cond.wait(min(remaining, 0.1))
        sp.ready_at = time.monotonic()
        sp.state = "ready"
        return True

    # -- starting -------------------------------------------------------------------------------

    def _pump(self, name: str, stream: IO[bytes], log: IO[bytes]) -> None:
        for raw in iter(stream.readline, b""):
            log.write(raw)
            log.flush()
            line = raw.decode(errors="replace").rstrip()
            if self.echo_all or " WARNING " in line or " ERROR " in line or "Traceback" in line:
                self.echo(f"{name:>13} | {line}")
        stream.close()
        log.close()

    def spawn(self, sp: Supervised) -> None:
        exe = shutil.which(sp.argv[0], path=self.env.get("PATH"))
        if exe is None:
            raise FileNotFoundError(f"process {sp.spec.name!r}: command {sp.argv[0]!r} not found")
        log = open(self.logs / f"{sp.spec.name}.log", "ab")  # noqa: SIM115 - closed by the pump
        log.write(f"--- start {time.strftime('%Y-%m-%dT%H:%M:%S')} {' '.join(sp.argv)}\n".encode())
        # A service is its own identity; another process (a replay) is named by the profile.
        env = {**self.env, **sp.spec.env, "PYTHONUNBUFFERED": "1", ENV_IDENTITY: sp.spec.identity}
        sp.popen = subprocess.Popen([exe, *sp.argv[1:]], stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, env=env, start_new_session=True,
                                    preexec_fn=_child_setup)
        sp.started_at = time.monotonic()
        sp.ready_at = None
        sp.state = "starting" if sp.spec.service else "running"
        threading.Thread(target=self._pump, args=(sp.spec.name, sp.popen.stdout, log),
                         daemon=True).start()
        self._event(sp, "start", pid=sp.popen.pid)

    def start_all(self, stop: threading.Event) -> str | None:
        """Start in order, waiting for each one's readiness. Returns an error text, or None."""
        for spec in start_order([p.spec for p in self.procs.values()]):
            sp = self.procs[spec.name]
            try:
                self.spawn(sp)
            except FileNotFoundError as err:
                sp.state = "failed"
                if spec.required:
                    return str(err)
                self.echo(f"launcher: {err}; optional, continuing without it")
                continue
            if spec.service and not self._wait_ready(sp, stop):
                if stop.is_set():
                    return "stopped while starting"
                why = (f"exited with code {sp.popen.poll()}" if sp.popen and sp.popen.poll() is not None
                       else f"not ready within {spec.ready_timeout_s:g} s")
                tail = self.log_tail(spec.name)
                return f"process {spec.name!r} {why}; last log lines:\n{tail}"
        return None

    # -- watching -------------------------------------------------------------------------------

    def poll(self) -> None:
        """Notice exits; restart per policy after back-off. Call this a few times a second."""
        now = time.monotonic()
        for sp in self.procs.values():
            if sp.state == "backoff" and sp.next_start_at is not None and now >= sp.next_start_at:
                sp.restarts += 1
                try:
                    self.spawn(sp)
                except FileNotFoundError as err:
                    sp.state = "failed"
                    self.echo(f"launcher: {err}")
                continue
            if sp.popen is None or sp.state in ("exited", "failed", "stopped", "backoff"):
                continue
            if sp.state == "starting" and sp.spec.service in self.alive_services:
                sp.state, sp.ready_at = "ready", now
            code = sp.popen.poll()
            if code is None:
                continue
            sp.last_exit = code
            self._event(sp, "exit", code=code)
            if self.stopping:
                sp.state = "stopped"
            elif code != 0 and sp.spec.restart == "on-failure" and sp.restarts < self.backoff.max_restarts:
                delay = self.backoff.delay_s(sp.restarts)
                sp.state, sp.next_start_at = "backoff", now + delay
                self.echo(f"launcher: {sp.spec.name} exited with code {code}; restarting in {delay:.1f} s "
                          f"(restart {sp.restarts + 1} of at most {self.backoff.max_restarts})")
            else:
                sp.state = "exited" if code == 0 else "failed"
                self.echo(f"launcher: {sp.spec.name} {sp.state} (code {code})")

    def failed_required(self) -> list[str]:
        return [n for n, sp in self.procs.items() if sp.spec.required and sp.state == "failed"]

    # -- stopping -------------------------------------------------------------------------------

    def stop_all(self) -> None:
        """SIGINT each process group in stop order; SIGKILL what is still alive after its timeout."""
        self.stopping = True
        for spec in stop_order([p.spec for p in self.procs.values()]):
            sp = self.procs[spec.name]
            if sp.popen is None or sp.popen.poll() is not None:
                if sp.state == "backoff":
                    sp.state = "stopped"
                continue
            _signal_group(sp.popen, signal.SIGINT)
            try:
                sp.popen.wait(spec.stop_timeout_s)
            except subprocess.TimeoutExpired:
                self.echo(f"launcher: {spec.name} ignored SIGINT for {spec.stop_timeout_s:g} s; SIGKILL")
                _signal_group(sp.popen, signal.SIGKILL)
                sp.popen.wait(5)
            sp.last_exit = sp.popen.returncode
            sp.state = "stopped"
            self._event(sp, "stopped", code=sp.last_exit)
            # Take the rest of the group too (helpers a process may have started).
            _signal_group(sp.popen, signal.SIGKILL)

    # -- reporting ------------------------------------------------------------------------------

    def status_table(self) -> str:
        rows = [("process", "state", "pid", "restarts", "last exit", "up")]
        now = time.monotonic()
        for sp in self.procs.values():
            up = f"{now - sp.started_at:.0f} s" if sp.started_at and sp.state in ("ready", "running",
                                                                                   "starting") else ""
            rows.append((sp.spec.name, sp.state, str(sp.pid or ""), str(sp.restarts),
                         "" if sp.last_exit is None else str(sp.last_exit), up))
        widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip()
                         for r in rows)

    def log_tail(self, name: str, n: int = 12) -> str:
        path = self.logs / f"{name}.log"
        lines = path.read_text(errors="replace").splitlines() if path.exists() else []
        return "\n".join(f"    {line}" for line in lines[-n:]) or "    (no output)"

    def _event(self, sp: Supervised, what: str, **kw: object) -> None:
        ev = {"t_unix_s": time.time(), "process": sp.spec.name, "event": what, **kw}
        sp.history.append(ev)
        self._events.append(ev)
        with open(self.run_dir / "events.jsonl", "a") as f:
            f.write(json.dumps(ev) + "\n")


def _signal_group(p: subprocess.Popen, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(p.pid, sig)


def default_echo(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
