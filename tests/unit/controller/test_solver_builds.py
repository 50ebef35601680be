"""Solvers made in the background, only those a mission needs (issue 14, item 12).

The builds here are fakes gated by the test (``GatedBuild``), so nothing is compiled and nothing
depends on how long a compile takes: the test decides when a build finishes. One test runs the
real code generation with a C compiler that gets killed, as the launcher's stop kills it.
"""

from __future__ import annotations

import logging
import os
import signal
import stat
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from seaway.contract import keys
from seaway.runtime.clock import WallClock
from seaway.runtime.memory_bus import MemoryHub
from seaway.runtime.node import Period
from seaway.runtime.run import RunDescription
from seaway.runtime.runner import run_node
from seaway.runtime.service import ServiceContext
from seaway.vessel.model import load_vessel
from seaway.vessel.native import CompileInterruptedError
from seaway_controller.codegen import SQP_OPTIONS, build_shared_object
from seaway_controller.config import ControllerConfig
from seaway_controller.core import ControllerCore
from seaway_controller.node import ControllerNode
from seaway_controller.ocp import Ocp, OcpSpec
from seaway_controller.solver_builds import SolverBuilds, StagedSolver

from tests.conftest import wait_for
from tests.unit.controller.test_core import ScriptedSolver, mission, state
from tests.unit.controller.test_service_loop import VESSEL, World

VP = load_vessel("paper-sim")


class GatedBuild:
    """A solver 'build' that finishes when the test says (``release``), recording what was asked."""

    def __init__(self, fail: bool = False) -> None:
        self.asked: list[str] = []
        self.gates: dict[str, threading.Event] = {}
        self.fail = fail
        self.made: dict[str, ScriptedSolver] = {}

    def __call__(self, ocp: Ocp) -> ScriptedSolver:
        kind = ocp.spec.kind
        self.asked.append(kind)
        self.gates.setdefault(kind, threading.Event()).wait(10)
        if self.fail:
            raise RuntimeError("compiling the solver failed: (a fake error)")
        self.made[kind] = ScriptedSolver()
        return self.made[kind]

    def release(self, kind: str) -> None:
        self.gates.setdefault(kind, threading.Event()).set()


def problem(kind: str = "cc-empc") -> tuple[Ocp, tuple[np.ndarray, ...]]:
    ocp = Ocp(OcpSpec(kind, horizon=3), VP)
    p = ocp.parameters(np.array([0.03, 0.0, 0.0, 0.5, 0.4, 0.2]), (0.0, 0.0), (8.0, 0.0), True, 0.49)
    return ocp, (ocp.cold_guess(p), p, np.zeros(ocp.nw), np.zeros(ocp.ng))


class GatedReference:
    """A reference 'set-up' (IPOPT's takes about a second) that finishes when the test says."""

    def __init__(self, fail: bool = False) -> None:
        self.gate, self.fail, self.solver = threading.Event(), fail, ScriptedSolver()
        self.thread: str | None = None

    def __call__(self, _ocp: Ocp) -> ScriptedSolver:
        self.thread = threading.current_thread().name
        self.gate.wait(10)
        if self.fail:
            raise RuntimeError("no IPOPT here (a fake error)")
        return self.solver


def test_real_time_flies_with_the_reference_until_the_fast_solver_is_made() -> None:
    build, reference = GatedBuild(), GatedReference()
    builds = SolverBuilds(build)
    ocp, args = problem()
    staged = StagedSolver(ocp, builds, reference=reference)
    wait_for(lambda: build.asked, 5, what="the build to start")
    # The reference is set up on a thread of its own, not in the control loop: the solve does
    # not wait for it, it fails at once, saying why (the controller's fallbacks fly meanwhile).
    res = staged.solve(*args)
    assert not res.success and res.solve_time_s == 0.0
    assert res.status == ("no solver yet (the reference IPOPT is being set up; the generated "
                          "solver is being made)")
    np.testing.assert_array_equal(res.w, args[0])
    wait_for(lambda: reference.thread is not None, 5, what="the reference's set-up to start")
    assert reference.thread != threading.current_thread().name
    reference.gate.set()
    wait_for(lambda: staged.solve(*args).success, 5, what="the reference to be set up")
    assert reference.solver.calls == 1
    res = staged.solve(*args)
    assert res.success and reference.solver.calls == 2
    assert res.status == "Solve_Succeeded (reference IPOPT: the generated solver is being made)"
    assert "its cc-empc solver is being made" in builds.describe("cc-empc")
    build.release("cc-empc")
    wait_for(lambda: builds.ready("cc-empc") is not None, 5, what="the build to finish")
    assert staged.solve(*args).status == "Solve_Succeeded" and reference.solver.calls == 2
    assert build.made["cc-empc"].calls == 1 and builds.describe("cc-empc") == ""


