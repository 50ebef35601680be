"""`seaway study` on shared stacks (``execute.run_shared``): which stack flies which run, what a
failed run does to its stack, and the launcher's output as the study reads it. The stack itself is a
stand-in here (pure scheduling); tests/system/study/test_study_shared.py flies real ones."""

from __future__ import annotations

import io
import os
import threading
import time
from pathlib import Path
from typing import ClassVar

import pytest
from seaway_lab.study import execute as ex
from seaway_lab.study import launcher
from seaway_lab.study.definitions import RunSpec, get_study

TABLE1 = get_study("table1").runs


class FakeStack:
    """Flies a run in no time; fails the runs named in ``FAILING``."""

    FAILING: ClassVar[set[str]] = set()
    made: ClassVar[list[FakeStack]] = []

    SLOW: ClassVar[set[str]] = set()
    """Runs that take a while: their stack is still flying when the other worker runs out."""

    def __init__(self, folder: Path, timeout_s: float, cpus: frozenset[int] | None = None) -> None:
        self.folder, self.timeout_s, self.cpus = folder, timeout_s, cpus
        self.started_on = cpus
        self.widened: list[tuple[frozenset[int], set[str]]] = []
        self.flown: list[ex.RunOutcome] = []
        self.flying: set[str] = set()
        self.closed = False
        FakeStack.made.append(self)

    def widen(self, cpus: frozenset[int]) -> None:
        self.widened.append((cpus, set(self.flying)))
        self.cpus = cpus

    def fly(self, spec: RunSpec) -> ex.RunOutcome:
        assert not self.closed, "a run flown on a stopped stack"
        out = ex.RunOutcome(spec, str(self.folder))
        self.flying = {spec.key}
        time.sleep(0.5 if spec.key in self.SLOW else 0.001)
        self.flying = set()
        if spec.key in self.FAILING:
            out.error = "timed out after 1 s"
            self.closed = True  # a failed run stops its stack (SharedStack.fly)
        else:
            out.report = {"metrics": {"completed": True}}
            self.flown.append(out)
        return out

    def close(self) -> list[ex.RunOutcome]:
        self.closed = True
        for i, o in enumerate(self.flown):
            o.episode = i
        return [ex._concluded(o) for o in self.flown]


@pytest.fixture()
def fake(monkeypatch: pytest.MonkeyPatch):
    monkeypatch.setattr(ex, "SharedStack", FakeStack)
    monkeypatch.setattr(ex, "launcher_options", lambda: set())
    FakeStack.made, FakeStack.FAILING, FakeStack.SLOW = [], set(), set()
    return FakeStack


def _run(tmp_path: Path, workers: int, cpus: list[frozenset[int]] | None = None,
         specs: list[RunSpec] = TABLE1) -> tuple[list[ex.RunOutcome], list[str]]:
    done, flown = [], []
    ex.run_shared(specs, tmp_path, workers, done.append, on_flown=lambda o: flown.append(o.spec.key),
                  cpus=cpus)
    return done, flown


def test_pinned_stacks_start_on_their_workers_cpus_and_take_the_cpus_a_finished_one_leaves(
        fake, tmp_path: Path) -> None:
    # Two runs: one long. The worker of the short one runs out of runs while the long one flies:
    # that stack may then use both CPUs (else one would idle to the end of the study).
    specs = [s for s in TABLE1 if s.key in ("paper-c1-cc-empc", "paper-c1-nmpc")]
    fake.SLOW = {"paper-c1-cc-empc"}
    done, _ = _run(tmp_path, workers=2, cpus=[frozenset({0}), frozenset({1})], specs=specs)
    assert all(o.ok for o in done) and len(fake.made) == 2
    assert sorted(s.started_on for s in fake.made) == [frozenset({0}), frozenset({1})]
    slow = next(s for s in fake.made if any(o.spec.key == "paper-c1-cc-empc" for o in s.flown))
    assert slow.widened and slow.widened[0] == (frozenset({0, 1}), {"paper-c1-cc-empc"})
    fast = next(s for s in fake.made if s is not slow)
    assert all(c == frozenset({0, 1}) for c, _ in fast.widened)  # nothing narrower, ever


