"""Running a study's runs: one run through the real processes, and many of them at once.

One run (``run_one``) is ``seaway launch sim-batch <the run's options> --run-dir DIR`` as a
subprocess on its own Zenoh rendezvous port (``SEAWAY_ZENOH_RENDEZVOUS``), so that stacks running
side by side never meet, followed by the report of its recording: ``seaway_recorder.report.analyse``
called in-process, which gives the same JSON as ``seaway report DIR --mission DIR/mission.json
--json --no-plots`` (the mission the launcher sent, so with the run's own T^w) from one decode of the
recording instead of a second process, and from the same decode the trajectory and thrusts the
figures need. The launcher's output is kept in ``DIR/launch.log`` and timed line by line, so the
wall time of a run splits into the stack's start-up, the mission, the stop and the launcher's own
final report.

Many runs: ``run_local`` (a pool of threads, each waiting on one launcher subprocess: ``--workers``)
or ``run_dask`` (each run submitted to a Dask cluster, whose worker starts the stack: ``--dask``).
``run_one`` is the function submitted, so a worker needs the same installation (``seaway`` next to
its Python). The worker reads its run's recording itself and sends back the numbers and the series,
so tables and figures need no shared file system; the run folders stay where the workers wrote them.
"""

from __future__ import annotations

import collections
import contextlib
import itertools
import logging
import math
import os
import queue
import random
import re
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.runtime import cpus as cpusets
from seaway.runtime.zenoh_bus import ENV_CONFIG, ENV_RENDEZVOUS
from seaway.simkit.scenario import load_mission

from seaway_lab.study.definitions import RunSpec, scenario_task_power_w

log = logging.getLogger("seaway.study")

PROFILE = "sim-batch"
OPTIONAL_FLAGS = ("--no-report",)
"""Launcher flags passed when the launcher has them: its own final report (with plots) is work the
study does not use, since it reads each recording itself."""
CPUS_FLAG = "--cpus"
"""The launcher's option that keeps a stack on a CPU set (``seaway.runtime.cpus``); passed when the
study pins its stacks and the launcher has it."""

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


# -- isolation: a rendezvous port per stack -------------------------------------------------------

_ports_lock = threading.Lock()
_ports_given: set[int] = set()


def _ephemeral_low() -> int:
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def free_port(rng: random.Random | None = None) -> int:
    """A loopback TCP port that is free now, below the ephemeral range and not given out before.

    Below the ephemeral range, no process of another stack can be handed the port by the kernel
    (each Zenoh process also listens on an ephemeral port) between this check and its first use.
    """
    rng = rng or random.Random()
    low, high = 20000, max(20001, min(_ephemeral_low(), 32768))
    with _ports_lock:
        for _ in range(200):
            port = rng.randrange(low, high)
            if port in _ports_given:
                continue
            with socket.socket() as s:
                try:
                    s.bind(("127.0.0.1", port))
                except OSError:
                    continue
            _ports_given.add(port)
            return port
    raise RuntimeError(f"no free loopback port in {low}..{high}")


def stack_env(port: int, base: dict[str, str] | None = None) -> dict[str, str]:
    """The environment of one stack: its own rendezvous port, the packaged Zenoh config."""
    env = dict(os.environ if base is None else base)
    env[ENV_RENDEZVOUS] = f"tcp/127.0.0.1:{port}"
    env.pop(ENV_CONFIG, None)
    env["PYTHONUNBUFFERED"] = "1"
    return env


# -- isolation: CPUs per stack -------------------------------------------------------------------

