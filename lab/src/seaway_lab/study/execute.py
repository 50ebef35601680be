"""Running a study's runs: one run through the real stack, and many of them at once.

One run (``run_one``) is ``seaway launch sim-batch [--composed] <the run's options> --run-dir DIR``
as a subprocess: composed, its services are nodes of the launcher's one process over the in-memory
bus; through the processes, the stack is on its own Zenoh rendezvous port
(``SEAWAY_ZENOH_RENDEZVOUS``), so that stacks running side by side never meet. It is followed by the
report of its recording: ``seaway_recorder.report.analyse`` called in-process, which gives the same
JSON as ``seaway report DIR --mission DIR/mission.json --json --no-plots`` (the mission the launcher
sent, so with the run's own T^w) from one decode of the recording instead of a second process, and
from the same decode the trajectory and thrusts the figures need. The launcher's output is kept in
``DIR/launch.log`` and timed line by line, so the wall time of a run splits into the stack's
start-up, the mission, the stop and the launcher's own final report.

Many runs: ``run_shared`` (``--workers`` stacks, each flying one run after another: a study worker
process composing its stack, ``worker.WorkerStack``, or a launcher and its processes,
``shared.SharedStack``), ``run_local`` (a pool of threads, each waiting on one launcher subprocess:
``--fresh-stacks``) or ``run_dask`` (each run submitted to a Dask cluster, whose worker starts the
stack: ``--dask``). ``run_one`` is the function submitted, so a worker needs the same installation
(``seaway`` next to its Python). The worker reads its run's recording itself and sends back the
numbers and the series, so tables and figures need no shared file system; the run folders stay
where the workers wrote them.

The parts: ``isolation`` (a rendezvous port and CPUs per stack), ``launcher`` (the launcher's
command, options and output, the launchers running), ``monitor`` (CPU seconds per process),
``outcome`` (what a run gave, its report), ``shared`` (many runs on one stack), ``composed`` (one
such stack as nodes of this process) and ``worker`` (a process per composed stack). This module runs
them and is what ``seaway study`` (``cli``) imports; it offers their names too.
"""
from __future__ import annotations

import collections
import itertools
import logging
import math
import queue
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from seaway_lab.study.composed import COMPOSED_FLAG
from seaway_lab.study.definitions import RunSpec, scenario_task_power_w
from seaway_lab.study.isolation import (
    CPUS_FLAG,
    _ephemeral_low,
    cpu_groups,
    cpus_option,
    free_port,
    stack_env,
)
from seaway_lab.study.launcher import (
    _MILESTONES,
    DEFAULT_TIMEOUT_S,
    OPTIONAL_FLAGS,
    PROFILE,
    LauncherLog,
    StudyStoppingError,
    _phases,
    _running,
    _running_lock,
    _spawn,
    _stop_group,
    _stopping,
    fit_options,
    launcher_options,
    seaway_command,
    stop_all,
)
from seaway_lab.study.monitor import CpuMonitor, ProcessCpu, process_name
from seaway_lab.study.outcome import (
    MISSION_FILE,
    RunOutcome,
    _concluded,
    not_completed_text,
    report_args,
    report_json,
)
from seaway_lab.study.shared import SharedStack, run_episode
from seaway_lab.study.worker import WorkerStack

log = logging.getLogger("seaway.study")


# -- one run --------------------------------------------------------------------------------------


def run_one(spec: RunSpec, run_dir: str | Path, *, profile: str = PROFILE,
            timeout_s: float = DEFAULT_TIMEOUT_S, keep_series: bool = True,
            cpus: frozenset[int] | None = None, composed: bool = False) -> RunOutcome:
    """One run through the real processes, or composed in the launcher's one process
    (``composed``: ``seaway launch --composed``, no network), its report, and its timing. Never
    raises for a failed run: the outcome says what went wrong (``ok``, ``error``, the launcher's log
    in ``run_dir``). ``cpus``: the CPUs its stack runs on (``cpu_groups``; None: wherever the kernel
    puts it)."""
    run_dir = Path(run_dir)
    out = RunOutcome(spec, str(run_dir))
    t0 = time.monotonic()
    try:
        supported = launcher_options()
        if composed and COMPOSED_FLAG not in supported:
            raise ValueError(f"seaway launch has no {COMPOSED_FLAG}: run the study with --processes")
        opts = ([COMPOSED_FLAG] if composed else []) + (
            fit_options(spec, supported) + [f for f in OPTIONAL_FLAGS if f in supported]
            + cpus_option(cpus, supported))
    except ValueError as err:
        out.error = str(err)
        return out
    out.port = None if composed else free_port()  # a composed stack has no network
    out.command = [*seaway_command(), "launch", profile, *opts, "--run-dir", str(run_dir)]
    run_dir.mkdir(parents=True, exist_ok=True)
    p = _spawn(out.command, out.port)
    timed_out = threading.Event()

    def on_timeout() -> None:
        timed_out.set()
        _stop_group(p)

    watchdog = threading.Timer(timeout_s, on_timeout)
    watchdog.daemon = True
    watchdog.start()
    assert p.stdout is not None
    with CpuMonitor(p.pid, root=ProcessCpu.NAME if composed else "launch") as cpu:
        launcher_log = LauncherLog(p.stdout, run_dir / "launch.log", t0)
        if launcher_log.wait(["refused"]) == "refused":  # it would wait for a mission forever
            threading.Thread(target=_stop_group, args=(p,), daemon=True).start()
        launcher_log.join()
        out.returncode = p.wait()
    with _running_lock:
        _running.discard(p)
    watchdog.cancel()
    out.cpu_s = cpu.cpu_s
    seen = launcher_log.seen
    if launcher_log.ready_reported_s is not None:
        out.timing["ready_reported_s"] = launcher_log.ready_reported_s
    t_exit = time.monotonic() - t0
    out.timing.update(_phases(seen, t_exit))
    if timed_out.is_set():
        out.error = f"timed out after {timeout_s:g} s"
    elif "refused" in seen:
        out.error = "mission refused: " + launcher_log.line_with("REFUSED")
    elif out.returncode != 0 or "complete" not in seen:
        out.error = f"launcher exited {out.returncode} before the mission completed"
    if out.error:
        out.error += "\n" + launcher_log.tail()
    t1 = time.monotonic()
    try:
        if not timed_out.is_set():  # a runaway's recording is large, and its numbers are not shown
            out.report, series = report_json(run_dir)
            if keep_series:
                out.series = series
    except Exception as err:  # a missing or broken recording is the run's failure, reported
        out.error = (out.error + "\n" if out.error else "") + f"report: {type(err).__name__}: {err}"
    out.timing["report_s"] = time.monotonic() - t1
    out.timing["wall_s"] = time.monotonic() - t0
    return _concluded(out)


