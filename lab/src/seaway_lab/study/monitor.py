"""Where a run's CPU went: the CPU seconds of a launcher and of each process under it, by name
(``CpuMonitor``, ``process_name``), or of a composed stack's one process (``ProcessCpu``)."""

from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Any


def process_name(cmdline: list[str]) -> str:
    """``sim`` for ``python .../seaway-sim ...``, ``launch`` for ``seaway launch``, else the program."""
    for i, arg in enumerate(cmdline[:3]):
        base = Path(arg).name
        if base == "seaway" and i + 1 < len(cmdline):
            return cmdline[i + 1]
        if base.startswith("seaway-"):
            return base[len("seaway-"):]
    return Path(cmdline[0]).name if cmdline else "?"


class CpuMonitor:
    """CPU seconds (user + system) of the launcher and each process under it, polled while they run.

    Each figure is the last value seen before the process ended (at most ``interval_s`` short).
    Which processes are under the launcher is asked every ``FIND_EVERY`` polls and at every
    ``snapshot``: psutil answers it by reading every process's ``/proc/PID/stat`` on the machine,
    which was more than half of a study's own Python while its stacks flew (py-spy). A process that
    starts between two askings is counted from its start all the same (its CPU times are its own
    since then); only one that starts and ends between them is missed.
    """

    FIND_EVERY = 6
    """Polls between two askings of which processes are under the launcher (3 s at 0.5 s)."""

    def __init__(self, pid: int, interval_s: float = 0.5, root: str = "launch") -> None:
        self.pid = pid
        self.root = root
        """The name of process ``pid`` in the figures (a composed launcher's is ``composed``)."""
        self.interval_s = interval_s
        self.cpu_s: dict[str, float] = {}
        self._seen: dict[tuple[int, float], tuple[str, float]] = {}
        self._procs: dict[tuple[int, float], tuple[Any, str | None]] = {}
        """The processes polled: (pid, start time) -> (psutil process, its name once known)."""
        self._polls = 0
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="cpu-monitor", daemon=True)

    def __enter__(self) -> CpuMonitor:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self.cpu_s = self._totals()

    def _totals(self) -> dict[str, float]:
        totals: dict[str, float] = {}
        with self._lock:
            for name, cpu in self._seen.values():
                totals[name] = totals.get(name, 0.0) + cpu
        return totals

    def snapshot(self) -> dict[str, float]:
        """CPU seconds by process name so far, every process sampled now (one that ended since the
        last poll counts with its last value)."""
        self._poll(find=True)
        return self._totals()

    def _sample(self, key: tuple[int, float], proc: Any, name: str | None) -> None:
        import psutil

        try:
            with proc.oneshot():
                if proc.create_time() != key[1]:  # ended, and its pid taken by another process
                    return
                t = proc.cpu_times()
                name = name or process_name(proc.cmdline())
        except psutil.Error:
            return
        with self._lock:
            self._procs[key] = (proc, name)
            self._seen[key] = (name, t.user + t.system)

    def _find(self) -> None:
        """Take in the launcher and every process now under it (those already known keep theirs)."""
        import psutil

        try:
            root = psutil.Process(self.pid)
            found = [(root, self.root), *((c, None) for c in root.children(recursive=True))]
        except psutil.Error:
            return
        for proc, name in found:
            try:
                key = (proc.pid, proc.create_time())
            except psutil.Error:
                continue
            with self._lock:
                if key not in self._procs:
                    self._procs[key] = (proc, name)

    def _poll(self, find: bool = False) -> None:
        if find or self._polls % self.FIND_EVERY == 0:
            self._find()
        self._polls += 1
        with self._lock:
            procs = list(self._procs.items())
        for key, (proc, name) in procs:
            self._sample(key, proc, name)

    def _run(self) -> None:
        while True:
            self._poll()
            if self._stop.wait(self.interval_s):
                return



class ProcessCpu:
    """CPU seconds (user + system) of this process, a composed stack (``seaway.runtime.host``), as
    ``composed``: its nodes hand work to one another on the thread that publishes (the in-memory
    bus calls subscribers in place), so a thread's CPU is not its node's, and only the whole is
    told. The face of ``CpuMonitor`` (``snapshot``, ``cpu_s`` once exited), without a thread."""

    NAME = "composed"

    def __init__(self) -> None:
        self.cpu_s: dict[str, float] = {}

    def __enter__(self) -> ProcessCpu:
        return self

    def __exit__(self, *exc: object) -> None:
        self.cpu_s = self.snapshot()

    def snapshot(self) -> dict[str, float]:
        t = os.times()
        return {self.NAME: t.user + t.system}
