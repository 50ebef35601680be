"""seaway.vessel.native: a CasADi function compiled to C, cached, and the fallback without a compiler."""

from __future__ import annotations

import logging
import math
import os
import shutil
import subprocess

import casadi as ca
import numpy as np
import pytest
from seaway.vessel import model, native
from seaway.vessel.model import NX

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None and shutil.which("cc") is None,
                                reason="needs a C compiler")


def rk4_function(name: str = "seaway_test_rk4") -> ca.Function:
    """One RK4 step of the paper's vessel model, its Jacobian J (a dense 6x6 output) and J M for a
    6x6 input M: a matrix in and out, so that the column-major layout is checked both ways."""
    p = model.load_vessel("paper-sim")
    x, u, h, M = ca.SX.sym("x", NX), ca.SX.sym("u", 2), ca.SX.sym("h"), ca.SX.sym("M", NX, NX)
    xn = ca.vertcat(*model.rk4_step([x[i] for i in range(NX)], [u[0], u[1]], h, p, ca))
    J = ca.jacobian(xn, x)
    return ca.Function(name, [x, u, h, M], native.dense(xn, J, J @ M))


X0 = np.array([0.9, 0.05, -0.02, 10.0, -4.0, 2.5])
M0 = np.arange(NX * NX, dtype=float).reshape(NX, NX) / 10.0  # not symmetric


def evaluate(fn: native.NativeFunction) -> tuple[np.ndarray, np.ndarray]:
    fn.inputs[0][:] = X0
    fn.inputs[1][:] = (3.0, 1.5)
    fn.inputs[2][0] = 0.05
    fn.inputs[3][:] = M0.ravel(order="F")
    fn()
    J = fn.outputs[1].reshape(NX, NX, order="F")
    np.testing.assert_allclose(fn.outputs[2].reshape(NX, NX, order="F"), J @ M0, rtol=1e-12,
                               atol=1e-12)
    return fn.outputs[0].copy(), J.copy()


def test_compiled_function_gives_the_models_numbers_and_is_cached(tmp_path) -> None:
    fn = native.NativeFunction(rk4_function(), tmp_path)
    assert fn.compiled
    xn, J = evaluate(fn)
    p = model.load_vessel("paper-sim")
    ref = model.rk4_step(X0.tolist(), (3.0, 1.5), 0.05, p, math)  # the float path
    np.testing.assert_allclose(xn, ref, rtol=1e-13, atol=1e-13)
    # The Jacobian against central differences of the float path.
    eps = 1e-6
    fd = np.column_stack([
        (np.array(model.rk4_step((X0 + eps * e).tolist(), (3.0, 1.5), 0.05, p, math))
         - np.array(model.rk4_step((X0 - eps * e).tolist(), (3.0, 1.5), 0.05, p, math))) / (2 * eps)
        for e in np.eye(NX)])
    np.testing.assert_allclose(J, fd, atol=1e-7)
    libs = list(tmp_path.glob("seaway_test_rk4-*.so"))
    assert len(libs) == 1
    mtime = libs[0].stat().st_mtime_ns
    again = native.NativeFunction(rk4_function(), tmp_path)  # the cached file, not compiled again
    assert again.compiled and libs[0].stat().st_mtime_ns == mtime
    np.testing.assert_array_equal(evaluate(again)[0], xn)


def test_another_function_gets_another_file(tmp_path) -> None:
    native.NativeFunction(rk4_function(), tmp_path)
    x = ca.SX.sym("x", 2)
    native.NativeFunction(ca.Function("seaway_test_rk4", [x], [x * 2]), tmp_path)  # same name
    assert len(list(tmp_path.glob("seaway_test_rk4-*.so"))) == 2


def test_without_a_compiler_casadi_evaluates_the_same_expressions(tmp_path, monkeypatch,
                                                                    caplog) -> None:
    compiled = evaluate(native.NativeFunction(rk4_function(), tmp_path))
    monkeypatch.setattr(native.shutil, "which", lambda name: None)
    caplog.set_level(logging.WARNING, "seaway.native")
    fn = native.NativeFunction(rk4_function("seaway_test_rk4_nocc"), tmp_path / "empty")
    assert not fn.compiled
    assert "no C compiler" in caplog.text and "seaway_test_rk4_nocc" in caplog.text
    xn, J = evaluate(fn)
    np.testing.assert_allclose(xn, compiled[0], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(J, compiled[1], rtol=1e-12, atol=1e-14)


def test_a_compiler_error_is_named(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr(native, "CC_FLAGS", ("-fPIC", "-shared", "-no-such-flag-for-seaway"))
    with pytest.raises(RuntimeError, match="compiling seaway_test_rk4 failed"):
        native.build(rk4_function(), tmp_path)
    assert not list(tmp_path.glob("*.so")) and not list(tmp_path.glob(".build-*"))


def test_sparse_outputs_are_refused_with_their_name() -> None:
    x = ca.SX.sym("x", 3)
    with pytest.raises(ValueError, match="output o0 is not dense"):
        native.NativeFunction(ca.Function("seaway_test_sparse", [x], [ca.diag(x)]))


def test_cache_dir_follows_the_environment(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(native.ENV_CACHE_DIR, str(tmp_path))
    assert native.cache_dir() == tmp_path
    monkeypatch.delenv(native.ENV_CACHE_DIR)
    assert native.cache_dir().parts[-3:] == (".cache", "seaway", "solvers")


def test_the_compiler_runs_at_the_lowest_priority(tmp_path, monkeypatch) -> None:
    # A stand-in `gcc` first on PATH that notes its niceness, then runs the real compiler: the
    # build must still work, and the compiler must have run niced (a background compile at
    # normal priority took CPU from a real-time controller).
    real = shutil.which("gcc") or shutil.which("cc")
    bin_dir, seen = tmp_path / "bin", tmp_path / "niceness"
    bin_dir.mkdir()
    (bin_dir / "gcc").write_text(f'#!/bin/sh\nnice > "{seen}"\nexec "{real}" "$@"\n')
    (bin_dir / "gcc").chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_dir}:{os.environ['PATH']}")
    fn = native.NativeFunction(rk4_function("seaway_test_rk4_niced"), tmp_path / "cache")
    assert fn.compiled
    base = int(subprocess.run(["nice"], capture_output=True, text=True, check=True).stdout)
    assert int(seen.read_text()) == min(19, base + native.COMPILE_NICENESS)