class WaitSpy(SolverBuilds):
    """Real builds whose ``wait`` records its timeout; ``finish``: the build finishes during it (as
    a solver loaded from the cache does, in milliseconds, while a mission's first period runs)."""

    def __init__(self, build: GatedBuild, finish: bool) -> None:
        super().__init__(build)
        self.gated, self.finish, self.waits = build, finish, []

    def wait(self, kind: str, timeout_s: float | None = None) -> bool:
        self.waits.append(timeout_s)
        if self.finish:
            self.gated.release(kind)
        return super().wait(kind, timeout_s)


def test_a_missions_first_solve_waits_a_little_for_its_solver_and_only_the_first() -> None:
    from seaway_controller.solver_builds import FIRST_SOLVE_WAIT_S

    ocp, args = problem()
    loading = WaitSpy(GatedBuild(), finish=True)
    staged = StagedSolver(ocp, loading, reference=GatedReference())
    wait_for(lambda: loading.gated.asked, 5, what="the build to start")
    res = staged.solve(*args)  # the solver became ready while the first solve waited: flown
    assert res.success and res.status == "Solve_Succeeded"
    assert loading.waits == [FIRST_SOLVE_WAIT_S] and loading.gated.made["cc-empc"].calls == 1

    compiling = WaitSpy(GatedBuild(), finish=False)  # a compile: still being made after the wait
    staged = StagedSolver(ocp, compiling, reference=GatedReference())
    wait_for(lambda: compiling.gated.asked, 5, what="the build to start")
    for _ in range(3):
        assert staged.solve(*args).status.startswith("no solver yet")
    assert compiling.waits == [FIRST_SOLVE_WAIT_S]  # the later solves fail at once
    compiling.gated.release("cc-empc")


def test_a_reference_that_cannot_be_set_up_is_named_and_not_tried_again(caplog) -> None:
    build, reference = GatedBuild(), GatedReference(fail=True)
    staged = StagedSolver(problem()[0], SolverBuilds(build), reference=reference)
    args = problem()[1]
    reference.gate.set()
    with caplog.at_level(logging.ERROR, "seaway_controller.solver_builds"):
        staged.solve(*args)
        wait_for(lambda: "could not be set up" in staged.solve(*args).status, 5,
                 what="the set-up to fail")
    res = staged.solve(*args)
    assert not res.success and res.status == (
        "no solver yet (the reference IPOPT could not be set up: RuntimeError: no IPOPT here (a "
        "fake error); the generated solver is being made)")
    assert caplog.text.count("could not set up the reference IPOPT for cc-empc") == 1
    build.release("cc-empc")


def test_a_solver_that_cannot_be_made_leaves_the_reference_flying(caplog) -> None:
    build, reference = GatedBuild(fail=True), ScriptedSolver()
    builds = SolverBuilds(build)
    ocp, args = problem()
    staged = StagedSolver(ocp, builds, reference=lambda _ocp: reference, wait=True)
    build.release("cc-empc")
    with caplog.at_level(logging.ERROR, "seaway_controller.solver_builds"):
        res = staged.solve(*args)  # lockstep waits for the build, then falls back as it failed
    assert res.status.endswith("(reference IPOPT: the generated solver is unavailable)")
    assert "could not make the cc-empc solver" in caplog.text
    assert "could not be made" in builds.describe("cc-empc")


def lockstep_controller(build: GatedBuild):
    """A lockstep controller on the in-memory bus whose fast solvers are made by ``build``."""
    hub = MemoryHub()
    bus = hub.bus(VESSEL)
    stop = threading.Event()
    ctx = ServiceContext(name="controller", vessel=VESSEL, bus=bus, clock=WallClock(), stop=stop,
                         run=RunDescription(run_id="unit", vessel=VESSEL, clock="lockstep"))
    builds = SolverBuilds(build, stopping=stop)
    core = ControllerCore(VP, ControllerConfig(solve_budget_s=None),
                          solver_factory=lambda ocp: StagedSolver(ocp, builds, wait=True))
    node = ControllerNode(core, builds=builds)
    loop = threading.Thread(target=run_node, args=(ctx, node, 0.1), daemon=True)
    loop.start()
    wait_for(lambda: ctx.is_ready, 5, what="the controller to be ready")
    return hub, stop, loop


def test_lockstep_holds_while_the_missions_solver_is_made_and_only_that_one() -> None:
    build = GatedBuild()
    hub, stop, loop = lockstep_controller(build)
    try:
        world = World(hub)
        operator = hub.bus(VESSEL)
        world.period(0, state(0))  # idle: hold
        reply = operator.request(keys.MISSION_SET, mission("nmpc"), timeout_s=10.0)
        assert reply.accepted, reply.reason
        assert "its nmpc solver is being made" in reply.reason
        assert "simulated time holds until it is ready" in reply.reason
        # The held period is thought again for the mission: still held, for its solver.
        held = world.next_answer(Period(0, 0))
        assert held.hold and keys.THRUST.suffix not in held.published
        status = world.status.drain()[-1]
        assert status.state == "active" and status.reason.startswith(
            "simulated time holds: its nmpc solver is being made")
        assert world.thrust.drain() == []
        build.release("nmpc")
        # Once made, the same period is answered again, now with the command.
        flown = world.next_answer(Period(0, 0))
        assert not flown.hold and flown.published[keys.THRUST.suffix] == [0]
        assert world.thrust.get(1.0).source == "nmpc"
        for k in range(1, 4):
            assert not world.period(k, state(k)).hold
        assert build.asked == ["nmpc"]  # only what the mission needs
        assert build.made["nmpc"].calls == 4
    finally:
        stop.set()
        loop.join(2.0)
    assert not loop.is_alive()


