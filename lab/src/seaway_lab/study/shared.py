"""Many runs on one stack: ``SharedStack``, one ``seaway launch sim-batch --no-mission --stay``
that flies runs one after another (a scenario load and a mission each), reported together from one
decode of its recording."""

from __future__ import annotations

import contextlib
import subprocess
import threading
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from seaway.contract import keys
from seaway.runtime import cpus as cpusets
from seaway.simkit.scenario import load_mission

from seaway_lab.study.definitions import RunSpec
from seaway_lab.study.isolation import cpus_option, free_port
from seaway_lab.study.launcher import (
    DEFAULT_TIMEOUT_S,
    OPTIONAL_FLAGS,
    PROFILE,
    LauncherLog,
    _running,
    _running_lock,
    _spawn,
    _stop_group,
    launcher_options,
    seaway_command,
)
from seaway_lab.study.monitor import CpuMonitor, ProcessCpu
from seaway_lab.study.outcome import RunOutcome, _concluded, report_json

STATUS_POLL_S = 0.05
"""How often a shared stack's mission status is looked at [wall s]: the transport keeps the newest
status (``Bus.newest``), so a look costs one decode, not one per period. A stack whose mission is
over holds (nothing to fly), so a later look costs the next run at most this much; looking more
often costs the study's process CPU, per stack, that the stacks would rather have, for little."""
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

    Why: a stack's start and stop cost seconds of wall time and CPU (five Python processes
    importing numpy, CasADi, pydantic and Zenoh), paid once per stack instead of once per run. Two
    missions in one stack give the numbers of two fresh
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
        self.proc: Any = None
        """The launcher: a process (``subprocess.Popen``), or a node (``host.NodeThread``) of a
        composed stack (``composed.ComposedStack``)."""
        self.log: LauncherLog | None = None
        self.bus: Any = None
        self.status: Any = None
        self.energy: Any = None
        self.cpu: CpuMonitor | ProcessCpu | None = None
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
        t0 = time.monotonic()
        self.folder.mkdir(parents=True, exist_ok=True)
        stream = self._launch(spec)
        self.log = LauncherLog(stream, self.folder / "launch.log", t0)
        if self.log.wait(["ready"], self.timeout_s) is None:
            if self.log.ended:
                raise _RunFailedError(f"launcher exited {self._exit_code()} before the stack was ready")
            raise _RunFailedError(f"the stack was not ready within {self.timeout_s:g} s")
        out.timing["startup_s"] = self.log.seen["ready"]
        if self.log.ready_reported_s is not None:
            out.timing["ready_reported_s"] = self.log.ready_reported_s
        self.bus = self._open_bus()
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

    def _launch(self, spec: RunSpec) -> Iterable[str]:
        """Start the stack's launcher on ``spec``'s scenario (``proc``, ``command``, ``port``,
        ``cpu``); its output, line by line."""
        supported = launcher_options()
        missing = [f for f in ("--scenario", *SHARED_FLAGS) if f not in supported]
        if missing:
            raise _RunFailedError(f"seaway launch has no {', '.join(missing)}, which a shared stack "
                                  "needs: run the study with --fresh-stacks")
        self.port = free_port()
        with self._cpus_lock:
            opts = ["--scenario", spec.scenario, *SHARED_FLAGS, *spec.module_options(),
                    *(f for f in OPTIONAL_FLAGS if f in supported), *cpus_option(self.cpus, supported)]
            self.command = [*seaway_command(), "launch", PROFILE, *opts, "--run-dir", str(self.folder)]
            self.proc = _spawn(self.command, self.port)
        assert self.proc.stdout is not None
        self.cpu = CpuMonitor(self.proc.pid)
        self.cpu.__enter__()
        return self.proc.stdout

    def _open_bus(self) -> Any:
        """The study's session on the stack, as the operator (with the credentials the launcher
        registered for its rendezvous)."""
        from seaway.runtime import stacks
        from seaway.runtime.bus import Bus

        rendezvous = f"tcp/127.0.0.1:{self.port}"
        entry = stacks.lookup(rendezvous)
        if entry is None:
            raise _RunFailedError(f"the launcher registered no stack on {rendezvous}")
        return Bus.open(entry.vessel, identity="operator", credentials=entry.session_credentials(),
                        rendezvous=rendezvous)

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
        self._end_launcher()
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

    def _end_launcher(self) -> None:
        """Stop the launcher (it stops its services, the recorder last) and wait for it."""
        assert self.proc is not None
        _stop_group(self.proc)
        with _running_lock:
            _running.discard(self.proc)

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