def cpu_groups(workers: int, pin: bool | None) -> list[frozenset[int]] | None:
    """The CPU set of each of ``workers`` local stacks (``cpus.partition`` of the CPUs this process
    may use), or None to leave them to the kernel. ``pin``: None pins where it pays, False never,
    True wherever it can be done (an error otherwise, saying why). It pays for two or more stacks
    and no more than the CPUs (each stack gets CPUs of its own), and for one stack given two CPUs or
    more (all of them: its launcher puts the lockstep chain on one and the rest on the others,
    ``cpus.split_chain``)."""
    if pin is False:
        return None
    available = cpusets.allowed()
    if workers == 1:
        groups = [available] if cpusets.split_chain(available) is not None else None
    else:
        groups = cpusets.partition(available, workers)
    if groups is None and pin:
        n = len(available)
        raise ValueError(f"--pin: {workers} stack(s) at once cannot each have CPUs of their own: "
                         f"this process may use {n} CPU(s) ({cpusets.format_cpus(available)}), so "
                         + (f"--pin takes 1 to {n} workers" if n >= 2 else "nothing can be pinned"))
    return groups


def cpus_option(group: frozenset[int] | None, supported: set[str]) -> list[str]:
    """``--cpus LIST`` for a stack pinned to ``group``, if the launcher has the option."""
    if group is None or CPUS_FLAG not in supported:
        return []
    return [CPUS_FLAG, cpusets.format_cpus(group)]


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


# -- one run --------------------------------------------------------------------------------------


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

    def __init__(self, pid: int, interval_s: float = 0.5) -> None:
        self.pid = pid
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
            found = [(root, "launch"), *((c, None) for c in root.children(recursive=True))]
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


@dataclass
class RunOutcome:
    """What one run gave: the report's JSON, the series for the figures, and where the time went."""

    spec: RunSpec
    run_dir: str
    episode: int | None = None
    """Which lockstep episode of the run folder's recording is this run's (``seaway report
    --episode``), where one stack flew several runs (``run_shared``); None: its only one."""
    ok: bool = False
    error: str = ""
    host: str = field(default_factory=socket.gethostname)
    port: int | None = None
    command: list[str] = field(default_factory=list)
    returncode: int | None = None
    report: dict[str, Any] | None = None
    """The JSON ``seaway report DIR --json --no-plots`` prints."""
    series: dict[str, Any] | None = None
    """The mission's trajectory and thrusts: t_s, x_m, y_m; thrust_t_s, thrust_port_n, thrust_starboard_n."""
    cpu_s: dict[str, float] = field(default_factory=dict)
    """CPU seconds by process: ``launch``, ``recorder``, ``sim``, ``estimator``, ``controller``,
    ``report`` (the launcher's own)."""
    timing: dict[str, float] = field(default_factory=dict)
    """Wall seconds: ``wall_s`` (all), ``startup_s`` (spawn to every service ready), ``ready_reported_s``
    (the launcher's own figure), ``mission_s`` (ready to complete), ``stop_s``, ``launcher_report_s``
    (the launcher's final report and exit), ``report_s`` (this report), ``sim_per_wall`` (simulated s
    per wall s over the mission phase)."""

    def metric(self, name: str) -> float | None:
        if self.report is None:
            return None
        v = self.report.get("metrics", {}).get(name)
        return None if v is None else float(v)

    def to_json(self, with_series: bool = False) -> dict[str, Any]:
        d: dict[str, Any] = {**self.spec.to_json(), "run_dir": self.run_dir,
                             "episode": self.episode, "ok": self.ok,
                             "error": self.error, "host": self.host, "port": self.port,
                             "command": self.command, "returncode": self.returncode,
                             "timing": self.timing, "cpu_s": self.cpu_s, "report": self.report}
        if with_series:
            d["series"] = self.series
        return d


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


def _spawn(command: list[str], port: int) -> subprocess.Popen[str]:
    """A launcher on its own rendezvous ``port``, in a session of its own, its output piped."""
    with _running_lock:
        if _stopping.is_set():
            raise StudyStoppingError("the study is stopping: no more stacks are started")
        p = subprocess.Popen(command, env=stack_env(port), stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, text=True,
                             start_new_session=True)
        _running.add(p)
    return p


