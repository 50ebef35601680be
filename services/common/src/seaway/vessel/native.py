"""CasADi functions of the vessel model, generated as C, compiled once and called through ctypes.

Needs the ``casadi`` extra. Why: evaluating the model with Python floats and numpy (the estimator's
prediction step, with its Jacobian and covariance) is dominated by the per-call overhead of numpy on
small matrices, and calling a CasADi ``Function`` from Python by its call overhead; the same
function generated as C and called through ctypes is an order of magnitude cheaper
(``../shared/solver-notes.md``, "Plant step cost"). The expressions are built from the one model
(``seaway.vessel.model`` evaluated on CasADi symbols), so nothing is stated twice.

Each function is compiled once per machine with ``CC_FLAGS`` and cached by a hash of its generated
source, CasADi's version and the flags, beside the controller's solvers (``cache_dir``). Without a C
compiler, or if the build fails, the same ``Function`` is evaluated by CasADi itself: the same
expressions, so the same numbers to rounding, but slower (CasADi's call overhead on every call);
that is logged once, with the reason.
"""

from __future__ import annotations

import ctypes
import hashlib
import logging
import os
import shutil
import signal
import subprocess
import tempfile
import threading
from collections.abc import Sequence
from pathlib import Path

import casadi as ca
import numpy as np

log = logging.getLogger("seaway.native")

ENV_CACHE_DIR = "SEAWAY_CACHE_DIR"
"""Where compiled functions and solvers are cached (default ``~/.cache/seaway/solvers``)."""
CC_FLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-semantic-interposition")
"""No ``-march`` and no contraction into fused multiply-adds: the same floats on every x86-64
machine, so that a lockstep run gives the same numbers wherever it is repeated."""


COMPILE_NICENESS = 19
"""The compiler's niceness (``nice -n``): the lowest priority, so it never delays the processes."""


def cache_dir() -> Path:
    """``$SEAWAY_CACHE_DIR`` or ``~/.cache/seaway/solvers``."""
    env = os.environ.get(ENV_CACHE_DIR)
    return Path(env) if env else Path.home() / ".cache" / "seaway" / "solvers"


def _source(fn: ca.Function) -> str:
    gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False})
    gen.add(fn)
    return gen.dump()


def library_path(fn: ca.Function, directory: Path | None = None) -> tuple[Path, str]:
    """Where ``fn`` compiled is cached (named by its name and a hash of its source, CasADi's version
    and the flags), and that source."""
    src = _source(fn)
    digest = hashlib.sha256("\0".join([src, ca.__version__, *CC_FLAGS]).encode()).hexdigest()[:20]
    return (directory or cache_dir()) / f"{fn.name()}-{digest}.so", src


class CompileInterruptedError(RuntimeError):
    """The C compiler was stopped by a signal before it finished: the process building is being
    stopped (a launcher's stop, Ctrl-C), which says nothing about the generated code."""


def compile_shared(src: str, target: Path, flags: Sequence[str], what: str) -> None:
    """Compile C ``src`` into the shared object ``target`` with ``flags`` (``what`` names it in
    errors): the one compile step of generated code (these functions, the controller's solvers).

    Safe with concurrent processes: each compiles in a temporary folder of its own beside
    ``target`` and moves the result into place with an atomic rename; whoever finishes last
    replaces an identical file. ``CompileInterruptedError`` if the compiler was stopped by a
    signal; ``RuntimeError`` naming the cause if there is no C compiler or it failed."""
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise RuntimeError(f"no C compiler (gcc or cc) on PATH: needed once to build {what}")
    # A compile is background work (a solver made while the reference flies the boat): at the
    # lowest CPU priority it takes only what the running stack leaves: at normal priority it can
    # delay the controller beside it past vehicle_io's thrust deadline. (`nice` execs the
    # compiler, so a signal that stops it still reads as one here.)
    nice = shutil.which("nice")
    lowest = [nice, "-n", str(COMPILE_NICENESS)] if nice else []
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".build-") as tmp:
        c_file, so_tmp = Path(tmp) / "source.c", Path(tmp) / "library.so"
        c_file.write_text(src)
        proc = subprocess.run([*lowest, cc, *flags, str(c_file), "-o", str(so_tmp), "-lm"],
                              capture_output=True, text=True, check=False)
        if proc.returncode < 0:  # killed (the launcher stopping us), not an error of the code
            raise CompileInterruptedError(
                f"compiling {what} was interrupted: the C compiler was stopped by "
                f"{signal.Signals(-proc.returncode).name} before it finished (this process is "
                "being stopped); not a compile error")
        if proc.returncode != 0:
            raise RuntimeError(f"compiling {what} failed (exit {proc.returncode}):\n"
                               f"{proc.stderr[-2000:]}")
        os.replace(so_tmp, target)


