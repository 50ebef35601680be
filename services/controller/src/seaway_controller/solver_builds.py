"""The fast solvers of one process, made in the background (``SolverBuilds``: compiled on first use
on this machine, then loaded from the cache), and the solver a controller flies meanwhile
(``StagedSolver``: the fast one once it is ready, else the reference IPOPT).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from seaway.contract.messages import SOLVER_NOT_READY
from seaway.vessel.native import CompileInterruptedError, cache_dir

from seaway_controller.codegen import SQP_OPTIONS, shared_object_path
from seaway_controller.ocp import Ocp
from seaway_controller.solvers import GeneratedSqpSolver, IpoptSolver, NlpSolver, SolveResult

log = logging.getLogger("seaway_controller.solver_builds")

PROGRESS_LOG_S = 15.0
"""While a build runs, say so this often (a first compile on a loaded machine can take minutes)."""


@dataclass
class _Build:
    kind: str
    started_s: float
    done: threading.Event = field(default_factory=threading.Event)
    solver: NlpSolver | None = None
    error: str = ""
    seconds: float = 0.0
    loading: bool = False  # from the cache (milliseconds), not compiled (seconds to minutes)


class SolverBuilds:
    """The fast solvers of one process, each made the first time a mission needs it (compiled, or
    loaded from the cache) on a thread of its own, so that the process serves meanwhile.

    Only what is asked for is built: a mission's controller, when the mission is accepted. ``build``
    makes one solver (default ``GeneratedSqpSolver``); ``on_done(kind)`` is called, on the build's
    thread, once it is ready or has failed. ``describe`` says where each one is, for people.
    A compiler killed because the process is stopping is said to be that, not a compile error.
    """

    def __init__(self, build: Callable[[Ocp], NlpSolver] = GeneratedSqpSolver,
                 on_done: Callable[[str], None] | None = None,
                 stopping: threading.Event | None = None,
                 cached: Callable[[Ocp], bool] | None = None) -> None:
        self._build_fn = build
        # Whether a build only loads a cached solver (said as such, not as a compile).
        self._cached = cached or (_generated_is_cached if build is GeneratedSqpSolver
                                  else lambda _ocp: False)
        self.on_done = on_done
        self._stopping = stopping or threading.Event()
        self._builds: dict[str, _Build] = {}
        self._lock = threading.Lock()
        self._monitor: threading.Thread | None = None

    def request(self, ocp: Ocp) -> None:
        """Start making ``ocp``'s solver unless it is made or being made."""
        kind = ocp.spec.kind
        with self._lock:
            if kind in self._builds:
                return
            b = self._builds[kind] = _Build(kind, time.monotonic())
            if self._monitor is None:
                self._monitor = threading.Thread(target=self._report, name="solver-builds",
                                                 daemon=True)
                self._monitor.start()
        log.info("making the %s solver in the background (compiled on first use on this machine, "
                 "then loaded from %s)", kind, cache_dir())
        threading.Thread(target=self._run, args=(b, ocp), name=f"build-{kind}", daemon=True).start()

    def _run(self, b: _Build, ocp: Ocp) -> None:
        try:
            b.loading = self._cached(ocp)
            b.solver = self._build_fn(ocp)
        except CompileInterruptedError as err:
            b.error = str(err)
            log.info("%s", err)
        except Exception as err:  # the process keeps serving (with the reference solver)
            b.error = f"{type(err).__name__}: {err}"
            if self._stopping.is_set():
                log.info("making the %s solver stopped with the process: %s", b.kind, b.error)
            else:
                log.error("could not make the %s solver: %s", b.kind, b.error)
        b.seconds = time.monotonic() - b.started_s
        if b.solver is not None:
            log.info("%s solver ready in %.1f s", b.kind, b.seconds)
        b.done.set()
        if self.on_done is not None:
            self.on_done(b.kind)

    def _report(self) -> None:
        while not self._stopping.wait(PROGRESS_LOG_S):
            with self._lock:
                pending = [b for b in self._builds.values() if not b.done.is_set()]
            for b in pending:
                log.info("still making the %s solver (%.0f s so far)", b.kind,
                         time.monotonic() - b.started_s)

    def ready(self, kind: str) -> NlpSolver | None:
        """The made solver of ``kind``, or None (not asked for, being made, or failed)."""
        b = self._builds.get(kind)
        return b.solver if b is not None and b.done.is_set() else None

    def pending(self, kind: str) -> bool:
        """Whether ``kind``'s solver is being made now."""
        b = self._builds.get(kind)
        return b is not None and not b.done.is_set()

    def failed(self, kind: str) -> str | None:
        """Why ``kind``'s solver could not be made, or None."""
        b = self._builds.get(kind)
        return b.error if b is not None and b.done.is_set() and b.solver is None else None

    def wait(self, kind: str, timeout_s: float | None = None) -> bool:
        b = self._builds.get(kind)
        return b is None or b.done.wait(timeout_s)

    def doing(self, kind: str) -> str:
        """'being loaded' (from the cache) or 'being made' (compiled) while ``kind``'s solver is
        pending; 'unavailable' otherwise."""
        b = self._builds.get(kind)
        if b is None or b.done.is_set():
            return "unavailable"
        return "being loaded" if b.loading else "being made"

    def describe(self, kind: str) -> str:
        """Where ``kind``'s solver is, in a few words ('' when it is ready or was never asked for)."""
        b = self._builds.get(kind)
        if b is None or b.solver is not None:
            return ""
        if not b.done.is_set():
            return (f"its {kind} solver is {self.doing(kind)} "
                    f"({time.monotonic() - b.started_s:.0f} s so far)")
        return f"its {kind} solver could not be made ({b.error[:120]})"

    @property
    def kinds(self) -> list[str]:
        """Every kind asked for so far, in order."""
        return list(self._builds)


