"""A study worker: a process of its own per composed stack, and the study's handle on it.

``python -m seaway_lab.study.worker --folder DIR`` makes its process a host (``seaway.runtime.host``)
and flies the runs it is given on one ``composed.ComposedStack`` in ``DIR``. It talks JSON lines:
it reads ``{"fly": <RunSpec.to_json()>}`` and ``{"close": true}`` on stdin and answers each on
stdout, ``{"flown": <RunOutcome.to_json(with_series=True)>}`` and ``{"closed": [<outcome>, ...]}``
(the stack stopped and every run reported from one decode of its recording), after a first
``{"ready": PID}``; then it exits. Anything else it prints, and its log, goes to stderr
(``DIR/worker.log``). SIGINT or SIGTERM stops its stack and ends it; so do the end of stdin and
the end of the study that started it.

``WorkerStack`` is that process seen from the study: ``SharedStack``'s face (``fly``, ``close``,
``widen``), so ``execute.run_shared`` runs composed stacks as it runs shared stacks of processes.
Why a process per stack: a host is one process with one GIL, and stacks flying side by side are
CPU-bound Python each; the study's own process only hands out runs.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, TextIO

from seaway.runtime import cpus as cpusets

from seaway_lab.study.definitions import RunSpec
from seaway_lab.study.launcher import DEFAULT_TIMEOUT_S, _running, _running_lock, _spawn, _stop_group
from seaway_lab.study.outcome import RunOutcome, _concluded

WORKER_LOG = "worker.log"
"""The worker's own output in its stack's folder (the launcher's is ``launch.log``)."""
REPLY_MARGIN_S = 60.0
"""How much longer than a run's own limit the study waits for the worker's answer [s]: the worker
times its runs out itself; this is for a worker that hangs (a node holding the GIL)."""
CLOSE_TIMEOUT_S = 600.0
"""How long the stop of a stack and the report of its runs may take [s]."""
EXIT_GRACE_S = 10.0
"""How long a worker that answered ``close`` may take to exit before it is stopped [s]."""


class WorkerError(RuntimeError):
    """The worker died, hung, or said something out of turn; the text says which."""


class WorkerStack:
    """A composed stack flown by a study worker process of its own, in ``folder``, on ``cpus``
    (the worker's whole process; None: wherever the kernel puts it)."""

    def __init__(self, folder: Path, timeout_s: float = DEFAULT_TIMEOUT_S,
                 cpus: frozenset[int] | None = None) -> None:
        self.folder = Path(folder)
        self.timeout_s = timeout_s
        self.cpus = cpus
        self._cpus_lock = threading.Lock()  # a widen waits for a start that read ``cpus``
        self.proc: subprocess.Popen[str] | None = None
        self._replies: queue.SimpleQueue[str | None] = queue.SimpleQueue()
        self._log: TextIO | None = None
        self._ended = False
        self._boot: tuple[str, float] = ("", 0.0)
        """The first run's key, and the seconds the worker took to start before it."""
        self.flown: list[RunSpec] = []
        """Runs the worker flew to their end, not yet reported."""

    # -- the study's side -------------------------------------------------------------------------

    def fly(self, spec: RunSpec) -> RunOutcome:
        """Fly ``spec`` in the worker (starting it for the first run). Never raises: a failed run's
        outcome says why, and leaves the stack stopped (``close`` reports the runs before it)."""
        t0 = time.monotonic()
        try:
            if self._ended:
                raise WorkerError("the stack was stopped")
            if self.proc is None:
                self._boot = (spec.key, self._start())
            out = self._booted(RunOutcome.from_json(self._ask({"fly": spec.to_json()}, "flown",
                                                              self.timeout_s + REPLY_MARGIN_S), spec))
        except WorkerError as err:
            out = RunOutcome(spec, str(self.folder), error=str(err))
            out.timing["flight_s"] = time.monotonic() - t0
            self._end()
            out.timing["wall_s"] = time.monotonic() - t0
            return out
        if not out.error:
            self.flown.append(spec)
        return out

    def close(self) -> list[RunOutcome]:
        """Stop the stack and report every run it flew (the worker decodes its recording once),
        then end the worker. Never raises: a run that cannot be reported says why."""
        flown, self.flown = self.flown, []
        if self.proc is None:
            return []
        try:
            if self._ended:
                raise WorkerError("the worker had ended")
            outs = [self._booted(RunOutcome.from_json(o))
                    for o in self._ask({"close": True}, "closed", CLOSE_TIMEOUT_S)]
        except WorkerError as err:
            outs = [_concluded(RunOutcome(s, str(self.folder), error=f"report: {err}")) for s in flown]
        self._end()
        return outs

    def widen(self, cpus: frozenset[int]) -> None:
        """Let the worker, every thread of it, use ``cpus`` from now on (a worker not started yet
        starts there). Best effort: a worker that ends meanwhile is skipped."""
        with self._cpus_lock:
            if self.cpus is None or self.cpus == cpus:
                return
            self.cpus = cpus
            if self.proc is not None and self.proc.poll() is None:
                with contextlib.suppress(OSError):
                    cpusets.pin_threads(self.proc.pid, cpus)

    def _booted(self, out: RunOutcome) -> RunOutcome:
        """``out`` with the worker's start (its imports) in its stack's start-up, if it is the
        first run's (the worker timed the rest)."""
        key, boot_s = self._boot
        if out.spec.key == key:
            for k in ("startup_s", "flight_s", "wall_s"):
                if k in out.timing:
                    out.timing[k] += boot_s
        return out

    # -- the process ------------------------------------------------------------------------------

    def _start(self) -> float:
        """Start the worker and wait for it to be ready; the seconds that took."""
        t0 = time.monotonic()
        self.folder.mkdir(parents=True, exist_ok=True)
        self._log = open(self.folder / WORKER_LOG, "w", buffering=1)  # noqa: SIM115 - closed in _end
        with self._cpus_lock:
            command = [sys.executable, "-m", "seaway_lab.study.worker", "--folder", str(self.folder),
                       "--timeout-s", f"{self.timeout_s:g}",
                       *(["--cpus", cpusets.format_cpus(self.cpus)] if self.cpus else [])]
            self.proc = _spawn(command, None, stdin=subprocess.PIPE, stderr=self._log)
        threading.Thread(target=self._read, args=(self.proc.stdout,), name="study-worker-replies",
                         daemon=True).start()
        self._reply("ready", self.timeout_s)
        return time.monotonic() - t0

    def _read(self, stream: TextIO) -> None:
        for line in stream:
            self._replies.put(line)
        self._replies.put(None)

    def _ask(self, message: dict[str, Any], expect: str, timeout_s: float) -> Any:
        assert self.proc is not None and self.proc.stdin is not None
        try:
            self.proc.stdin.write(json.dumps(message) + "\n")
            self.proc.stdin.flush()
        except OSError as err:  # a worker that has died: its pipe is closed
            raise WorkerError(self._ended_text(f"the study worker took no request ({err})")) from None
        return self._reply(expect, timeout_s)

    def _reply(self, expect: str, timeout_s: float) -> Any:
        try:
            line = self._replies.get(timeout=timeout_s)
        except queue.Empty:
            raise WorkerError(self._ended_text(f"the study worker gave no answer within "
                                               f"{timeout_s:g} s")) from None
        if line is None:
            raise WorkerError(self._ended_text("the study worker ended"))
        try:
            reply = json.loads(line)
            return reply[expect]
        except (ValueError, KeyError, TypeError):
            raise WorkerError(self._ended_text(f"the study worker said {line.strip()[:200]!r} where "
                                               f"{expect!r} was due")) from None

    def _ended_text(self, what: str) -> str:
        code = self.proc.poll() if self.proc is not None else None
        tail = ""
        with contextlib.suppress(OSError):
            tail = "\n".join((self.folder / WORKER_LOG).read_text(errors="replace").splitlines()[-20:])
        return what + (f" (exit {code})" if code is not None else "") + (f"\n{tail}" if tail else "")

    def _end(self) -> None:
        """End the worker (it stops its stack first), once; stopped if it lingers."""
        if self._ended or self.proc is None:
            self._ended = True
            return
        self._ended = True
        with contextlib.suppress(OSError):
            assert self.proc.stdin is not None
            self.proc.stdin.close()  # the end of its requests: it stops its stack and exits
        try:
            self.proc.wait(EXIT_GRACE_S)
        except subprocess.TimeoutExpired:
            _stop_group(self.proc)
        with _running_lock:
            _running.discard(self.proc)
        if self._log is not None:
            self._log.close()


# -- the worker's side ----------------------------------------------------------------------------

def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="python -m seaway_lab.study.worker", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--folder", type=Path, required=True, help="the stack's folder (run folder)")
    ap.add_argument("--timeout-s", type=float, default=DEFAULT_TIMEOUT_S,
                    help="wall time limit of one run [s]")
    ap.add_argument("--cpus", type=cpusets.parse_cpus, default=None, metavar="LIST",
                    help="keep this process, every thread of it, on these CPUs")
    return ap


ORPHAN_POLL_S = 1.0
"""How often the worker looks whether the study that started it is still there [s]."""


def _interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt


def _end_when_orphaned() -> None:
    """SIGTERM to this process once its parent, the study, is gone (killed outright, it stopped
    nothing): the stack is stopped as on a Ctrl-C, not left flying on its own."""
    parent = os.getppid()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(ORPHAN_POLL_S)
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=watch, name="study-worker-orphan", daemon=True).start()


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    # The requests' answers on a descriptor of their own; whatever else writes to stdout (a stray
    # print, a library) goes to stderr with the log, not into the answers.
    replies = os.fdopen(os.dup(sys.stdout.fileno()), "w", buffering=1)
    sys.stdout.flush()
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    from seaway.runtime import host, memory

    memory.cap_malloc_arenas()  # as the launcher does, before any thread (seaway.runtime.memory)
    if args.cpus is not None:
        cpusets.pin_threads(0, args.cpus)
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGINT, _interrupt)
    _end_when_orphaned()
    host.activate()
    from seaway_lab.study.composed import ComposedStack

    stack = ComposedStack(args.folder, args.timeout_s)

    def say(what: str, value: Any) -> None:
        replies.write(json.dumps({what: value}) + "\n")

    try:
        say("ready", os.getpid())
        for line in sys.stdin:
            request = json.loads(line)
            if "fly" in request:
                say("flown", stack.fly(RunSpec.from_json(request["fly"])).to_json(with_series=True))
            elif "close" in request:
                say("closed", [o.to_json(with_series=True) for o in stack.close()])
                return 0
            else:
                print(f"study worker: unknown request {line.strip()[:200]!r}", file=sys.stderr)
                return 2
        return 0
    except KeyboardInterrupt:
        return 130
    finally:
        stack.stop()


if __name__ == "__main__":
    raise SystemExit(main())
