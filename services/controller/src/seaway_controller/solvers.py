"""NLP solvers for the OCPs: a generated SQP (the fast path) and plain IPOPT (the reference).

Fast path (solver-notes.md, the measured best configuration): CasADi ``sqpmethod`` with the ``qrqp``
active-set QP, exact Hessian convexified by ``eigen-clip`` with ``max_iter_eig`` = 1e5 (at the default
it stops silently at waypoint turns), generated as C, compiled once with ``gcc -O3`` and cached by a
hash of the problem and the options, then called through ctypes so that the outputs survive a
failed solve and the call costs microseconds.

qrqp re-forms and re-factorises its KKT matrix at every active-set iteration, also when the active
set did not change, so that a QP which converges in one step pays for two sparse QR factorisations.
The generated C is patched to keep the last factorisation while the QP's active pattern is unchanged
(``_patch_kkt_reuse``): the same matrix gives the same factors, so the results are bit for bit those of
the unpatched code (the same closed loop), and a step costs less by the factorisations saved.

Success is decided from this call's own results, never from a stale status (trap 3): the generated
function's return flag, plus the primal and dual infeasibilities of the returned point as the
solver's own convergence test computed them. CasADi 3.8's generated ``sqpmethod`` returns 0 at its
iteration limit, so the flag alone is not enough; the C is patched (checked, anchored edits) to export
the iteration count and those two residuals. eigen-clip's eigenvalue iteration is patched too, to step
on the right block (``cvx_patch``: CasADi's could exhaust ``max_iter_eig`` on close eigenvalues). The
cache key covers the patches' code (``_patch_digest``).

Reference: ``nlpsol('ipopt')`` with default options, the configuration most examples use.
"""

from __future__ import annotations

import ctypes
import hashlib
import inspect
import logging
import re
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import casadi as ca
import numpy as np
from seaway.contract.messages import SOLVER_NOT_READY
from seaway.vessel.native import CompileInterruptedError, cache_dir, compile_shared

from seaway_controller import cvx_patch
from seaway_controller.ocp import NP, Ocp, spec_digest

log = logging.getLogger("seaway_controller.solvers")

CC_FLAGS = ("-O3", "-fPIC", "-shared", "-fno-semantic-interposition")
"""-fno-semantic-interposition: the generated helpers (casadi_qr, casadi_cvx, ...) are global symbols;
without it every call between them goes through the PLT and none is inlined (the results are
identical either way)."""
SYMBOL = "seaway_nlp"
N_IN, N_OUT = 8, 6  # x0, p, lbx, ubx, lbg, ubg, lam_x0, lam_g0 -> x, f, g, lam_x, lam_g, lam_p

SQP_TOL = 1e-6
SQP_OPTIONS: dict = {
    "qpsol": "qrqp",
    "qpsol_options": {"print_iter": False, "print_header": False, "print_info": False,
                      "error_on_fail": False},
    "hessian_approximation": "exact",
    "convexify_strategy": "eigen-clip",
    "max_iter_eig": 100000,
    "max_iter": 50,
    "tol_pr": SQP_TOL,
    "tol_du": SQP_TOL,
    "print_header": False,
    "print_iteration": False,
    "print_status": False,
    "error_on_fail": True,
}

_STATS_DECL = "static casadi_real seaway_stats[4] = {-1.0, -1.0, -1.0, 0.0};\n"
_STATS_SET = ("\n  seaway_stats[0] = (casadi_real) iter_count; seaway_stats[1] = pr_inf;"
              " seaway_stats[2] = du_inf;")
_STATS_EXPORT = ("\nCASADI_SYMBOL_EXPORT casadi_real* seaway_solver_stats(void) "
                 "{ return seaway_stats; }\n")
_SQP_ANCHOR = "casadi_int iter_count=0, ls_iter=0;"


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


ERROR_EVALUATION, ERROR_CONVEXIFY = 1.0, 2.0
"""Codes in seaway_stats[3]: which step made the generated SQP return 1 (0: none)."""
_FAIL_RETURN = re.compile(r"if \((casadi_(f\d+|convexify_eval)\([^;]*\))\) return 1;")


def _tag_failure(match: re.Match[str]) -> str:
    code = ERROR_CONVEXIFY if match.group(2) == "convexify_eval" else ERROR_EVALUATION
    return f"if ({match.group(1)}) {{ seaway_stats[3] = {code}; return 1; }}"


