"""The process supervisor behind ``seaway launch``: start, watch, restart and stop a profile.

Processes run in sessions of their own, so a Ctrl-C at the terminal reaches only the launcher, which
then stops them in order: SIGINT to each process group in stop order (recorder last; SIGTERM to one
still starting, ``stop_signal``), SIGKILL after the process's ``stop_timeout_s``. A second Ctrl-C
(``hurry``) shortens that grace to ``HURRY_GRACE_S`` for every process but the recorder, which keeps
its own to finish the recording: the stop stays in order and the file stays whole. Each child also
gets ``PR_SET_PDEATHSIG`` = SIGTERM, so that even a SIGKILLed launcher leaves no orphans behind on
Linux: set by util-linux's ``setpriv --pdeathsig`` before it execs the command, not by Python code
between fork and exec (``preexec_fn``), which in a process with Zenoh's threads could deadlock the
child before its exec and the launcher with it (a process that never starts).

A process that exits with a failure is restarted after its back-off (``restart = "on-failure"``),
and so is a service that exits with 0 unasked (``seaway.tools.launch.exits``).
So is one that hangs (``liveness``): its health token gone for ``TOKEN_GRACE_S`` while it still
runs, overdue on what its service must publish, or restarted and not ready within its
``ready_timeout_s``; it is SIGKILLed (a stopped or deadlocked process
cannot stop itself) and then restarted as a dead one. Each start, exit, hang and stop is a line of
``<run_dir>/events.jsonl``, which the recorder puts into the recording (``seaway-recorder --events``).

Every line a process prints goes to ``<run_dir>/logs/<name>.log``; warnings and errors (or everything,
with ``echo_all``) are also shown on the terminal prefixed with the process name.

Each process runs for one vessel (``Supervised.vessel``; a fleet's, ``profile.instances``): its
readiness is that vessel's health token of its service, and what it must publish is heard on that
vessel's keys, so the same service on two vessels is watched twice, apart. A copy of a per-vessel
process in a fleet also has its events written to its vessel's folder (``vessel_dir``), which that
vessel's recorder copies into its recording.
"""

from __future__ import annotations

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

from seaway.contract import keys
from seaway.runtime import cpus, host
from seaway.runtime.bus import Bus
from seaway.runtime.bus_typed import RawRing
from seaway.runtime.credentials import ENV_IDENTITY
from seaway.runtime.service import ENV_VESSEL
from seaway.tools.launch import exits
from seaway.tools.launch.events import EVENTS_FILE, EventsFiles, ProcessEvent
from seaway.tools.launch.liveness import CHAIN_RANK, TOKEN_GRACE_S, Watch, answer_period
from seaway.tools.launch.logsink import LogSink
from seaway.tools.launch.profile import BackoffPolicy, ProcessSpec, start_order, stop_order
from seaway.tools.launch.signals import SETPRIV, signal_group, stop_signal, with_parent_death_signal

WATCH_RING = 4096
"""Samples held per watched key between two looks (``poll``, a few times a second): some 15 s of
lockstep answers at 300 periods a second; past that the oldest go (a launcher busy that long)."""
HURRY_GRACE_S = 0.5
"""After a second Ctrl-C: how long a process (but the recorder) gets between SIGINT and SIGKILL."""