def test_more_workers_than_runs_fly_each_run_once_on_cpus_of_their_own(fake, tmp_path: Path) -> None:
    specs = [s for s in TABLE1 if s.key in ("paper-c1-cc-empc", "paper-c1-nmpc")]
    groups = [frozenset({0}), frozenset({1})]  # cpu_groups(min(workers, runs)): one per stack
    done, _ = _run(tmp_path, workers=3, cpus=groups, specs=specs)
    assert sorted(o.spec.key for o in done) == sorted(s.key for s in specs) and all(o.ok for o in done)
    # Each stack made has a CPU set of its own among the two. How many are made depends on
    # scheduling: a fake run ends at once, so one worker may fly both before the next one starts.
    made = [s.started_on for s in fake.made]
    assert made and set(made) <= set(groups) and len(set(made)) == len(made), made
    with pytest.raises(ValueError, match=r"2 CPU sets for 1 workers at once"):
        _run(tmp_path, workers=1, cpus=groups, specs=specs)


def test_stacks_left_to_the_kernel_are_never_pinned(fake, tmp_path: Path) -> None:
    fake.SLOW = {"paper-c1-cc-empc"}
    _run(tmp_path, workers=2, specs=[s for s in TABLE1 if s.row == "#1"])
    assert all(s.started_on is None and not s.widened for s in fake.made)


def test_the_cpu_groups_of_a_study(monkeypatch: pytest.MonkeyPatch) -> None:
    from seaway.runtime import cpus

    monkeypatch.setattr(cpus, "allowed", lambda: frozenset({0, 1}))
    assert ex.cpu_groups(2, None) == [frozenset({0}), frozenset({1})]
    # One stack: both CPUs, its launcher putting the lockstep chain on one (cpus.split_chain).
    assert ex.cpu_groups(1, None) == [frozenset({0, 1})]
    assert ex.cpu_groups(1, True) == [frozenset({0, 1})]
    assert ex.cpu_groups(3, None) is None  # two stacks on one CPU while none idles: no
    assert ex.cpu_groups(2, False) is None
    with pytest.raises(ValueError, match=r"--pin: 3 stack\(s\) at once cannot each have CPUs of their "
                                         r"own: this process may use 2 CPU\(s\) \(0-1\), so --pin "
                                         r"takes 1 to 2 workers"):
        ex.cpu_groups(3, True)
    monkeypatch.setattr(cpus, "allowed", lambda: frozenset({3}))
    with pytest.raises(ValueError, match=r"1 CPU\(s\) \(3\), so nothing can be pinned"):
        ex.cpu_groups(2, True)
    assert ex.cpu_groups(2, None) is None  # not asked: one CPU, nothing to pin, no error
    assert ex.cpu_groups(1, None) is None  # one stack, one CPU: nothing to split
    with pytest.raises(ValueError, match="nothing can be pinned"):
        ex.cpu_groups(1, True)
    assert ex.cpus_option(frozenset({1}), {"--cpus"}) == ["--cpus", "1"]
    assert ex.cpus_option(frozenset({1}), set()) == []  # a launcher without the option
    assert ex.cpus_option(None, {"--cpus"}) == []


def test_each_worker_flies_its_runs_on_one_stack(fake, tmp_path: Path) -> None:
    done, flown = _run(tmp_path, workers=2)
    assert sorted(o.spec.key for o in done) == sorted(s.key for s in TABLE1)  # each once
    assert sorted(flown) == sorted(s.key for s in TABLE1)
    assert all(o.ok for o in done)
    assert len(fake.made) == 2 and all(s.closed for s in fake.made)
    assert {s.folder.name for s in fake.made} == {"stack-1", "stack-2"}
    # a run's folder is its stack's, and its episode says which part of the recording is its
    for s in fake.made:
        mine = [o for o in done if o.run_dir == str(s.folder)]
        assert [o.episode for o in mine] == list(range(len(mine)))