def patch_generated_source(src: str) -> str:
    """Export the SQP's iteration count, final residuals and failing step; fail loudly if CasADi
    changed the code's shape."""
    if src.count(_SQP_ANCHOR) != 1:
        raise RuntimeError("generated sqpmethod code has an unexpected shape (iteration counter not "
                           f"found once); CasADi {ca.__version__} is not supported by this patch")
    at = src.index(_SQP_ANCHOR)
    fn_start = src.rfind("\nstatic int ", 0, at)
    end = src.find("\n  return 0;\n}\n", at)
    if fn_start < 0 or end < 0 or "pr_inf" not in src[at:end] or "du_inf" not in src[at:end]:
        raise RuntimeError("generated sqpmethod code has an unexpected shape (no final return or "
                           "residuals); cannot export solver statistics")
    body, n_tagged = _FAIL_RETURN.subn(_tag_failure, src[at:end])
    if n_tagged == 0:
        raise RuntimeError("generated sqpmethod code has an unexpected shape (no error returns)")
    src = src[:at] + body + _STATS_SET + src[end:]
    src = src[:fn_start + 1] + _STATS_DECL + src[fn_start + 1:]
    return src + _STATS_EXPORT


_FACTORIZE_BODY = """  casadi_qrqp_kkt(d);
  casadi_qr(p->sp_kkt, d->nz_kkt, d->w, p->sp_v, d->nz_v, p->sp_r,
            d->nz_r, d->beta, p->prinv, p->pc);
  d->sing = casadi_qr_singular(&d->mina, &d->imina, d->nz_r, p->sp_r, p->pc, 1e-12);
}"""
_RESET_HEAD = "int casadi_qrqp_reset(struct casadi_qrqp_data* d) {\n  casadi_int i;\n"
_SINGULAR_HEAD = ("int casadi_qrqp_singular_step(struct casadi_qrqp_data* d) {\n"
                  "  casadi_real tau_test, tau;\n"
                  "  casadi_int nnz_kkt, nk, k, i, best_k, best_neg, neg;\n"
                  "  const struct casadi_qrqp_prob* p = d->prob;\n")
_KKT_CACHE_DECL = """/* seaway: the active pattern (lam != 0) of the last KKT factorisation in this QP,
   and what the factorisation computed besides the factors; counts: factorised, reused. */
#define SEAWAY_KKT_NZ {nz}
static int seaway_kkt_valid = 0;
static char seaway_kkt_active[SEAWAY_KKT_NZ];
static int seaway_kkt_sing;
static casadi_real seaway_kkt_mina;
static casadi_int seaway_kkt_imina;
static casadi_real seaway_kkt_counts[2] = {{0.0, 0.0}};
"""
_KKT_CACHED_FACTORIZE = """  /* seaway: the KKT matrix depends on H, A (fixed within one QP) and on which
     lam are zero; if that pattern was factorised last, d still holds its factors. */
  if (seaway_kkt_valid && p->qp->nz <= SEAWAY_KKT_NZ) {
    casadi_int i_;
    for (i_ = 0; i_ < p->qp->nz; ++i_) if (seaway_kkt_active[i_] != (d->lam[i_] != 0)) break;
    if (i_ == p->qp->nz) {
      d->sing = seaway_kkt_sing;
      d->mina = seaway_kkt_mina;
      d->imina = seaway_kkt_imina;
      seaway_kkt_counts[1] += 1.0;
      return;
    }
  }
""" + _FACTORIZE_BODY[:-2] + """
  seaway_kkt_counts[0] += 1.0;
  if (p->qp->nz <= SEAWAY_KKT_NZ) {
    casadi_int i_;
    for (i_ = 0; i_ < p->qp->nz; ++i_) seaway_kkt_active[i_] = d->lam[i_] != 0;
    seaway_kkt_sing = d->sing;
    seaway_kkt_mina = d->mina;
    seaway_kkt_imina = d->imina;
    seaway_kkt_valid = 1;
  }
}"""
_KKT_EXPORT = ("\nCASADI_SYMBOL_EXPORT casadi_real* seaway_kkt_stats(void) "
               "{ return seaway_kkt_counts; }\n")