@dataclass
class Supervised:
    spec: ProcessSpec
    argv: list[str]
    vessel: str
    """The vessel it runs for: its health token is ``seaway/<vessel>/health/<service>``."""
    vessel_dir: Path | None = None
    """A fleet's per-vessel copy: its vessel's folder, where its events are written too."""
    state: str = "pending"  # pending, starting, ready, running, hung, backoff, exited, failed, stopped
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
                 backoff: BackoffPolicy, echo: Callable[[str], None], echo_all: bool = False,
                 clock: str = "wall", placement: dict[str, frozenset[int]] | None = None,
                 finishes: frozenset[str] = frozenset()) -> None:
        self.procs = {p.spec.name: p for p in procs}
        self.finishes = finishes
        """The processes whose exit with code 0 is a finish (the profile's ``stop_after``); any
        other service's is unasked and handled as a failure (``seaway.tools.launch.exits``)."""
        self.placement = placement or {}
        """CPUs of the processes of a service (``seaway.runtime.cpus.split_chain``); a process of a
        service not named keeps the launcher's."""
        self.run_dir = run_dir
        self.logs = run_dir / "logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        self.env = env
        self.backoff = backoff
        self.echo = echo
        self.echo_all = echo_all
        self.vessels = {sp.vessel for sp in procs}
        self.alive_services: set[tuple[str, str]] = set()
        """(vessel, service) of every health token present, on the launch's vessels."""
        self._health_cond = threading.Condition()
        self.stopping = False
        self.hurried = 0  # Ctrl-Cs after the first: the stop's grace is short (HURRY_GRACE_S)
        self._hurry_noted = 0
        self._events: list[dict] = []
        self.events_out = EventsFiles(lambda line: self.echo(f"launcher: {line}"))
        # Hang detection (liveness): the duties of each process under the run's clock, what the
        # launcher hears of them, and since when each service's token has been missing.
        self.duties = {name: sp.spec.duties(clock) for name, sp in self.procs.items()}
        self.watches = {v: Watch() for v in self.vessels}
        """One per vessel: what a process must publish is heard on its own vessel's keys."""
        self._watch_lock = threading.Lock()
        self._token_lost: dict[tuple[str, str], float] = {}
        self._own_link_noted = False
        self._rings: list[tuple[str, str, RawRing]] = []  # (vessel, suffix, ring): watch_on

    # -- health ---------------------------------------------------------------------------------

    def on_health(self, vessel: str, service: str, alive: bool) -> None:
        """Liveliness callback (from the launcher's Zenoh session, every vessel's tokens): those of
        the launch's vessels count."""
        if vessel not in self.vessels:
            return
        token = (vessel, service)
        with self._health_cond:
            (self.alive_services.add if alive else self.alive_services.discard)(token)
            if alive:
                self._token_lost.pop(token, None)
            else:
                self._token_lost.setdefault(token, time.monotonic())
            self._health_cond.notify_all()

    def watched_keys(self) -> set[tuple[str, str]]:
        """(vessel, key suffix) the launcher must hear to watch every process's duties."""
        return {(sp.vessel, k) for name, sp in self.procs.items()
                for k in Watch.keys_of(self.duties[name])}

    def watch_on(self, bus: Bus) -> None:
        """Hear every watched key (``watched_keys``) through a ring the transport fills on its own
        threads (``Bus.ring_raw``): no Python runs per sample, hundreds a second in lockstep; what
        was heard is taken at each ``poll``."""
        self._rings = []
        for vessel, suffix in sorted(self.watched_keys()):
            spec = keys.spec_for_suffix(suffix)
            assert spec is not None  # a duty names registered topics (liveness.Duty)
            self._rings.append((vessel, suffix, bus.ring_raw(spec.key(vessel), WATCH_RING)))

    def take_heard(self, now: float) -> int:
        """Give the watches what the rings hold (as heard ``now``); how many samples.

        Taken key by key, they are fed in the order they were published in: by period, and in a
        period along the lockstep chain (sim, estimator, controller, recorder), so each answer
        comes after the one that asked for it, as the watch expects."""
        heard: list[tuple[str, tuple[int, int], int, str, bool]] = []
        no_period = (-1, -1)
        for vessel, suffix, ring in self._rings:
            rank = CHAIN_RANK.get(suffix, -1)
            while (item := ring.take_carried()) is not None:
                period, hold = answer_period(*item) if rank >= 0 else (no_period, False)
                if period is not None:
                    heard.append((vessel, period, rank, suffix, hold))
        heard.sort(key=lambda h: (h[0], h[1], h[2]))
        with self._watch_lock:
            for vessel, period, rank, suffix, hold in heard:
                self.watches[vessel].heard(suffix, now, None if rank < 0 else period, hold)
        return len(heard)

    def _mark_ready(self, sp: Supervised, now: float) -> None:
        sp.state, sp.ready_at = "ready", now
        with self._watch_lock:
            self.watches[sp.vessel].arm(sp.spec.name, self.duties[sp.spec.name], now)

    def _wait_any_ready(self, starting: list[Supervised], stop: threading.Event) -> str | None:
        """Block until at least one of ``starting`` is ready (its health token is up), mark those and
        take them out of ``starting``; an error text if one exited or passed its ``ready_timeout_s``
        (from its own spawn) first, or the launch was stopped."""
        with self._health_cond:
            while True:
                now = time.monotonic()
                up = [sp for sp in starting if (sp.vessel, sp.spec.service) in self.alive_services]
                if up:
                    break
                if stop.is_set():
                    return "stopped while starting"
                for sp in starting:
                    code = sp.popen.poll() if sp.popen is not None else None
                    if sp.popen is None or code is not None:
                        return self._start_failure(sp, f"exited with code {code}")
                    if now - sp.started_at >= sp.spec.ready_timeout_s:
                        return self._start_failure(sp, f"not ready within {sp.spec.ready_timeout_s:g} s")
                self._health_cond.wait(0.1)
        for sp in up:
            starting.remove(sp)
            self._mark_ready(sp, time.monotonic())
        return None

    def _start_failure(self, sp: Supervised, why: str) -> str:
        return f"process {sp.spec.name!r} {why}; last log lines:\n{self.log_tail(sp.spec.name)}"

    # -- starting -------------------------------------------------------------------------------

    def _pump(self, name: str, stream: IO[bytes], log: LogSink) -> None:
        # Reads on whatever happens to the log (``LogSink.write`` never raises): a process whose
        # output is not read blocks once its pipe is full.
        for raw in iter(stream.readline, b""):
            log.write(raw)
            line = raw.decode(errors="replace").rstrip()
            if self.echo_all or " WARNING " in line or " ERROR " in line or "Traceback" in line:
                self.echo(f"{name:>13} | {line}")
        stream.close()
        log.close()

    def spawn(self, sp: Supervised) -> None:
        composed = host.active()
        if composed is not None:  # a node of this process (seaway.runtime.host), not a process
            log = self._log_sink(sp.spec.name)  # closed by the pump
            log.write(f"--- start {time.strftime('%Y-%m-%dT%H:%M:%S')} (node of this process) "
                      f"{' '.join(sp.argv)}\n".encode())
            sp.popen = composed.start(sp.spec.name, sp.argv)  # type: ignore[assignment]
            self._started(sp, log)
            return
        exe = shutil.which(sp.argv[0], path=self.env.get("PATH"))
        if exe is None:
            raise FileNotFoundError(f"process {sp.spec.name!r}: command {sp.argv[0]!r} not found")
        log = self._log_sink(sp.spec.name)  # closed by the pump
        log.write(f"--- start {time.strftime('%Y-%m-%dT%H:%M:%S')} {' '.join(sp.argv)}\n".encode())
        # A service is its own identity; another process (a replay) is named by the profile.
        env = {**self.env, ENV_VESSEL: sp.vessel, **sp.spec.env, "PYTHONUNBUFFERED": "1",
               ENV_IDENTITY: sp.spec.identity}
        sp.popen = subprocess.Popen(with_parent_death_signal([exe, *sp.argv[1:]]),
                                    stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env,
                                    start_new_session=True)
        where = self.placement.get(sp.spec.service or "")
        if where is not None:  # now, while it has one thread: the ones it starts inherit the set
            try:
                cpus.pin_threads(sp.popen.pid, where)
            except OSError as err:
                self.echo(f"launcher: {sp.spec.name} left on the launcher's CPUs: {err}")
        self._started(sp, log)

    def _log_sink(self, name: str) -> LogSink:
        return LogSink(self.logs / f"{name}.log", trouble=lambda line: self.echo(f"launcher: {line}"))

    def _started(self, sp: Supervised, log: LogSink) -> None:
        """What follows a start, process or node: its state, its output pumped to its log."""
        assert sp.popen is not None and sp.popen.stdout is not None
        sp.started_at = time.monotonic()
        sp.ready_at = None
        sp.state = "starting" if sp.spec.service else "running"
        with self._watch_lock:
            self.watches[sp.vessel].disarm(sp.spec.name)
        threading.Thread(target=self._pump, args=(sp.spec.name, sp.popen.stdout, log),
                         daemon=True).start()
        self._event(sp, "start", pid=sp.popen.pid)

    def start_all(self, stop: threading.Event) -> str | None:
        """Start each process once every process it names in ``after`` is ready: those with nothing
        between them start together, so a profile starts in the time of its longest ``after`` chain,
        not the sum of its processes' start-ups (each is seconds of imports and a session). Returns
        an error text, or None."""
        if SETPRIV is None:
            self.echo("launcher: util-linux's setpriv is not installed: a launcher killed with "
                      "SIGKILL leaves its processes running (apt install util-linux)")
        pending = start_order([p.spec for p in self.procs.values()])
        ready: set[str] = set()  # ready, running (no health token to wait for), or optional and absent
        starting: list[Supervised] = []
        while pending or starting:
            for spec in [s for s in pending if ready.issuperset(s.after)]:
                pending.remove(spec)
                sp = self.procs[spec.name]
                try:
                    self.spawn(sp)
                except FileNotFoundError as err:
                    sp.state = "failed"
                    if spec.required:
                        return str(err)
                    self.echo(f"launcher: {err}; optional, continuing without it")
                    ready.add(spec.name)
                    continue
                if spec.service:
                    starting.append(sp)
                else:
                    ready.add(spec.name)
            if starting:
                before = {sp.spec.name for sp in starting}
                error = self._wait_any_ready(starting, stop)
                if error:
                    return error
                ready |= before - {sp.spec.name for sp in starting}
        return None

    # -- watching -------------------------------------------------------------------------------

    def poll(self) -> None:
        """Notice exits; restart per policy after back-off. Call this a few times a second."""
        now = time.monotonic()
        # What the watched keys carried since the last look, before any exit is noticed: a dead
        # process's last answers count for it, not for the one that replaces it.
        self.take_heard(now)
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
            if sp.state == "starting" and (sp.vessel, sp.spec.service) in self.alive_services:
                self._mark_ready(sp, now)
            code = sp.popen.poll()
            if code is None:
                continue
            sp.last_exit = code
            with self._watch_lock:
                self.watches[sp.vessel].disarm(sp.spec.name)
            self._event(sp, "exit", code=code)
            if self.stopping:
                sp.state = "stopped"
                continue
            # A failure, or a service's exit with 0 nobody asked for, is restarted (exits module).
            then = exits.after_exit(sp.spec, code, sp.restarts, self.backoff, self.finishes)
            sp.state = then.state
            if then.delay_s is not None:
                sp.next_start_at = now + then.delay_s
            self.echo(then.line)

        if not self.stopping:
            self._check_hung(now)

    def hung(self, now: float) -> dict[str, str]:
        """Running processes that hang, each with the reason (see the module docstring)."""
        out: dict[str, str] = {}
        ready = [sp for sp in self.procs.values() if sp.state in ("ready", "running")
                 and sp.popen is not None and sp.popen.poll() is None]
        with self._health_cond:
            lost = dict(self._token_lost)
            any_alive = bool(self.alive_services)
        watched = [sp for sp in ready if sp.spec.service]
        # A restarted service that never becomes ready (stuck in its start-up, or unable to link:
        # credentials the stack no longer accepts) was left "starting" for good, and the run went
        # on without it, unsaid. The start's own wait (``_wait_any_ready``) covers the first start.
        for sp in self.procs.values():
            if (sp.state == "starting" and sp.spec.service and sp.popen is not None
                    and sp.started_at is not None and sp.popen.poll() is None
                    and now - sp.started_at > sp.spec.ready_timeout_s):
                out[sp.spec.name] = (f"not ready {now - sp.started_at:.1f} s after its start "
                                     f"(ready_timeout_s {sp.spec.ready_timeout_s:g})")
        # Every token gone at once is this launcher losing sight of the stack, not them all hanging.
        if any_alive or len(watched) < 2:
            for sp in watched:
                since = lost.get((sp.vessel, sp.spec.service))  # type: ignore[arg-type]
                if since is not None and sp.ready_at is not None and now - since > TOKEN_GRACE_S:
                    out[sp.spec.name] = (f"its health token has been gone for {now - since:.1f} s "
                                         "while the process still runs")
        with self._watch_lock:
            overdue = {n: why for w in self.watches.values() for n, why in w.overdue(now).items()}
            late = {n: why for n, why in overdue.items() if n in {sp.spec.name for sp in ready}}
            armed = sum(1 for sp in ready if self.watches[sp.vessel].armed(sp.spec.name)
                        and self.duties[sp.spec.name])
        if len(late) >= 2 and 2 * len(late) > armed:
            # Most of the stack silent at once: more likely this launcher's own view than them all.
            if not self._own_link_noted:
                self.echo(f"launcher: hearing nothing from {', '.join(sorted(late))} at once; "
                          "not restarting them (is the launcher's own link down?)")
                self._own_link_noted = True
            late = {}
        else:
            self._own_link_noted = False
        return {**late, **out}

    def _check_hung(self, now: float) -> None:
        for name, reason in self.hung(now).items():
            sp = self.procs[name]
            self._event(sp, "hung", reason=reason)
            self.echo(f"launcher: {name} is hung: {reason}; SIGKILL, then a restart as for a "
                      "dead process")
            with self._watch_lock:
                self.watches[sp.vessel].disarm(name)
            with self._health_cond:
                if sp.spec.service:
                    self._token_lost.pop((sp.vessel, sp.spec.service), None)
            sp.state = "hung"
            assert sp.popen is not None
            signal_group(sp.popen, signal.SIGKILL)

    def failed_required(self) -> list[str]:
        return [n for n, sp in self.procs.items() if sp.spec.required and sp.state == "failed"]

    def failed_optional(self) -> list[str]:
        """The processes the profile does not require that failed for good: the run went on
        without them."""
        return [n for n, sp in self.procs.items() if not sp.spec.required and sp.state == "failed"]

    def failed_optional_by_vessel(self) -> dict[str, list[str]]:
        """``failed_optional`` per vessel, each by its service's name (else its own)."""
        out: dict[str, list[str]] = {}
        for name in self.failed_optional():
            sp = self.procs[name]
            out.setdefault(sp.vessel, []).append(sp.spec.service or name)
        return out

    # -- stopping -------------------------------------------------------------------------------

    def hurry(self) -> None:
        """Shorten the stop: every process but the recorder gets ``HURRY_GRACE_S`` (a second
        Ctrl-C); the order stays, and the recorder keeps its grace to finish its file. Safe in a
        signal handler (it only counts; ``note_hurry`` says so later, from the stopping thread)."""
        self.hurried += 1

    def note_hurry(self) -> None:
        """Say, once per Ctrl-C, that the stop was hurried."""
        if self.hurried > self._hurry_noted:
            self._hurry_noted = self.hurried
            self.echo(f"launcher: Ctrl-C again: stopping faster (each process gets "
                      f"{HURRY_GRACE_S:g} s before SIGKILL; the recorder still finishes its file)")

    def grace_s(self, spec: ProcessSpec) -> float:
        """How long ``spec``'s process gets between SIGINT and SIGKILL, now."""
        if self.hurried and spec.service != "recorder":
            return min(spec.stop_timeout_s, HURRY_GRACE_S)
        return spec.stop_timeout_s

    def _wait_stopped(self, sp: Supervised) -> bool:
        """Wait for ``sp`` to exit within its grace (which a Ctrl-C meanwhile may shorten)."""
        assert sp.popen is not None
        t0 = time.monotonic()
        while sp.popen.poll() is None:
            self.note_hurry()
            if time.monotonic() - t0 >= self.grace_s(sp.spec):
                return False
            time.sleep(0.02)
        return True

    def stop_all(self) -> None:
        """Signal each process group in stop order (``stop_signal``); SIGKILL what is still alive
        after its grace."""
        self.stopping = True
        for spec in stop_order([p.spec for p in self.procs.values()]):
            sp = self.procs[spec.name]
            if sp.popen is None or sp.popen.poll() is not None:
                if sp.state == "backoff":
                    sp.state = "stopped"
                continue
            sig = stop_signal(sp.state)
            signal_group(sp.popen, sig)
            if not self._wait_stopped(sp):
                self.echo(f"launcher: {spec.name} ignored {sig.name} for {self.grace_s(spec):g} s; "
                          f"SIGKILL")
                signal_group(sp.popen, signal.SIGKILL)
                sp.popen.wait(5)
            sp.last_exit = sp.popen.returncode
            sp.state = "stopped"
            self._event(sp, "stopped", code=sp.last_exit)
            # Take the rest of the group too (helpers a process may have started).
            signal_group(sp.popen, signal.SIGKILL)

    # -- reporting ------------------------------------------------------------------------------

    def status_table(self) -> str:
        rows = [("process", "state", "pid", "restarts", "last exit", "up")]
        now = time.monotonic()
        for sp in self.procs.values():
            up = f"{now - sp.started_at:.0f} s" if sp.started_at and sp.state in (
                "ready", "running", "starting", "hung") else ""
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
        ev = ProcessEvent(t_unix_s=time.time(), process=sp.spec.name, event=what, **kw)  # type: ignore[arg-type]
        data = ev.model_dump(exclude_defaults=True)
        sp.history.append(data)
        self._events.append(data)
        for folder in (self.run_dir, sp.vessel_dir):
            if folder is not None:
                self.events_out.append(folder / EVENTS_FILE, ev.line())


def default_echo(line: str) -> None:
    sys.stderr.write(line + "\n")
    sys.stderr.flush()