def build(fn: ca.Function, directory: Path | None = None) -> Path:
    """Generate and compile ``fn`` (cached: ``library_path``); its shared object. Errors as
    ``compile_shared``'s."""
    target, src = library_path(fn, directory)
    if not target.is_file():
        compile_shared(src, target, CC_FLAGS, fn.name())
    return target


_LOADED: dict[str, ctypes.CDLL] = {}
_LOADED_LOCK = threading.Lock()
_WARNED: set[str] = set()


class NativeFunction:
    """``fn`` with dense inputs and outputs in preallocated float64 buffers, evaluated in place.

    Fill ``inputs[i]`` (column-major, as CasADi stores matrices), call, read ``outputs[j]``. The
    buffers are reused by every call, so a caller copies out what it keeps. Not thread-safe: one
    object per thread that evaluates.
    """

    def __init__(self, fn: ca.Function, directory: Path | None = None) -> None:
        for i in range(fn.n_in()):
            if not fn.sparsity_in(i).is_dense():
                raise ValueError(f"{fn.name()}: input {fn.name_in(i)} is not dense")
        for j in range(fn.n_out()):
            if not fn.sparsity_out(j).is_dense():
                raise ValueError(f"{fn.name()}: output {fn.name_out(j)} is not dense (densify it)")
        self.name = fn.name()
        self.inputs = [np.zeros(fn.nnz_in(i)) for i in range(fn.n_in())]
        self.outputs = [np.zeros(fn.nnz_out(j)) for j in range(fn.n_out())]
        self._fn = fn
        self.compiled = False
        try:
            path = build(fn, directory)
            with _LOADED_LOCK:  # one handle per file and process (dlopen would share it anyway)
                if str(path) not in _LOADED:
                    _LOADED[str(path)] = ctypes.CDLL(str(path))
                lib = _LOADED[str(path)]
        except (RuntimeError, OSError) as err:
            if self.name not in _WARNED:
                _WARNED.add(self.name)
                log.warning("%s is evaluated by CasADi, not as compiled C (slower, same "
                            "expressions): %s", self.name, err)
            return
        sizes = [ctypes.c_longlong() for _ in range(4)]
        if getattr(lib, f"{self.name}_work")(*(ctypes.byref(s) for s in sizes)) != 0:
            raise RuntimeError(f"{path.name}: work-size query failed")
        n_arg, n_res, n_iw, n_w = (max(s.value, 1) for s in sizes)
        self._arg = (ctypes.c_void_p * max(n_arg, len(self.inputs)))(
            *(a.ctypes.data for a in self.inputs))
        self._res = (ctypes.c_void_p * max(n_res, len(self.outputs)))(
            *(r.ctypes.data for r in self.outputs))
        self._iw = np.zeros(n_iw, dtype=np.int64)  # casadi_int is long long in generated code
        self._w = np.zeros(n_w)
        entry = getattr(lib, self.name)
        entry.restype = ctypes.c_int
        entry.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_int]
        self._entry = entry
        self._args = (self._arg, self._res, self._iw.ctypes.data, self._w.ctypes.data, 0)
        self.compiled = True

    def __call__(self) -> None:
        """Evaluate: ``inputs`` -> ``outputs``, in place. Raises ``RuntimeError`` if it fails."""
        if self.compiled:
            if self._entry(*self._args) != 0:
                raise RuntimeError(f"{self.name}: evaluation failed")
            return
        out = self._fn.call([ca.reshape(ca.DM(a), *self._fn.size_in(i))  # column-major, as C's
                             for i, a in enumerate(self.inputs)])
        for buf, value in zip(self.outputs, out, strict=True):
            buf[:] = value.full().ravel(order="F")


def dense(*exprs: ca.SX) -> Sequence[ca.SX]:
    """Each expression densified (structural zeros made explicit), as ``NativeFunction`` needs."""
    return [ca.densify(e) for e in exprs]