def run_one(spec: RunSpec, run_dir: str | Path, *, profile: str = PROFILE,
            timeout_s: float = DEFAULT_TIMEOUT_S, keep_series: bool = True,
            cpus: frozenset[int] | None = None) -> RunOutcome:
    """One run through the real processes, its report, and its timing. Never raises for a failed run:
    the outcome says what went wrong (``ok``, ``error``, the launcher's log in ``run_dir``).
    ``cpus``: the CPUs its stack runs on (``cpu_groups``; None: wherever the kernel puts it)."""
    run_dir = Path(run_dir)
    out = RunOutcome(spec, str(run_dir))
    t0 = time.monotonic()
    try:
        supported = launcher_options()
        opts = (fit_options(spec, supported) + [f for f in OPTIONAL_FLAGS if f in supported]
                + cpus_option(cpus, supported))
    except ValueError as err:
        out.error = str(err)
        return out
    out.port = free_port()
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
    with CpuMonitor(p.pid) as cpu:
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


def _concluded(out: RunOutcome) -> RunOutcome:
    """``out`` with its simulated seconds per wall second and its verdict: ok only when nothing
    failed and the recording shows the mission completed."""
    travel = out.metric("travel_time_s")
    if travel and out.timing.get("mission_s"):
        out.timing["sim_per_wall"] = travel / out.timing["mission_s"]
    completed = bool(out.report and out.report.get("metrics", {}).get("completed"))
    if not out.error and not completed:
        out.error = not_completed_text(out.report or {})
    out.ok = not out.error
    return out


def not_completed_text(report: dict[str, Any]) -> str:
    """Why a run whose launcher saw the mission complete counts as not completed: the recording's
    true track did not complete it, while the controller did on its estimate (``completion``)."""
    met, c = report.get("metrics") or {}, report.get("completion") or {}
    text = "the recording shows the mission not completed"
    legs = (report.get("mission") or {}).get("waypoints_m")
    if met.get("legs_completed") is not None and legs:
        text += f" on the true track ({met['legs_completed']} of {len(legs) - 1} legs)"
    if c.get("controller"):
        err = c.get("estimate_error_m")
        text += ("; the controller completed it on its estimate"
                 + (f", {err:.2f} m from the truth" if err is not None else ""))
    return text


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


MISSION_FILE = "mission.json"
"""The mission the launcher sent, in the run folder: the launcher's own report takes it from there."""


def report_args(run_dir: str | Path) -> list[str]:
    """The ``seaway report`` arguments of a run folder: the mission sent, when the launcher wrote it.

    Without it the report takes the mission from the recording's scenario attachment, whose T^w is
    the scenario's, not the ``--task-power-w`` the run flew.
    """
    mission = Path(run_dir) / MISSION_FILE
    return [str(run_dir), *(["--mission", str(mission)] if mission.is_file() else [])]


def report_json(run_dir: str | Path, *, episode: int | None = None, read: Any = None,
                scenario: str | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """(what ``seaway report <report_args> --json --no-plots`` prints, the series for the figures).

    ``episode``, ``read`` (``report.read_for_report`` of the folder) and ``scenario``: one of the
    runs a shared stack flew (``run_shared``), from one decode of its recording; its mission is the
    one the controller recorded accepting (the launcher sent none: no ``mission.json``)."""
    from seaway.recording import reader as recording
    from seaway_recorder import report as rep

    mission = Path(run_dir) / MISSION_FILE
    files = recording.open_paths([run_dir]) if read is None else read[0].files
    res = rep.analyse(files, scenario=scenario, episode=episode, read=read,
                      mission_file=str(mission) if mission.is_file() else None)
    doc = rep._clean({k: v for k, v in res.items() if k != "_"})  # exactly what --json prints
    data = res["_"]
    ser = data["series"]
    start, end = data["start_ns"], res["metrics"]["end_ns"]
    thrusts = [c for c in data["thrusts"] if start <= c.stamp_ns <= end]
    series = {"t_s": ser["t_s"], "x_m": ser["x_m"], "y_m": ser["y_m"],
              "thrust_source": keys.SIM_TRUTH.suffix if res["metrics"]["state_source"] ==
              keys.SIM_TRUTH.suffix else keys.THRUST.suffix,
              "thrust_t_s": [(c.stamp_ns - start) / 1e9 for c in thrusts],
              "thrust_port_n": [c.thrust_port_n for c in thrusts],
              "thrust_starboard_n": [c.thrust_starboard_n for c in thrusts],
              "waypoints_m": res["mission"]["waypoints_m"], "coa_radius_m": res["mission"]["coa_radius_m"]}
    return doc, rep._clean(series)


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
              cpus: list[frozenset[int]] | None = None) -> None:
    """Run the jobs ``workers`` at a time on this machine; ``on_done`` as each finishes. ``cpus``:
    one CPU set per worker (``cpu_groups``); a run's stack takes a free one for its life."""
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
            return run_one(spec, d, timeout_s=timeout_s, cpus=group)
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