FIRST_SOLVE_WAIT_S = 0.05
"""How long a real-time mission's first solve waits for its fast solver still being made [s]: one
loaded from the cache takes milliseconds (logged "ready in 0.0 s"), and the first period of a
mission came while it loaded, flying one period of fallback (with its WARNING) for a race of 1 ms.
A compile takes seconds to minutes: after this the fallbacks fly, and no later solve waits. Well
inside the control period (0.1 s) and the solve budget."""


class StagedSolver:
    """One OCP's solver in a process that makes its fast solvers in the background
    (``SolverBuilds``): the fast one once it is ready; until then, or if it cannot be made, the
    reference (``reference``, plain IPOPT), whose results say so in their status. ``wait``
    (lockstep, where results must not depend on how long a compile took): wait for the fast one
    instead, and use the reference only if it cannot be made. The caller usually asks
    ``SolverBuilds.pending`` first and does not solve meanwhile.

    Real time never waits: setting up IPOPT takes about a second (CasADi builds its derivatives),
    which in the control loop left the vessel without a command past vehicle_io's watchdog. So the
    reference is set up on a thread of its own the first time it is needed, and until it is
    ready a solve fails at once with a status that says why (the controller's fallbacks fly). Only
    the first solve waits, ``FIRST_SOLVE_WAIT_S`` at most, for a fast solver being loaded."""

    def __init__(self, ocp: Ocp, builds: SolverBuilds,
                 reference: Callable[[Ocp], NlpSolver] = IpoptSolver, wait: bool = False) -> None:
        self.ocp, self.builds, self.wait = ocp, builds, wait
        self.kind = ocp.spec.kind
        self.name = f"{self.kind}/staged"
        self._make_reference = reference
        self._reference: NlpSolver | None = None
        self._reference_error = ""
        self._reference_started_once = False
        self._waited_once = False
        builds.request(ocp)

    def solve(self, w0: np.ndarray, p: np.ndarray, lam_x0: np.ndarray,
              lam_g0: np.ndarray) -> SolveResult:
        fast = self.builds.ready(self.kind)
        if fast is None and (self.wait or not self._waited_once):
            self._waited_once = True
            self.builds.wait(self.kind, None if self.wait else FIRST_SOLVE_WAIT_S)
            fast = self.builds.ready(self.kind)
        if fast is not None:
            return fast.solve(w0, p, lam_x0, lam_g0)
        why = self.builds.doing(self.kind)
        reference = self._reference_now() if self.wait else self._reference_started()
        if reference is None:
            what = (f"could not be set up: {self._reference_error}" if self._reference_error
                    else "is being set up")
            return SolveResult(w0, lam_x0, lam_g0, float("nan"), False,
                               f"{SOLVER_NOT_READY} (the reference IPOPT {what}; the generated "
                               f"solver is {why})", 0, 0.0)
        res = reference.solve(w0, p, lam_x0, lam_g0)
        return replace(res, status=f"{res.status} (reference IPOPT: the generated solver is {why})")

    def _reference_now(self) -> NlpSolver | None:
        """Lockstep: the reference, set up here and now (time holds meanwhile)."""
        if self._reference is None and not self._reference_error:
            self._set_up_reference()
        return self._reference

    def _reference_started(self) -> NlpSolver | None:
        """Real time: the reference if it is set up; else start setting it up, and None."""
        if self._reference is None and not self._reference_started_once:
            self._reference_started_once = True
            threading.Thread(target=self._set_up_reference, name=f"reference-{self.kind}",
                             daemon=True).start()
        return self._reference

    def _set_up_reference(self) -> None:
        try:
            self._reference = self._make_reference(self.ocp)
        except Exception as err:  # the fallbacks fly on; say why once
            why = f"{type(err).__name__}: {err}"
            log.error("could not set up the reference IPOPT for %s: %s", self.kind, why)
            self._reference_error = why  # after the log: whoever reads it finds the log written


def _generated_is_cached(ocp: Ocp) -> bool:
    """Whether ``GeneratedSqpSolver(ocp)`` finds its compiled solver in the cache."""
    return shared_object_path(ocp, dict(SQP_OPTIONS)).is_file()
