"""NLP solvers for the OCPs: a generated SQP (the fast path) and plain IPOPT (the reference).

Fast path (solver-notes.md, the measured best configuration): CasADi ``sqpmethod`` with the ``qrqp``
active-set QP, generated as C, patched, compiled once and cached (``codegen``), then called through
ctypes so that the outputs survive a failed solve and the call costs microseconds.

Success is decided from this call's own results, never from a stale status (trap 3): the generated
function's return flag, plus the primal and dual infeasibilities of the returned point as the
solver's own convergence test computed them (``codegen`` patches the C to export them).

Reference: ``nlpsol('ipopt')`` with default options, the configuration most examples use. A process
that makes its fast solvers in the background flies on the reference meanwhile (``solver_builds``).
"""

from __future__ import annotations

import ctypes
import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import casadi as ca
import numpy as np

from seaway_controller.codegen import (
    ERROR_CONVEXIFY,
    ERROR_EVALUATION,
    N_IN,
    N_OUT,
    SQP_OPTIONS,
    SQP_TOL,
    SYMBOL,
    build_shared_object,
)
from seaway_controller.ocp import NP, Ocp

log = logging.getLogger("seaway_controller.solvers")


@dataclass
class SolveResult:
    """One solve's outcome; arrays are the solver's raw (scaled) NLP variables."""

    w: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    objective: float
    success: bool
    status: str
    iterations: int
    solve_time_s: float
    interior_point: bool = False
    """Solved by an interior-point method (the reference IPOPT). Its multipliers are not a warm
    start for the SQP: IPOPT leaves every bound a small positive multiplier, so the active-set QP
    starts from the wrong active set and stalls (``not_converged``, seen when a real-time mission's
    first solve came before the generated solver was loaded). ``MpcController`` warm-starts the
    primal only from such a plan."""


class NlpSolver(Protocol):
    name: str

    def solve(self, w0: np.ndarray, p: np.ndarray, lam_x0: np.ndarray,
              lam_g0: np.ndarray) -> SolveResult: ...


@dataclass
class _Library:
    """One loaded solver library: its entry point, its memory slot and its statistics array.

    The generated code keeps static memory (one slot: CASADI_MAX_NUM_THREADS is 1), and dlopen
    returns the same handle for the same file, so each file is loaded and checked out once per
    process and shared by every solver object on it, calls serialised by ``lock``.
    """

    fn: Any
    mem: int
    stats: Any
    kkt_stats: Any  # [factorised, reused] since loading, or None without the KKT reuse patch
    sizes: tuple[int, int, int, int]
    lock: threading.Lock


_LIBRARIES: dict[str, _Library] = {}
_LIBRARIES_LOCK = threading.Lock()


def _load_library(path: Path) -> _Library:
    with _LIBRARIES_LOCK:
        key = str(path.resolve())
        if key in _LIBRARIES:
            return _LIBRARIES[key]
        lib = ctypes.CDLL(key)
        fn = getattr(lib, SYMBOL)
        fn.restype = ctypes.c_int
        fn.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
        sizes = [ctypes.c_longlong() for _ in range(4)]
        if getattr(lib, f"{SYMBOL}_work")(*(ctypes.byref(s) for s in sizes)) != 0:
            raise RuntimeError(f"{path.name}: work-size query failed")
        getattr(lib, f"{SYMBOL}_incref")()
        checkout = getattr(lib, f"{SYMBOL}_checkout")
        checkout.restype = ctypes.c_int
        mem = checkout()
        if mem < 0:
            raise RuntimeError(f"{path.name}: no memory slot available")
        stats = lib.seaway_solver_stats
        stats.restype = ctypes.POINTER(ctypes.c_double)
        kkt_stats = getattr(lib, "seaway_kkt_stats", None)
        if kkt_stats is not None:
            kkt_stats.restype = ctypes.POINTER(ctypes.c_double)
        loaded = _Library(fn, mem, stats(), kkt_stats() if kkt_stats is not None else None,
                          tuple(s.value for s in sizes),  # type: ignore[arg-type]
                          threading.Lock())
        _LIBRARIES[key] = loaded
        return loaded


