"""The generated SQP's C: made by CasADi, patched, compiled and cached (``solvers.GeneratedSqpSolver``
loads it and calls it through ctypes).

The configuration (solver-notes.md, the measured best): CasADi ``sqpmethod`` with the ``qrqp``
active-set QP, exact Hessian convexified by ``eigen-clip`` with ``max_iter_eig`` = 1e5 (at the default
it stops silently at waypoint turns), generated as C, compiled once with ``gcc -O3`` and cached by a
hash of the problem and the options (``shared_object_path``).

qrqp re-forms and re-factorises its KKT matrix at every active-set iteration, also when the active
set did not change, so that a QP which converges in one step pays for two sparse QR factorisations.
The generated C is patched to keep the last factorisation while the QP's active pattern is unchanged
(``_patch_kkt_reuse``): the same matrix gives the same factors, so the results are bit for bit those of
the unpatched code (the same closed loop), and a step costs less by the factorisations saved.

A solve's success is decided from its own results (``solvers``): the generated function's return
flag, plus the primal and dual infeasibilities of the returned point. CasADi 3.8's generated
``sqpmethod`` returns 0 at its iteration limit, so the flag alone is not enough; the C is patched
(checked, anchored edits) to export the iteration count and those two residuals. eigen-clip's
eigenvalue iteration is patched too, to step on the right block (``cvx_patch``: CasADi's could
exhaust ``max_iter_eig`` on close eigenvalues). The cache key covers the patches' code
(``_patch_digest``).
"""

from __future__ import annotations

import hashlib
import inspect
import logging
import re
import time
from pathlib import Path

import casadi as ca
from seaway.vessel.native import cache_dir, compile_shared

from seaway_controller import cvx_patch
from seaway_controller.ocp import Ocp, spec_digest

log = logging.getLogger("seaway_controller.codegen")

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
