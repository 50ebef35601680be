"""``seaway bench model``: RK4 steps per second of the vessel model on one core.

Three ways to take one RK4 step of the same model are timed in the same run: the fast numeric path
(plain floats, what the simulator uses), and as baselines numpy arrays and a CasADi Function called
from Python (the slow path solver-notes.md warns about). Target: >= 20,000 steps/s for the fast path.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable

from seaway.runtime.argtypes import positive_int
from seaway.vessel import model
from seaway.vessel.metrics import median, percentile

from seaway_lab.bench.common import BenchResult, pin_to_one_core

TARGET_STEPS_PER_S = 20_000


def _time_batches(step: Callable[[list[float]], list[float]], batches: int, batch: int) -> list[float]:
    """Per-step time [s] of each batch of ``batch`` consecutive steps."""
    x = [0.3, 0.05, 0.02, 0.0, 0.0, 0.1]
    out = []
    for _ in range(batches):
        t0 = time.perf_counter()
        for _ in range(batch):
            x = step(x)
        out.append((time.perf_counter() - t0) / batch)
        if not all(math.isfinite(v) for v in x):
            raise RuntimeError("model diverged during the benchmark")
    return out


def run(argv: list[str]) -> BenchResult:
    ap = argparse.ArgumentParser(prog="seaway bench model", description=__doc__.split("\n\n")[0])
    ap.add_argument("--vessel", default="paper-sim", help="vessel file name or path")
    ap.add_argument("--batches", type=positive_int, default=200,
                    help="timed batches (median and p99 over them)")
    ap.add_argument("--batch", type=positive_int, default=200, help="RK4 steps per batch")
    args = ap.parse_args(argv)
    p = model.load_vessel(args.vessel)
    cpu = pin_to_one_core()
    dt = 0.01
    thrust = (3.0, 2.0)
    tau = (0.015, 0.015, 0.0)

    def fast(x: list[float]) -> list[float]:
        return model.rk4_step(x, thrust, dt, p, math, tau)

    res = BenchResult("model", f"Vessel model RK4 step, dt = {dt} s, vessel {p.name}")
    fast_t = _time_batches(fast, args.batches, args.batch)
    fast_rate = 1.0 / median(fast_t)
    res.add("fast_steps_per_s", fast_rate, f">= {TARGET_STEPS_PER_S:,}", fast_rate >= TARGET_STEPS_PER_S,
            "plain floats (simulator path)")
    res.add("fast_step_median_us", median(fast_t) * 1e6)
    res.add("fast_step_p99_us", percentile(fast_t, 99) * 1e6, note="p99 over batches")

    try:
        import numpy as np

        class _NpOps:
            sin = staticmethod(np.sin)
            cos = staticmethod(np.cos)

        def with_numpy(x: list[float]) -> list[float]:
            xa = np.asarray(x)
            return list(model.rk4_step(xa, np.asarray(thrust), dt, p, _NpOps, np.asarray(tau)))

        np_t = _time_batches(with_numpy, max(20, args.batches // 10), args.batch)
        res.add("numpy_steps_per_s", 1.0 / median(np_t), note="baseline: numpy scalars")
        res.add("fast_vs_numpy", median(np_t) / median(fast_t), note="speed-up ratio")
    except ImportError:
        pass
    try:
        import casadi as ca
        from seaway.vessel.model_casadi import rk4_discrete

        F = rk4_discrete(p, dt)

        def with_casadi(x: list[float]) -> list[float]:
            return F(x, thrust, tau).full().ravel().tolist()

        ca_t = _time_batches(with_casadi, max(20, args.batches // 10), args.batch)
        res.add("casadi_call_steps_per_s", 1.0 / median(ca_t), note="baseline: CasADi Function call")
        res.add("fast_vs_casadi_call", median(ca_t) / median(fast_t), note="speed-up ratio")
        res.meta["casadi"] = ca.__version__
    except ImportError:
        res.meta["casadi"] = "not installed (install the casadi extra for the baseline)"
    res.meta["pinned_cpu"] = cpu
    res.meta["steps_timed"] = args.batches * args.batch
    return res