# -- many runs on one stack -----------------------------------------------------------------------

STATUS_POLL_S = 0.05
"""How often a shared stack's mission status is looked at [wall s]: the transport keeps the newest
status (``Bus.newest``), so a look costs one decode, not one per period. A stack whose mission is
over holds (nothing to fly), so a later look costs the next run at most this much; looking every
0.01 s cost the study's process 5.4 % of a core per stack while it flew, every 0.05 s 3.7-4.2 %
(a paper #1 run, two of each)."""
REQUEST_TIMEOUT_S = 30.0
"""How long a scenario load or a mission request may take to be answered (a load is answered once
every member has answered the new episode's first period)."""
REQUESTED_FROM = frozenset({"sim", "controller"})
"""The services a shared stack's runs are requested from (a scenario load, a mission)."""
SHARED_FLAGS = ("--no-mission", "--stay")
"""What a shared stack's launcher is started with: no mission of its own (the study sends each, the
first too, once it hears the status), and no stop at a mission's end."""


class _RunFailedError(Exception):
    """A run on a shared stack failed; the text says how. The stack is stopped after it."""


def run_episode(episodes: list[int], mission_id: str) -> int:
    """The episode of a stack's recording that is a run's, from the episodes that accepted its
    mission (``report.mission_episodes``): the last. More than one: the sim restarted mid-run, came
    back in the scenario loaded for the run (``seaway_sim.kept``) with time at 0, and the controller
    flew the mission again from its first leg. ValueError when none accepted it."""
    if not episodes:
        raise ValueError(f"no episode of the recording accepted mission {mission_id}")
    return episodes[-1]