class GeneratedSqpSolver:
    """The compiled SQP, called through ctypes with preallocated buffers."""

    def __init__(self, ocp: Ocp, options: dict | None = None,
                 directory: Path | None = None, kkt_reuse: bool = True) -> None:
        self.ocp = ocp
        self.options = dict(SQP_OPTIONS if options is None else options)
        self.name = f"{ocp.spec.kind}/sqp-qrqp-generated"
        self.path = build_shared_object(ocp, self.options, directory, kkt_reuse)
        self._lib = _load_library(self.path)
        self._fn, self._stats = self._lib.fn, self._lib.stats
        sz_arg, sz_res, sz_iw, sz_w = self._lib.sizes
        nw, ng, npar = ocp.nw, ocp.ng, NP
        # Input and output buffers, in the order of nlpsol's scheme.
        self._in = [np.zeros(n) for n in (nw, npar, nw, nw, ng, ng, nw, ng)]
        self._out = [np.zeros(n) for n in (nw, 1, ng, nw, ng, npar)]
        self._in[2][:], self._in[3][:] = ocp.lbw, ocp.ubw
        self._in[4][:], self._in[5][:] = ocp.lbg, ocp.ubg
        self._arg = (ctypes.c_void_p * max(sz_arg, N_IN))()
        self._res = (ctypes.c_void_p * max(sz_res, N_OUT))()
        for i, a in enumerate(self._in):
            self._arg[i] = a.ctypes.data
        for i, r in enumerate(self._out):
            self._res[i] = r.ctypes.data
        self._iw = np.zeros(max(sz_iw, 1), dtype=np.int64)
        self._w = np.zeros(max(sz_w, 1))
        self._call_args = (ctypes.cast(self._arg, ctypes.c_void_p),
                           ctypes.cast(self._res, ctypes.c_void_p),
                           self._iw.ctypes.data, self._w.ctypes.data, self._lib.mem)
        self.tol_pr = float(self.options.get("tol_pr", SQP_TOL))
        self.tol_du = float(self.options.get("tol_du", SQP_TOL))

    def kkt_counts(self) -> tuple[int, int] | None:
        """(KKT factorisations done, reused) by this library since it was loaded; None if unpatched."""
        k = self._lib.kkt_stats
        return None if k is None else (int(k[0]), int(k[1]))

    def solve(self, w0: np.ndarray, p: np.ndarray, lam_x0: np.ndarray,
              lam_g0: np.ndarray) -> SolveResult:
        self._in[0][:] = w0
        self._in[1][:] = p
        self._in[6][:] = lam_x0
        self._in[7][:] = lam_g0
        with self._lib.lock:
            for i in range(3):
                self._stats[i] = -1.0
            self._stats[3] = 0.0
            t0 = time.perf_counter()
            flag = self._fn(*self._call_args)
            elapsed = time.perf_counter() - t0
            iters, pr_inf, du_inf, failed_at = (self._stats[i] for i in range(4))
        finite = bool(np.isfinite(self._out[0]).all())  # the method: no dispatch layers
        converged = 0 <= pr_inf < self.tol_pr and 0 <= du_inf < self.tol_du
        success = flag == 0 and finite and converged
        if success:
            status = "Solve_Succeeded"
        elif flag == -1000:
            status = "qp_failed"
        elif flag != 0 and failed_at == ERROR_CONVEXIFY:
            status = "convexify_failed"  # eigen-clip's eigenvalue iteration did not converge
        elif flag != 0 and failed_at == ERROR_EVALUATION:
            status = "evaluation_failed"  # f, g or a derivative was not finite
        elif flag != 0:
            status = f"solver_error_flag_{flag}"
        elif not finite:
            status = "non_finite_solution"
        elif iters >= self.options.get("max_iter", 50):
            status = "Maximum_Iterations_Exceeded"
        else:
            status = f"not_converged(pr_inf={pr_inf:.2e},du_inf={du_inf:.2e})"
        return SolveResult(self._out[0].copy(), self._out[3].copy(), self._out[4].copy(),
                           float(self._out[1][0]), success, status, max(int(iters), 0), elapsed)


class IpoptSolver:
    """Plain IPOPT with default options (output silenced): the robust, slow reference.

    ``time_limit_s``: stop a solve after this long (IPOPT's ``max_wall_time``; the result then
    fails with status ``Maximum_WallTime_Exceeded``). Real time solves on the control loop's
    thread, and IPOPT's own limit is 3000 iterations, not a time: without one a hard solve keeps
    the vessel without a command for as long as it runs."""

    def __init__(self, ocp: Ocp, options: dict | None = None,
                 time_limit_s: float | None = None) -> None:
        self.ocp = ocp
        self.name = f"{ocp.spec.kind}/ipopt"
        opts: dict = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes"}
        if time_limit_s is not None:
            if not time_limit_s > 0:
                raise ValueError(f"time_limit_s must be > 0 s, got {time_limit_s}")
            opts["ipopt.max_wall_time"] = float(time_limit_s)
        opts.update(options or {})
        self._solver = ca.nlpsol("ipopt_ref", "ipopt", ocp.nlp, opts)

    def solve(self, w0: np.ndarray, p: np.ndarray, lam_x0: np.ndarray,
              lam_g0: np.ndarray) -> SolveResult:
        o = self.ocp
        t0 = time.perf_counter()
        sol = self._solver(x0=w0, p=p, lbx=o.lbw, ubx=o.ubw, lbg=o.lbg, ubg=o.ubg,
                           lam_x0=lam_x0, lam_g0=lam_g0)
        elapsed = time.perf_counter() - t0
        stats = self._solver.stats()
        return SolveResult(np.asarray(sol["x"]).ravel(), np.asarray(sol["lam_x"]).ravel(),
                           np.asarray(sol["lam_g"]).ravel(), float(sol["f"]),
                           bool(stats.get("success", False)), str(stats.get("return_status", "")),
                           int(stats.get("iter_count", 0)), elapsed, interior_point=True)


SolverKind = str
SOLVERS: dict[SolverKind, Callable[[Ocp], NlpSolver]] = {
    "generated": GeneratedSqpSolver,  # the fast path
    "ipopt": IpoptSolver,  # the reference
}
"""Every solver by name; the command line's choices and the config's values come from here."""
SOLVER_KINDS: tuple[SolverKind, ...] = tuple(SOLVERS)


def make_solver(ocp: Ocp, kind: SolverKind = "generated") -> NlpSolver:
    """The solver named ``kind`` for ``ocp``: 'generated' (fast SQP) or 'ipopt' (reference)."""
    try:
        factory = SOLVERS[kind]
    except KeyError:
        raise ValueError(f"unknown solver {kind!r}; known: {', '.join(SOLVER_KINDS)}") from None
    return factory(ocp)