def test_one_worker_one_stack_longest_first(fake, tmp_path: Path) -> None:
    done, flown = _run(tmp_path, workers=1)
    assert len(done) == 15 and len(fake.made) == 1
    assert flown == [s.key for s, _ in ex.longest_first((s, tmp_path) for s in TABLE1)]
    assert [k.endswith("nmpc") for k in flown[-5:]] == [True] * 5


def test_a_failed_run_stops_its_stack_and_the_next_run_starts_a_new_one(fake, tmp_path: Path) -> None:
    fake.FAILING = {"paper-c3-eo-empc"}
    done, _ = _run(tmp_path, workers=1)
    by_key = {o.spec.key: o for o in done}
    assert len(done) == 15
    assert not by_key["paper-c3-eo-empc"].ok and "timed out" in by_key["paper-c3-eo-empc"].error
    assert all(o.ok for k, o in by_key.items() if k != "paper-c3-eo-empc")
    assert len(fake.made) == 2  # the runs after it on a stack of their own
    assert [s.folder.name for s in fake.made] == ["stack-1", "stack-2"]


def test_the_launchers_output_read_on_its_own_thread(tmp_path: Path) -> None:
    feed = io.StringIO("seaway launch sim-batch: vessel vessel1\nall ready in 1.5 s\n"
                       "mission paper-c1: accepted (nmpc, tau_d = 0, T^w 0.49 W)\n")
    log = ex.LauncherLog(feed, tmp_path / "launch.log", time.monotonic())
    assert log.wait(["refused", "accepted"], 5.0) == "accepted"
    log.join(5.0)
    assert log.ready_reported_s == 1.5 and set(log.seen) == {"ready", "accepted"}
    assert log.wait(["complete"]) is None  # the output ended without it: no waiting for ever
    assert log.line_with("accepted").startswith("mission paper-c1")
    text = (tmp_path / "launch.log").read_text().splitlines()
    assert len(text) == 3 and text[1].split(None, 1)[1] == "all ready in 1.5 s"


def test_waiting_on_a_launcher_that_says_nothing_times_out(tmp_path: Path) -> None:
    r, w = _pipe()
    log = ex.LauncherLog(r, tmp_path / "launch.log", time.monotonic())
    t0 = time.monotonic()
    assert log.wait(["accepted"], 0.2) is None
    assert time.monotonic() - t0 >= 0.2
    w.write("mission x: REFUSED: no\n")
    w.flush()
    assert log.wait(["refused", "accepted"], 5.0) == "refused"
    w.close()
    log.join(5.0)


def _pipe():
    rfd, wfd = os.pipe()
    return os.fdopen(rfd, "r"), os.fdopen(wfd, "w")


def test_the_cpu_of_each_run_is_what_its_stack_spent_while_it_flew() -> None:
    # CpuMonitor.snapshot gives totals so far; SharedStack takes differences. Here on this process.
    with ex.CpuMonitor(os.getpid(), interval_s=10.0) as mon:
        a = mon.snapshot()
        t0 = time.process_time()
        while time.process_time() - t0 < 0.2:
            pass
        b = mon.snapshot()
    assert b["launch"] - a["launch"] >= 0.15


def test_a_run_is_the_last_episode_that_accepted_its_mission() -> None:
    assert ex.run_episode([3], "k") == 3
    # The sim restarted mid-run (in the run's own scenario: seaway_sim.kept), and the controller
    # flew the mission again: the last episode is the one flown to its end.
    assert ex.run_episode([2, 3], "k") == 3
    with pytest.raises(ValueError, match="no episode of the recording accepted mission k"):
        ex.run_episode([], "k")