class SharedStack:
    """One ``seaway launch sim-batch --no-mission --stay`` that flies runs one after another, in one
    folder.

    The launcher starts the stack on the first run's scenario. For each run the study, as the
    operator (with the credentials the launcher registered for the stack's rendezvous), loads its
    scenario into the sim (``sim/scenario``, action ``load``: a new lockstep episode from t = 0, in
    which the estimator starts again and the controller holds; not for the first run, whose
    scenario is the launch's) and sends its mission (``mission/set``) named after the run, with its
    controller, T^w and disturbance prediction, then waits until the controller's status says it is
    over (``mission_over``). Each run is one episode of the folder's recording; ``close`` stops the
    stack and reports every run it flew from one decode of it.

    Why: a stack's start and stop cost 2.5-3 s of wall time and about 1 core-s (five Python
    processes importing numpy, CasADi, pydantic and Zenoh), paid once per stack instead of once per
    run (docs/results.md, 2026-11-29). Two missions in one stack give the numbers of two fresh
    stacks (``test_lockstep_restarts``, ``test_study_shared``).
    """

    def __init__(self, folder: Path, timeout_s: float = DEFAULT_TIMEOUT_S,
                 cpus: frozenset[int] | None = None) -> None:
        self.folder = Path(folder)
        self.timeout_s = timeout_s
        self.cpus = cpus
        """The CPUs the stack runs on (``cpu_groups``; None: wherever the kernel puts it)."""
        self._cpus_lock = threading.Lock()  # a widen waits for a start that read ``cpus``
        self.port: int | None = None
        self.command: list[str] = []
        self.proc: subprocess.Popen[str] | None = None
        self.log: LauncherLog | None = None
        self.bus: Any = None
        self.status: Any = None
        self.energy: Any = None
        self.cpu: CpuMonitor | None = None
        self._cpu_before: dict[str, float] = {}
        self._stopped = False
        self.flown: list[RunOutcome] = []
        """Runs flown to their end, not yet reported (each mission is named ``spec.key``)."""

    def fly(self, spec: RunSpec) -> RunOutcome:
        """Fly ``spec`` on this stack (starting it for the first run). Never raises: a failed run's
        outcome says why, and leaves the stack stopped (the runs it flew before are in ``flown``)."""
        out = RunOutcome(spec, str(self.folder))
        t0 = time.monotonic()
        try:
            if self._stopped:
                raise _RunFailedError("the stack was stopped")
            if self.proc is None:
                self._start(spec, out)
            else:
                self._load(spec, out)
            self._mission(spec, out, t0 + self.timeout_s)
        except _RunFailedError as err:
            out.error = str(err) + ("\n" + self.log.tail() if self.log is not None else "")
        except Exception as err:  # a bus that would not open, a scenario that would not read
            out.error = f"{type(err).__name__}: {err}"
        out.port, out.command = self.port, self.command
        out.timing["flight_s"] = time.monotonic() - t0
        self._count_cpu(out)
        if out.error:
            self.stop(out)
            out.timing["wall_s"] = out.timing["flight_s"] + out.timing.get("stop_s", 0.0)
        else:
            self.flown.append(out)
        return out

    def _count_cpu(self, out: RunOutcome) -> None:
        """The stack's CPU since the last run ended, as this run's (the first's has the start-up)."""
        if self.cpu is None:
            return
        now = self.cpu.snapshot()
        out.cpu_s = {k: v - self._cpu_before.get(k, 0.0) for k, v in now.items()}
        self._cpu_before = now

    def _start(self, spec: RunSpec, out: RunOutcome) -> None:
        from seaway.runtime import stacks
        from seaway.runtime.bus import Bus

        supported = launcher_options()
        missing = [f for f in ("--scenario", *SHARED_FLAGS) if f not in supported]
        if missing:
            raise _RunFailedError(f"seaway launch has no {', '.join(missing)}, which a shared stack "
                                  "needs: run the study with --fresh-stacks")
        self.port = free_port()
        self.folder.mkdir(parents=True, exist_ok=True)
        t0 = time.monotonic()
        with self._cpus_lock:
            opts = ["--scenario", spec.scenario, *SHARED_FLAGS,
                    *(f for f in OPTIONAL_FLAGS if f in supported), *cpus_option(self.cpus, supported)]
            self.command = [*seaway_command(), "launch", PROFILE, *opts, "--run-dir", str(self.folder)]
            self.proc = _spawn(self.command, self.port)
        assert self.proc.stdout is not None
        self.cpu = CpuMonitor(self.proc.pid)
        self.cpu.__enter__()
        self.log = LauncherLog(self.proc.stdout, self.folder / "launch.log", t0)
        if self.log.wait(["ready"], self.timeout_s) is None:
            if self.log.ended:
                raise _RunFailedError(f"launcher exited {self._exit_code()} before the stack was ready")
            raise _RunFailedError(f"the stack was not ready within {self.timeout_s:g} s")
        out.timing["startup_s"] = self.log.seen["ready"]
        if self.log.ready_reported_s is not None:
            out.timing["ready_reported_s"] = self.log.ready_reported_s
        rendezvous = f"tcp/127.0.0.1:{self.port}"
        entry = stacks.lookup(rendezvous)
        if entry is None:
            raise _RunFailedError(f"the launcher registered no stack on {rendezvous}")
        self.bus = Bus.open(entry.vessel, identity="operator",
                            credentials=entry.session_credentials(), rendezvous=rendezvous)
        self.status = self.bus.newest(keys.MISSION_STATUS)
        self.energy = self.bus.newest(keys.MISSION_ENERGY)
        # A session just opened knows nobody yet: a request sent now found no one to answer it
        # ("no reply"). The services' health tokens, declared after their queryables, say it does.
        deadline = t0 + self.timeout_s
        while not (seen := self.bus.alive_services(timeout_s=0.5)) >= REQUESTED_FROM:
            if time.monotonic() > deadline:
                raise _RunFailedError(f"the study's session did not reach the stack's "
                                      f"{', '.join(sorted(REQUESTED_FROM - seen))} within "
                                      f"{self.timeout_s:g} s")
            time.sleep(0.05)

    def _exit_code(self) -> int | str:
        assert self.proc is not None
        try:
            return self.proc.wait(5.0)
        except subprocess.TimeoutExpired:
            return "?"

    def _load(self, spec: RunSpec, out: RunOutcome) -> None:
        from seaway.contract.config import deploy_named, read_document
        from seaway.contract.messages import ScenarioRequest

        t0 = time.monotonic()
        doc = read_document(deploy_named("scenarios", spec.scenario, "scenario"))
        reply = self.bus.request(keys.SIM_SCENARIO, ScenarioRequest(stamp_ns=0, action="load",
                                                                    scenario=doc),
                                 REQUEST_TIMEOUT_S)
        if not reply.accepted:
            raise _RunFailedError(f"scenario {spec.scenario} not loaded: {reply.reason}")
        out.timing["switch_s"] = time.monotonic() - t0

    def _mission(self, spec: RunSpec, out: RunOutcome, deadline: float) -> None:
        from seaway.contract.messages import mission_over

        t0 = time.monotonic()
        mission = load_mission(spec.scenario).to_request(
            0, controller=spec.controller, predict_disturbance=spec.predict_disturbance,
            task_power_w=spec.task_power_w)
        # Named after the run, whatever the scenario calls it: its status and its episode must not
        # be taken for an earlier run's of the same scenario (which flew under the same name).
        mission = type(mission).model_validate({**mission.model_dump(), "mission_id": spec.key})
        reply = self.bus.request(keys.MISSION_SET, mission, REQUEST_TIMEOUT_S)
        if not reply.accepted:
            raise _RunFailedError(f"mission {spec.key} refused: {reply.reason}")
        assert self.proc is not None
        while not mission_over(s := self.status.get(), self.energy.get(), spec.key):
            if s is not None and s.mission_id == spec.key and s.state == "aborted":
                raise _RunFailedError(f"mission {spec.key} aborted"
                                      + (f": {s.reason}" if s.reason else ""))
            if self.proc.poll() is not None:
                raise _RunFailedError(f"launcher exited {self.proc.returncode} before mission "
                                      f"{spec.key} was over")
            if time.monotonic() > deadline:
                raise _RunFailedError(f"timed out after {self.timeout_s:g} s")
            time.sleep(STATUS_POLL_S)
        out.timing["mission_s"] = time.monotonic() - t0

    def widen(self, cpus: frozenset[int]) -> None:
        """Let the stack use ``cpus`` from now on (for the CPUs a finished stack leaves idle): every
        thread of its launcher and of the processes it started (one it starts later inherits the
        launcher's); a stack not started yet starts there. Best effort: a process that ends
        meanwhile is skipped."""
        import psutil

        with self._cpus_lock:
            if self.cpus is None or self.cpus == cpus:
                return
            self.cpus = cpus
            if self.proc is None or self._stopped or self.proc.poll() is not None:
                return
            try:
                procs = [psutil.Process(self.proc.pid)]
                procs += procs[0].children(recursive=True)
            except psutil.Error:
                return
            for p in procs:
                with contextlib.suppress(OSError):
                    cpusets.pin_threads(p.pid, cpus)

    def stop(self, last: RunOutcome | None = None) -> None:
        """Stop the stack (its launcher and services), once; the time it took and the CPU spent
        meanwhile count to ``last``'s."""
        if self._stopped or self.proc is None:
            self._stopped = True
            return
        self._stopped = True
        t0 = time.monotonic()
        if self.bus is not None:
            self.bus.close()
            self.bus = None
        _stop_group(self.proc)
        with _running_lock:
            _running.discard(self.proc)
        if self.log is not None:
            self.log.join(10.0)
        if self.cpu is not None:
            self.cpu.__exit__(None, None, None)
            if last is not None:
                for k, v in self.cpu.cpu_s.items():
                    last.cpu_s[k] = last.cpu_s.get(k, 0.0) + v - self._cpu_before.get(k, 0.0)
        if last is not None:
            last.returncode = self.proc.returncode
            last.timing["stop_s"] = time.monotonic() - t0

    def close(self, keep_series: bool = True) -> list[RunOutcome]:
        """Stop the stack (if a failed run did not) and report every run it flew, from one decode
        of its recording. Never raises: a run that cannot be reported says why."""
        outs, self.flown = self.flown, []
        self.stop(outs[-1] if outs else None)
        if not outs:
            return []
        from seaway.recording import reader as recording
        from seaway_recorder import report as rep

        try:
            t0 = time.monotonic()
            read = rep.read_for_report(recording.open_paths([self.folder]))
            shared_s = (time.monotonic() - t0) / len(outs)  # the decode, shared by its runs
        except Exception as err:
            for o in outs:
                o.error = f"report: {type(err).__name__}: {err}"
            return [_concluded(o) for o in outs]
        for o in outs:
            t1 = time.monotonic()
            try:
                o.episode = run_episode(rep.mission_episodes(read[1], o.spec.key), o.spec.key)
                o.report, series = report_json(self.folder, episode=o.episode, read=read,
                                               scenario=o.spec.scenario)
                if keep_series:
                    o.series = series
            except Exception as err:
                o.error = f"report: {type(err).__name__}: {err}"
            o.timing["report_s"] = time.monotonic() - t1 + shared_s
            o.timing["wall_s"] = sum(o.timing.get(k, 0.0) for k in ("flight_s", "stop_s", "report_s"))
        return [_concluded(o) for o in outs]