def _patch_kkt_reuse(src: str, nz: int) -> str:
    """Make qrqp skip re-factorising an unchanged KKT matrix (see the module docstring).

    The cache is invalidated where the QP data change (``casadi_qrqp_reset``, once per QP) and where
    the factors are overwritten (``casadi_qrqp_singular_step`` factorises the transposed matrix).
    ``nz`` = variables + constraints; a larger QP is never cached (the guard in C).
    """
    for anchor, what in ((_FACTORIZE_BODY, "KKT factorisation"), (_RESET_HEAD, "QP reset"),
                         (_SINGULAR_HEAD, "singular step")):
        if src.count(anchor) != 1:
            raise RuntimeError(f"generated qrqp code has an unexpected shape ({what} not found once); "
                               f"CasADi {ca.__version__} is not supported by the KKT reuse patch")
    src = src.replace(_FACTORIZE_BODY, _KKT_CACHED_FACTORIZE)
    src = src.replace(_RESET_HEAD, _RESET_HEAD + "  seaway_kkt_valid = 0;\n")
    src = src.replace(_SINGULAR_HEAD, _SINGULAR_HEAD + "  seaway_kkt_valid = 0;\n")
    at = src.index(_RESET_HEAD)
    src = src[:at] + _KKT_CACHE_DECL.format(nz=nz) + src[at:]
    return src + _KKT_EXPORT


def _patch_digest() -> str:
    """A hash of the code that edits the generated C (it is part of what gets compiled), and of
    nothing else in this module, so that editing the rest does not discard every cached solver."""
    parts = [inspect.getsource(f) for f in (patch_generated_source, _tag_failure, _patch_kkt_reuse)]
    parts += [inspect.getsource(cvx_patch)]
    parts += [_STATS_DECL, _STATS_SET, _STATS_EXPORT, _SQP_ANCHOR, _FAIL_RETURN.pattern,
              _FACTORIZE_BODY, _RESET_HEAD, _SINGULAR_HEAD, _KKT_CACHE_DECL, _KKT_CACHED_FACTORIZE,
              _KKT_EXPORT, repr((ERROR_EVALUATION, ERROR_CONVEXIFY))]
    return hashlib.sha256("\0".join(parts).encode()).hexdigest()


def shared_object_path(ocp: Ocp, options: dict, directory: Path | None = None,
                       kkt_reuse: bool = True) -> Path:
    """Where the compiled solver for ``ocp`` is cached: named by its kind and a hash of the
    problem, the options, the compiler flags and the patch."""
    digest = spec_digest(ocp.spec, ocp.vessel, {"options": options, "cc": CC_FLAGS,
                                                "patch": _patch_digest(), "scaled": ocp.scaled,
                                                "kkt_reuse": kkt_reuse, "graph": ocp.graph})
    return (directory or cache_dir()) / f"{ocp.spec.kind}-{digest}.so"


def build_shared_object(ocp: Ocp, options: dict, directory: Path | None = None,
                        kkt_reuse: bool = True) -> Path:
    """Generate, patch and compile the SQP solver for ``ocp``; cached (``shared_object_path``).

    ``kkt_reuse=False`` leaves qrqp as CasADi generates it (the tests compare the two).

    Safe with concurrent processes: each builds in its own temporary folder and moves the result into
    place with an atomic rename; whoever finishes last replaces an identical file. A compiler
    stopped by a signal raises ``CompileInterruptedError``, a compiler that fails ``RuntimeError``
    with its messages.
    """
    target = shared_object_path(ocp, options, directory, kkt_reuse)
    if target.is_file():
        return target
    t0 = time.perf_counter()
    solver = ca.nlpsol(SYMBOL, "sqpmethod", ocp.nlp, options)
    gen = ca.CodeGenerator("solver.c", {"with_header": False})
    gen.add(solver)
    src = cvx_patch.patch_cvx_block_choice(patch_generated_source(gen.dump()))
    if kkt_reuse:
        src = _patch_kkt_reuse(src, ocp.nw + ocp.ng)
    compile_shared(src, target, CC_FLAGS, f"the {ocp.spec.kind} solver")
    log.info("built %s solver %s in %.1f s", ocp.spec.kind, target.name, time.perf_counter() - t0)
    return target


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


def make_solver(ocp: Ocp, kind: SolverKind = "generated") -> NlpSolver:
    """The solver named ``kind`` for ``ocp``: 'generated' (fast SQP) or 'ipopt' (reference)."""
    try:
        factory = SOLVERS[kind]
    except KeyError:
        raise ValueError(f"unknown solver {kind!r}; known: {', '.join(SOLVER_KINDS)}") from None
    return factory(ocp)
