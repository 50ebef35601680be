"""eigen-clip's eigenvalue iteration steps on the right block (``seaway_controller.cvx_patch``)."""

from __future__ import annotations

import json
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from seaway.vessel.model import load_vessel
from seaway_controller import cvx_patch
from seaway_controller.codegen import SQP_OPTIONS
from seaway_controller.ocp import Ocp, OcpSpec
from seaway_controller.solvers import GeneratedSqpSolver, IpoptSolver

CAPTURED = Path(__file__).parent / "data" / "cc_empc_c4_perturbed_160s.json"


def test_the_captured_mismatched_plant_solve_converges():
    # paper-c4-perturbed's CC-EMPC solve at t = 160.1 s, inputs as the controller gave them: the
    # Hessian's terminal block has two eigenvalues 1e-5 apart, and CasADi's block choice stepped the
    # pair with a foreign shift until max_iter_eig ran out ("convexify_failed").
    doc = json.loads(CAPTURED.read_text())
    ocp = Ocp(OcpSpec(doc["controller"]), load_vessel(doc["vessel"]))
    w0, p, lam_x0, lam_g0 = (np.asarray(doc[k], dtype=float) for k in ("w0", "p", "lam_x0", "lam_g0"))
    res = GeneratedSqpSolver(ocp).solve(w0, p, lam_x0, lam_g0)
    assert res.success, res.status
    assert res.iterations < 10
    g = np.asarray(ocp.constraint_fn(res.w, p)).ravel()
    assert np.max(np.abs(g)) < 1e-6
    ref = IpoptSolver(ocp).solve(w0, p, lam_x0, lam_g0)
    assert ref.success, ref.status
    assert res.objective == pytest.approx(ref.objective, rel=1e-5)


def test_the_patch_applies_once_to_the_real_generated_code():
    ocp = Ocp(OcpSpec("eo-empc", horizon=2), load_vessel("paper-sim"))
    gen = ca.CodeGenerator("solver.c", {"with_header": False})
    gen.add(ca.nlpsol("seaway_nlp", "sqpmethod", ocp.nlp, SQP_OPTIONS))
    src = gen.dump()
    patched = cvx_patch.patch_cvx_block_choice(src)
    assert cvx_patch.CVX_BLOCK_CHOICE not in patched
    assert patched.count(cvx_patch.CVX_BLOCK_CHOICE_FIXED) == 1


def test_the_patch_refuses_an_unknown_shape_and_leaves_code_without_eigen_clip_alone():
    with pytest.raises(RuntimeError, match="unexpected shape"):
        cvx_patch.patch_cvx_block_choice("int casadi_cvx_symm_schur(void) { return 0; }\n")
    plain = "int main(void) { return 0; }\n"
    assert cvx_patch.patch_cvx_block_choice(plain) == plain