def run_shared(specs: Iterable[RunSpec], runs_dir: Path, workers: int, on_done: Done,
               on_flown: Done | None = None, timeout_s: float = DEFAULT_TIMEOUT_S,
               cpus: list[frozenset[int]] | None = None) -> None:
    """Run the specs on ``workers`` stacks at once, each flying one run after another
    (``SharedStack``), longest first from one queue; ``on_flown`` as each run's mission ends,
    ``on_done`` with its numbers once its stack has stopped (a stack stops when the queue is empty,
    or after a failed run: the next run starts a new one). Stack folders: ``runs_dir/stack-N``.
    Callbacks are called one at a time. Ctrl-C (or SIGTERM made one by the caller) starts no more
    runs and stops every stack. ``cpus``: one CPU set per worker (``cpu_groups``), its stacks run
    there; once a worker has nothing left to fly, the stacks still flying may use every CPU."""
    todo = collections.deque(longest_first((s, runs_dir) for s in specs))
    workers = _workers(workers, len(todo), cpus)
    lock = threading.Lock()
    flying: dict[int, SharedStack] = {}
    """Each worker's stack, by worker, while it has one."""
    stacks_made = itertools.count(1)
    _stopping.clear()
    launcher_options()  # once, before the threads

    def said(callback: Done | None, outcome: RunOutcome) -> None:
        if callback is not None:
            with lock:
                callback(outcome)

    def closed(stack: SharedStack) -> None:
        for o in stack.close():
            said(on_done, o)

    def worker(index: int) -> None:
        stack: SharedStack | None = None
        try:
            while True:
                with lock:
                    if not todo:
                        break
                    spec, _ = todo.popleft()
                    if stack is None:
                        stack = SharedStack(runs_dir / f"stack-{next(stacks_made)}", timeout_s,
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
             timeout_s: float = DEFAULT_TIMEOUT_S) -> dict[str, Any]:
    """Submit every run to the Dask scheduler at ``address``; each worker thread launches one stack.

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
            fut = client.submit(run_one, spec, str(d), timeout_s=timeout_s, pure=False,
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