def test_a_stack_is_stopped_once(tmp_path: Path) -> None:
    """A failed run stops its stack; closing it after must not stop it again (it gave the run
    before the failed one the failed one's exit code, stop time and CPU)."""
    import subprocess

    stack = ex.SharedStack(tmp_path / "stack-1")
    stack.proc = subprocess.Popen(["sleep", "60"], start_new_session=True, text=True)
    failed = ex.RunOutcome(RunSpec("paper-c1", "nmpc", "#1", "nmpc"), str(stack.folder))
    stack.stop(failed)
    assert failed.returncode is not None and "stop_s" in failed.timing
    before = ex.RunOutcome(RunSpec("paper-c2", "nmpc", "#2", "nmpc"), str(stack.folder))
    stack.flown = [before]
    assert stack.close() == [before]  # reported (its recording is missing: said so)
    assert before.returncode is None and "stop_s" not in before.timing
    assert not before.ok and "report" in before.error
    out = stack.fly(RunSpec("paper-c3", "nmpc", "#3", "nmpc"))
    assert not out.ok and "the stack was stopped" in out.error


def test_no_stack_is_started_once_the_study_is_stopping(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(launcher, "_stopping", threading.Event())  # where _spawn and stop_all read it
    ex.stop_all()
    with pytest.raises(ex.StudyStoppingError, match="the study is stopping"):
        ex._spawn(["sleep", "60"], 20000)


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2, reason="needs two CPUs to pin to one")
def test_widening_a_stack_reaches_every_thread_of_every_process_in_it(tmp_path: Path) -> None:
    import subprocess
    import sys

    import psutil

    everything = frozenset(os.sched_getaffinity(0))
    one = frozenset({min(everything)})
    # A launcher pinned to one CPU (as --cpus does it) that started a service with two threads.
    service = ("import threading, time; threading.Thread(target=time.sleep, args=(60,)).start(); "
               "time.sleep(60)")
    launcher = (f"import os, subprocess, sys, time; os.sched_setaffinity(0, {set(one)}); "
                f"subprocess.Popen([sys.executable, '-c', {service!r}]); time.sleep(60)")
    stack = ex.SharedStack(tmp_path / "stack-1", cpus=one)
    stack.proc = subprocess.Popen([sys.executable, "-c", launcher], start_new_session=True, text=True)
    try:
        deadline = time.monotonic() + 30
        while not (kids := psutil.Process(stack.proc.pid).children()) or len(kids[0].threads()) < 2:
            assert time.monotonic() < deadline, "the stand-in service did not start"
            time.sleep(0.05)
        procs = [psutil.Process(stack.proc.pid), *kids]
        assert {frozenset(os.sched_getaffinity(t.id)) for p in procs for t in p.threads()} == {one}
        stack.widen(everything)
        assert {frozenset(os.sched_getaffinity(t.id)) for p in procs for t in p.threads()} == {everything}
        assert stack.cpus == everything
    finally:
        stack.stop()


def test_the_cpu_monitor_asks_for_the_stack_s_processes_every_few_polls(monkeypatch) -> None:
    """Which processes are under the launcher is asked every ``FIND_EVERY`` polls and at every
    snapshot (psutil reads every process's stat on the machine for it), and a process started
    between two askings is counted from its start."""
    import subprocess
    import sys

    import psutil

    asked = []
    real = psutil.Process.children
    monkeypatch.setattr(psutil.Process, "children",
                        lambda self, recursive=False: asked.append(1) or real(self, recursive=recursive))
    mon = ex.CpuMonitor(os.getpid(), interval_s=10.0)
    for _ in range(2 * ex.CpuMonitor.FIND_EVERY):
        mon._poll()
    assert len(asked) == 2
    child = subprocess.Popen([sys.executable, "-c",
                              "import time\nt = time.process_time()\n"
                              "while time.process_time() - t < 0.3: pass\ntime.sleep(30)"])
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            got = mon.snapshot()
            burnt = sum(v for k, v in got.items() if k != "launch")
            if burnt >= 0.25:
                break
            time.sleep(0.1)
        assert burnt >= 0.25, got
    finally:
        child.kill()
        child.wait()