def test_a_compiler_killed_by_a_stop_is_not_a_compile_error(tmp_path: Path, monkeypatch) -> None:
    """The launcher stops a controller by SIGINT to its process group, gcc included: that is an
    interrupted build, which must not be reported as the compiler failing."""
    fake = tmp_path / "bin" / "gcc"
    fake.parent.mkdir()
    # Python, not sh: a suite started in the background (``./test &``, nohup) inherits SIGINT
    # ignored, and a shell may not undo that, so a shell's ``kill -INT $$`` did nothing there.
    fake.write_text(f"#!{sys.executable}\nimport os, signal, time\n"
                    "signal.signal(signal.SIGINT, signal.SIG_DFL)\n"
                    "os.kill(os.getpid(), signal.SIGINT)\ntime.sleep(5)\n")
    fake.chmod(fake.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    ocp = Ocp(OcpSpec("eo-empc", horizon=3), VP)
    with pytest.raises(CompileInterruptedError) as err:
        build_shared_object(ocp, SQP_OPTIONS, tmp_path / "cache")
    text = str(err.value)
    assert f"stopped by {signal.SIGINT.name}" in text and "not a compile error" in text
    assert "failed" not in text
    assert not list((tmp_path / "cache").glob("*.so"))


def test_real_time_starts_a_mission_once_its_cached_solver_is_loaded() -> None:
    """A warm-cache run logged "fallback level 2 ... the solver is being made" at a mission's start
    and its report counted a failed solve: the mission started at once, and its first period came
    while its solver was still being loaded. The mission now starts once its solver is there (the
    control loop goes on meanwhile), and a solver being loaded is said to be loaded, not made."""
    from seaway.contract.messages import SOLVER_NOT_READY

    build = GatedBuild()
    hub = MemoryHub()
    stop = threading.Event()
    ctx = ServiceContext(name="controller", vessel=VESSEL, bus=hub.bus(VESSEL), clock=WallClock(),
                         stop=stop, run=RunDescription(run_id="unit", vessel=VESSEL))
    builds = SolverBuilds(build, stopping=stop, cached=lambda _ocp: True)
    core = ControllerCore(VP, ControllerConfig(solve_budget_s=None),
                          solver_factory=lambda ocp: StagedSolver(ocp, builds,
                                                                  reference=GatedReference()))
    node = ControllerNode(core, builds=builds, max_state_age_s=0.5)
    observer = hub.bus(VESSEL)
    thrust = observer.subscribe(keys.THRUST, mode="fifo")
    solves = observer.subscribe(keys.SOLVE, mode="fifo")
    nav = hub.bus(VESSEL).publisher(keys.NAV_STATE)
    loop = threading.Thread(target=run_node, args=(ctx, node, 1 / 50.0), daemon=True)
    feeder_stop = threading.Event()

    def feed() -> None:  # fresh states, as the estimator publishes them
        while not feeder_stop.wait(0.02):
            nav.put(state(0).model_copy(update={"stamp_ns": ctx.clock.now_ns()}))

    feeder = threading.Thread(target=feed, daemon=True)
    replies: list = []
    operator = hub.bus(VESSEL)
    asking = threading.Thread(target=lambda: replies.append(
        operator.request(keys.MISSION_SET, mission(), timeout_s=10.0)), daemon=True)
    try:
        loop.start()
        wait_for(lambda: ctx.is_ready, 5, what="the controller to be ready")  # requests served
        feeder.start()
        asking.start()
        wait_for(lambda: build.asked, 5, what="the mission's solver to be asked for")
        assert "its cc-empc solver is being loaded" in builds.describe("cc-empc")
        seen: list = []
        # The loop goes on while the solver loads, the mission not started yet (zero thrust).
        wait_for(lambda: seen.extend(thrust.drain()) or len(seen) >= 10, 10,
                 what="the loop's commands while the solver loads")
        assert {c.source for c in seen} == {"idle"}
        build.release("cc-empc")
        asking.join(10)
        assert replies and replies[0].accepted, replies
        wait_for(lambda: seen.extend(thrust.drain()) or any(c.source == "cc-empc" for c in seen),
                 10, what="the mission flown with its solver")
        records = solves.drain()
        assert records and all(r.success and r.fallback_level == 0 for r in records), \
            [(r.status, r.fallback_level) for r in records[:3]]
        assert not any(r.status.startswith(SOLVER_NOT_READY) for r in records)
    finally:
        feeder_stop.set()
        stop.set()
        build.release("cc-empc")
        loop.join(5)
        for bus in (ctx.bus, observer, operator):
            bus.close()
    assert not loop.is_alive()
