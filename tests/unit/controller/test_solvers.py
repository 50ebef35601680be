"""The generated SQP solver: agreement with IPOPT, an honest success flag, the cache, the C patch."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from seaway.vessel.model import load_vessel
from seaway_controller.codegen import (
    SQP_OPTIONS,
    _patch_kkt_reuse,
    build_shared_object,
    patch_generated_source,
)
from seaway_controller.ocp import Ocp, OcpSpec
from seaway_controller.solvers import GeneratedSqpSolver, IpoptSolver

VP = load_vessel("paper-sim")


def start_problem(ocp: Ocp) -> tuple[np.ndarray, np.ndarray]:
    p = ocp.parameters(np.array([0.03, 0.0, 0.0, 0.5, 0.4, 0.2]), (0.0, 0.0), (8.0, 0.0), True, 0.49)
    return ocp.cold_guess(p), p


@pytest.mark.parametrize("kind", ["cc-empc", "nmpc"])
def test_generated_solver_agrees_with_ipopt(kind):
    ocp = Ocp(OcpSpec(kind), VP)
    w0, p = start_problem(ocp)
    z = (np.zeros(ocp.nw), np.zeros(ocp.ng))
    fast = GeneratedSqpSolver(ocp).solve(w0, p, *z)
    ref = IpoptSolver(ocp).solve(w0, p, *z)
    assert fast.success and ref.success, (fast.status, ref.status)
    assert fast.objective == pytest.approx(ref.objective, rel=1e-6)
    np.testing.assert_allclose(ocp.thrusts(fast.w), ocp.thrusts(ref.w), atol=1e-3)
    g = np.asarray(ocp.constraint_fn(fast.w, p)).ravel()
    assert np.max(np.abs(g)) < 1e-6


def test_iteration_limit_is_reported_as_failure_not_stale_success(tmp_path):
    # A solver limited to one SQP iteration cannot converge from a cold start; its flag must say
    # so even right after a successful call of another solver (no stale status).
    ocp = Ocp(OcpSpec("cc-empc", horizon=3), VP)
    w0, p = start_problem(ocp)
    z = (np.zeros(ocp.nw), np.zeros(ocp.ng))
    good = GeneratedSqpSolver(ocp, directory=tmp_path)
    assert good.solve(w0, p, *z).success
    capped = GeneratedSqpSolver(ocp, {**SQP_OPTIONS, "max_iter": 1}, directory=tmp_path)
    res = capped.solve(w0, p, *z)
    assert not res.success
    assert res.status == "Maximum_Iterations_Exceeded" and res.iterations == 1
    assert good.solve(w0, p, *z).success  # and the good one still succeeds afterwards


def test_shared_object_is_cached_by_problem_and_options(tmp_path):
    ocp = Ocp(OcpSpec("eo-empc", horizon=3), VP)
    first = build_shared_object(ocp, SQP_OPTIONS, tmp_path)
    mtime = first.stat().st_mtime_ns
    assert build_shared_object(ocp, SQP_OPTIONS, tmp_path) == first
    assert first.stat().st_mtime_ns == mtime  # not rebuilt
    other = Ocp(OcpSpec("eo-empc", horizon=3, t_d_max_s=50.0), VP)
    assert build_shared_object(other, SQP_OPTIONS, tmp_path) != first
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".build-")]  # temp dirs cleaned


def test_patch_refuses_unknown_code_shapes():
    with pytest.raises(RuntimeError, match="unexpected shape"):
        patch_generated_source("int main(void) { return 0; }\n")


def test_two_solvers_on_the_same_library_in_one_process():
    # The generated code has one static memory slot; a second object on the same file shares it.
    ocp = Ocp(OcpSpec("cc-empc"), VP)
    w0, p = start_problem(ocp)
    z = (np.zeros(ocp.nw), np.zeros(ocp.ng))
    a, b = GeneratedSqpSolver(ocp), GeneratedSqpSolver(ocp)
    ra, rb = a.solve(w0, p, *z), b.solve(w0, p, *z)
    assert ra.success and rb.success
    np.testing.assert_array_equal(ra.w, rb.w)


def test_concurrent_builds_of_one_solver_leave_one_complete_file(tmp_path):
    # Two processes compiling the same solver into the same cache: both load a working library.
    code = ("import sys, numpy as np; from pathlib import Path; from seaway.vessel.model import load_vessel;"
            "from seaway_controller.ocp import Ocp, OcpSpec;"
            "from seaway_controller.solvers import GeneratedSqpSolver;"
            "ocp = Ocp(OcpSpec('eo-empc', horizon=2), load_vessel('paper-sim'));"
            "s = GeneratedSqpSolver(ocp, directory=Path(sys.argv[1]));"
            "p = ocp.parameters(np.array([0.05, 0, 0, 0, 0.2, 0]), (0, 0), (8, 0), True, 0.49);"
            "r = s.solve(ocp.cold_guess(p), p, np.zeros(ocp.nw), np.zeros(ocp.ng));"
            "print(s.path.name, r.success)")
    procs = [subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE,
                              text=True) for _ in range(2)]
    outs = [p.communicate(timeout=120)[0].split() for p in procs]
    assert all(p.returncode == 0 for p in procs)
    assert outs[0] == outs[1] and outs[0][1] == "True"
    assert sorted(os.listdir(tmp_path)) == [outs[0][0]]


def test_patch_tags_every_error_return_of_the_real_generated_code(tmp_path):
    import casadi as ca

    ocp = Ocp(OcpSpec("eo-empc", horizon=2), VP)
    gen = ca.CodeGenerator("solver.c", {"with_header": False})
    gen.add(ca.nlpsol("seaway_nlp", "sqpmethod", ocp.nlp, SQP_OPTIONS))
    gen.generate(f"{tmp_path}{os.sep}")
    patched = patch_generated_source((tmp_path / "solver.c").read_text())
    assert patched.count("seaway_stats[3] = 2.0; return 1;") == 1  # eigen-clip
    assert patched.count("seaway_stats[3] = 1.0; return 1;") >= 3  # f/g, Hessian, final eval
    assert "seaway_stats[0] = (casadi_real) iter_count" in patched
    assert patched.rstrip().endswith("{ return seaway_stats; }")


def test_kkt_reuse_patch_refuses_unknown_code_shapes():
    with pytest.raises(RuntimeError, match="KKT reuse patch"):
        _patch_kkt_reuse("int main(void) { return 0; }\n", 10)


def test_kkt_reuse_gives_bit_identical_solves_and_skips_factorisations(tmp_path):
    # A short closed loop on the paper's first leg, every solve warm-started from the previous one
    # as the controller does: the patched and the unpatched qrqp must agree bit for bit, and the
    # patched one must actually have skipped factorisations (else the patch is dead code).
    ocp = Ocp(OcpSpec("cc-empc"), VP)
    reuse = GeneratedSqpSolver(ocp)  # the controller's own, from the solver cache (built once)
    plain = GeneratedSqpSolver(ocp, directory=tmp_path, kkt_reuse=False)
    assert reuse.path != plain.path and plain.kkt_counts() is None
    done0, reused0 = reuse.kkt_counts()
    x0 = np.array([0.03, 0.0, 0.0, 0.5, 0.4, 0.2])
    p = ocp.parameters(x0, (0.0, 0.0), (8.0, 0.0), True, 0.49)
    w, lam_x, lam_g = ocp.cold_guess(p), np.zeros(ocp.nw), np.zeros(ocp.ng)
    for _ in range(15):
        a, b = reuse.solve(w, p, lam_x, lam_g), plain.solve(w, p, lam_x, lam_g)
        assert a.success and b.success, (a.status, b.status)
        assert a.iterations == b.iterations
        np.testing.assert_array_equal(a.w, b.w)
        np.testing.assert_array_equal(a.lam_g, b.lam_g)
        np.testing.assert_array_equal(a.lam_x, b.lam_x)
        x0 = ocp.states(a.w, x0)[1]  # the plan's next state becomes the measured one
        p = ocp.parameters(x0, (0.0, 0.0), (8.0, 0.0), True, 0.49)
        w, lam_x, lam_g = ocp.shift(a.w, a.lam_x, a.lam_g, np.zeros(3))
    done, reused = reuse.kkt_counts()
    assert done > done0 and reused > reused0


@pytest.mark.parametrize("kind", ["cc-empc", "nmpc"])
def test_mx_graph_builds_the_same_nlp_as_the_sx_graph(kind):
    # The bench's plain-IPOPT reference is the MX graph; it must be the NLP the fast path solves.
    sx, mx = Ocp(OcpSpec(kind), VP), Ocp(OcpSpec(kind), VP, graph="MX")
    assert (mx.nw, mx.ng) == (sx.nw, sx.ng)
    np.testing.assert_array_equal(mx.lbw, sx.lbw)
    np.testing.assert_array_equal(mx.ubw, sx.ubw)
    rng = np.random.default_rng(3)
    for _ in range(5):
        w0, p = start_problem(sx)
        w = w0 + 0.1 * rng.standard_normal(sx.nw)
        assert float(mx.objective_fn(w, p)) == pytest.approx(float(sx.objective_fn(w, p)), rel=1e-12)
        np.testing.assert_allclose(np.asarray(mx.constraint_fn(w, p)).ravel(),
                                   np.asarray(sx.constraint_fn(w, p)).ravel(), rtol=1e-12, atol=1e-12)
    with pytest.raises(ValueError, match="graph"):
        Ocp(OcpSpec(kind), VP, graph="QX")


def test_a_plan_from_the_reference_ipopt_warm_starts_the_generated_solver() -> None:
    """A real-time mission's first solve can come before the generated solver is loaded, so IPOPT
    makes the first plan and the SQP warm-starts from it. With IPOPT's multipliers the SQP stalled
    (not_converged, pr_inf ~1) for about a second, falling back to plan reuse and line of sight;
    from its primal solution alone it converges at once. States as logged in such a run (the lake,
    paper-boat, at rest then speeding up along a 25 m leg)."""
    from seaway_controller.mpc import MpcController

    ocp = Ocp(OcpSpec("cc-empc"), load_vessel("paper-boat"))
    ctrl = MpcController(ocp, IpoptSolver(ocp))
    leg = ((0.0, 0.0), (25.0, 0.0), 2.0, 250.0, ("quiet", 1))
    first = ctrl.solve(10**9, np.array([0.011, 0.0, 0.0, -0.25, -0.06, 0.001]), *leg)
    assert first.result.success and first.result.interior_point
    ctrl.accept(first)
    ctrl.solver = GeneratedSqpSolver(ocp)
    for k, u_mps in enumerate((0.132, 0.241, 0.338, 0.42), start=1):
        out = ctrl.solve(10**9 + k * 10**8, np.array([u_mps, 0.0, 0.0, -0.21 + 0.015 * k, 0.05, 0.004]),
                         *leg)
        assert out.result.success, (k, out.result.status)
        assert not out.result.interior_point
        ctrl.accept(out)


def test_ipopt_with_a_time_limit_stops_there_and_says_so():
    """Real time solves the reference IPOPT on the control loop's thread (while the generated
    solver is being made); its own limit is 3000 iterations, not a time, so the service gives it
    the control period. A solve that cannot finish within the limit fails, naming the limit."""
    ocp = Ocp(OcpSpec("cc-empc"), VP)
    w0, p = start_problem(ocp)
    z = (np.zeros(ocp.nw), np.zeros(ocp.ng))
    res = IpoptSolver(ocp, time_limit_s=1e-9).solve(w0, p, *z)
    assert not res.success and "WallTime" in res.status, res.status
    assert IpoptSolver(ocp, time_limit_s=60.0).solve(w0, p, *z).success
    with pytest.raises(ValueError, match="time_limit_s"):
        IpoptSolver(ocp, time_limit_s=0.0)


@pytest.mark.parametrize("kind", ["cc-empc", "eo-empc"])
def test_a_plan_with_a_weak_port_thruster_commands_it_harder(kind):
    """On a straight leg at the economic cruise a thruster giving half its command is commanded
    twice the other, so that the thrust given does not turn the boat. (The NMPC runs both at the
    bound on this leg, and the bound is what a weak thruster cannot pass.)"""
    ocp = Ocp(OcpSpec(kind), VP)
    x0 = np.array([0.045, 0.0, 0.0, 1.0, 0.0, 0.0])  # on the leg (0, 0) -> (8, 0), at cruise
    z = (np.zeros(ocp.nw), np.zeros(ocp.ng))
    ratios = {}
    for given in ((1.0, 1.0), (0.5, 1.0)):
        p = ocp.parameters(x0, (0.0, 0.0), (8.0, 0.0), True, 0.49, given=given)
        res = GeneratedSqpSolver(ocp).solve(ocp.cold_guess(p), p, *z)
        assert res.success, res.status
        port, starboard = ocp.thrusts(res.w)[:5].mean(axis=0)
        ratios[given] = port / starboard
    assert ratios[(1.0, 1.0)] == pytest.approx(1.0, abs=0.1)
    assert ratios[(0.5, 1.0)] == pytest.approx(2.0, abs=0.2)