# -- many runs ------------------------------------------------------------------------------------

Done = Callable[[RunOutcome], None]


def expected_cost(spec: RunSpec) -> float:
    """A rough guess of a run's length, to start the long ones first (and not end on one alone).

    NMPC flies the paper's path in ~36 s of simulated time, the economic controllers in ~340 s at the
    paper's T^w; their cruise speed grows as sqrt(T^w), so their time falls as 1/sqrt(T^w).
    """
    if spec.controller == "nmpc":
        return 1.0
    base = scenario_task_power_w(spec.scenario)
    w = spec.task_power_w if spec.task_power_w is not None else base
    return 10.0 * math.sqrt(base / w) if w > 0 and base > 0 else 10.0


def longest_first(jobs: Iterable[tuple[RunSpec, Path]]) -> list[tuple[RunSpec, Path]]:
    return sorted(jobs, key=lambda j: -expected_cost(j[0]))


def _workers(workers: int, runs: int, cpus: list[frozenset[int]] | None) -> int:
    """The workers that run at once: no more than the runs; one CPU set each when pinned
    (``cpu_groups`` of this number; ValueError otherwise, a caller's mistake)."""
    n = max(1, min(workers, runs))
    if cpus is not None and len(cpus) != n:
        raise ValueError(f"{len(cpus)} CPU sets for {n} workers at once (cpu_groups(min(workers, "
                         f"runs)) gives one each)")
    return n


def run_local(jobs: Iterable[tuple[RunSpec, Path]], workers: int, on_done: Done,
              timeout_s: float = DEFAULT_TIMEOUT_S,
              cpus: list[frozenset[int]] | None = None, composed: bool = False) -> None:
    """Run the jobs ``workers`` at a time on this machine, each with a stack of its own (composed:
    ``run_one``); ``on_done`` as each finishes. ``cpus``: one CPU set per worker (``cpu_groups``);
    a run's stack takes a free one for its life."""
    jobs = longest_first(jobs)
    workers = _workers(workers, len(jobs), cpus)
    _stopping.clear()
    launcher_options()  # once, before the threads
    free: queue.SimpleQueue[frozenset[int] | None] = queue.SimpleQueue()
    for group in cpus or [None] * workers:
        free.put(group)

    def one(spec: RunSpec, d: Path) -> RunOutcome:
        group = free.get()  # never waits: a pool thread runs one run at a time
        try:
            return run_one(spec, d, timeout_s=timeout_s, cpus=group, composed=composed)
        finally:
            free.put(group)

    pool = ThreadPoolExecutor(max_workers=workers, thread_name_prefix="study")
    try:
        futures = {pool.submit(one, spec, d): (spec, d) for spec, d in jobs}
        for fut in as_completed(futures):
            spec, d = futures[fut]
            try:
                on_done(fut.result())
            except Exception as err:
                on_done(RunOutcome(spec, str(d), error=f"{type(err).__name__}: {err}"))
    except BaseException:  # Ctrl-C: start no more runs, stop the running ones
        pool.shutdown(wait=False, cancel_futures=True)
        stop_all()
        raise
    finally:
        pool.shutdown(wait=True)


def run_shared(specs: Iterable[RunSpec], runs_dir: Path, workers: int, on_done: Done,
               on_flown: Done | None = None, timeout_s: float = DEFAULT_TIMEOUT_S,
               cpus: list[frozenset[int]] | None = None, composed: bool = False) -> None:
    """Run the specs on ``workers`` stacks at once, each flying one run after another
    (``SharedStack``; ``composed``: ``WorkerStack``, a study worker process composing its stack),
    longest first from one queue; ``on_flown`` as each run's mission ends,
    ``on_done`` with its numbers once its stack has stopped (a stack stops when the queue is empty,
    or after a failed run: the next run starts a new one). Stack folders: ``runs_dir/stack-N``.
    Callbacks are called one at a time. Ctrl-C (or SIGTERM made one by the caller) starts no more
    runs and stops every stack. ``cpus``: one CPU set per worker (``cpu_groups``), its stacks run
    there; once a worker has nothing left to fly, the stacks still flying may use every CPU."""
    todo = collections.deque(longest_first((s, runs_dir) for s in specs))
    workers = _workers(workers, len(todo), cpus)
    lock = threading.Lock()
    make: type[SharedStack] | type[WorkerStack] = WorkerStack if composed else SharedStack
    flying: dict[int, SharedStack | WorkerStack] = {}
    """Each worker's stack, by worker, while it has one."""
    stacks_made = itertools.count(1)
    _stopping.clear()
    launcher_options()  # once, before the threads

    def said(callback: Done | None, outcome: RunOutcome) -> None:
        if callback is not None:
            with lock:
                callback(outcome)

    def closed(stack: SharedStack | WorkerStack) -> None:
        for o in stack.close():
            said(on_done, o)

    def worker(index: int) -> None:
        stack: SharedStack | WorkerStack | None = None
        try:
            while True:
                with lock:
                    if not todo:
                        break
                    spec, _ = todo.popleft()
                    if stack is None:
                        stack = make(runs_dir / f"stack-{next(stacks_made)}", timeout_s,
                                     cpus[index] if cpus else None)
                        flying[index] = stack
                out = stack.fly(spec)
                said(on_flown, out)
                if out.error:  # the stack is stopped: report what it flew, then this run
                    closed(stack)
                    said(on_done, _concluded(out))
                    stack = None
        except Exception as err:  # a callback's: said, not lost with the thread
            log.exception("study worker: %s", err)
        finally:
            with lock:
                flying.pop(index, None)
                others = list(flying.values())
            if cpus:  # this worker's CPUs would idle: the stacks still flying may use them
                everything = frozenset().union(*cpus)
                for other in others:
                    other.widen(everything)
            if stack is not None:
                closed(stack)

    threads = [threading.Thread(target=worker, args=(i,), name=f"study-{i}", daemon=True)
               for i in range(workers)]
    for t in threads:
        t.start()
    try:
        for t in threads:
            while t.is_alive():
                t.join(0.5)
    except BaseException:  # Ctrl-C: start no more runs, stop the running stacks
        with lock:
            todo.clear()
        stop_all()
        raise


def run_dask(address: str, jobs: Iterable[tuple[RunSpec, Path]], on_done: Done,
             timeout_s: float = DEFAULT_TIMEOUT_S, composed: bool = False) -> dict[str, Any]:
    """Submit every run to the Dask scheduler at ``address``; each worker thread launches one stack
    (``composed``: one process, ``run_one``).

    Returns what the cluster was (scheduler address, workers and their threads).
    """
    from distributed import Client
    from distributed import as_completed as dask_completed

    jobs = longest_first(jobs)
    with Client(address, timeout="30s") as client:
        info = client.scheduler_info()
        workers = {w: {"nthreads": v.get("nthreads"), "host": v.get("host")}
                   for w, v in info.get("workers", {}).items()}
        futures = {}
        for spec, d in jobs:
            fut = client.submit(run_one, spec, str(d), timeout_s=timeout_s, composed=composed,
                                pure=False,
                                priority=round(expected_cost(spec)),
                                key=f"seaway-study-{spec.key}-{time.time_ns()}")
            futures[fut] = (spec, d)
        try:
            for fut in dask_completed(list(futures)):
                spec, d = futures[fut]
                try:
                    on_done(fut.result())
                except Exception as err:
                    on_done(RunOutcome(spec, str(d), error=f"{type(err).__name__}: {err}"))
        except BaseException:  # Ctrl-C: the runs not started are cancelled; a started one finishes
            client.cancel(list(futures))
            raise
    return {"scheduler": address, "workers": workers}


__all__ = [  # the parts' names that ``cli`` and the study's tests reach through here
    "COMPOSED_FLAG", "CPUS_FLAG", "DEFAULT_TIMEOUT_S", "MISSION_FILE", "OPTIONAL_FLAGS", "PROFILE",
    "_MILESTONES", "CpuMonitor", "Done", "LauncherLog", "RunOutcome", "SharedStack",
    "StudyStoppingError", "WorkerStack", "_ephemeral_low", "cpu_groups", "cpus_option",
    "expected_cost", "fit_options", "free_port", "launcher_options", "longest_first",
    "not_completed_text", "process_name", "report_args", "report_json", "run_dask", "run_episode",
    "run_local", "run_one", "run_shared", "seaway_command", "stack_env", "stop_all",
]
